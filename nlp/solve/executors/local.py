"""Worker processes on this machine, and an in-process executor.

Each worker is one process with one thread (IPOPT with MUMPS is not
thread-safe). Where ``fork`` exists the workers are forked for each
submission and inherit the caller's built problem (no rebuild, nothing
pickled); elsewhere they are spawned and build it once from the Setup's
recipe. Work goes out in small batches over one pipe per worker, and every
item's result comes back on its own as soon as it is done.
"""

from collections import deque
import ctypes
import math
import multiprocessing as mp
from multiprocessing.connection import wait
import os
import signal
import sys
import traceback

from nlp.solve.executors.base import Executor, Stream, TaskFailed, batches

__all__ = ["LocalExecutor", "SerialExecutor"]


def _can_fork():
    return "fork" in mp.get_all_start_methods()


PR_SET_PDEATHSIG = 1


def _die_with_parent(parent_pid):
    """Have the kernel send SIGTERM to this worker when its parent dies (Linux).

    A parent killed with SIGKILL runs no clean-up; its workers would otherwise go on
    solving, or wait forever on a pipe that a sibling worker still holds open (a
    blind scoring run's 900-s timeout left one idle for 70 minutes). The kernel ties the
    signal to the thread that forked the worker: streams are opened from the thread that
    reads them, so that thread outlives its workers.
    """
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError, TypeError):
        return
    if os.getppid() != parent_pid:   # the parent died before the request was made
        os._exit(1)


def _worker_main(conn, setup, fn, parent_pid=None):
    # The parent decides when to stop: a Ctrl-C sent to the whole process
    # group must not kill a worker in the middle of sending a result.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if parent_pid is not None and sys.platform.startswith("linux"):
        _die_with_parent(parent_pid)
    try:
        context = setup.get()
    except BaseException:
        conn.send(("error", None, traceback.format_exc()))
        return
    conn.send(("idle",))
    while True:
        batch = conn.recv()
        if batch is None:
            return
        for key, item in batch:
            try:
                result = fn(context, item)
            except BaseException:
                conn.send(("error", key, traceback.format_exc()))
                return
            conn.send(("result", key, result))
        conn.send(("idle",))


class _ProcessStream(Stream):
    def __init__(self, setup, fn, items, workers, batch_size):
        items = list(items)
        n = max(1, min(workers, len(items)))
        if batch_size is None:  # a few batches per worker: balance, but little IPC
            batch_size = max(1, min(16, math.ceil(len(items) / (4 * n))))
        self._todo = deque(batches(items, batch_size))
        self._left = len(items)
        self._ready = deque()
        self._procs, self._conns = [], []
        self._retired = set()  # workers told to quit: their EOF is expected
        ctx = mp.get_context("fork" if _can_fork() else "spawn")
        if self._left == 0:
            return
        for _ in range(n):
            parent, child = ctx.Pipe()
            p = ctx.Process(target=_worker_main, args=(child, setup, fn, os.getpid()),
                            daemon=True)
            p.start()
            child.close()  # so the parent sees EOF when the worker dies
            self._procs.append(p)
            self._conns.append(parent)

    def _handle(self, conn):
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            i = self._conns.index(conn)
            self._conns.pop(i)
            p = self._procs[i]
            p.join(1)
            if id(conn) not in self._retired:
                raise TaskFailed(f"a worker process died (exit code {p.exitcode}) with "
                                 f"{self._left} tasks unfinished") from None
            return
        kind = msg[0]
        if kind == "result":
            self._left -= 1
            self._ready.append((msg[1], msg[2]))
        elif kind == "idle":
            if self._todo:
                conn.send(self._todo.popleft())
            else:
                self._retired.add(id(conn))
                conn.send(None)
        else:
            raise TaskFailed(f"task {msg[1]!r} failed in a worker:\n{msg[2]}")

    def __next__(self):
        while not self._ready:
            if self._left == 0 or not self._conns:
                self.close()
                raise StopIteration
            for conn in wait(self._conns):
                self._handle(conn)
        return self._ready.popleft()

    def stop(self):
        done = list(self._ready)
        self._ready.clear()
        for conn in list(self._conns):
            try:
                while conn.poll():
                    msg = conn.recv()
                    if msg[0] == "result":
                        done.append((msg[1], msg[2]))
            except (EOFError, OSError):
                pass
        self.close()
        return done

    def close(self):
        for p in self._procs:
            if p.is_alive():
                p.kill()  # IPOPT may be deep in C code: SIGKILL is the prompt way
        for p in self._procs:
            p.join(2)
        for c in self._conns:
            c.close()
        self._procs, self._conns = [], []
        self._todo.clear()


class LocalExecutor(Executor):
    """``workers`` processes on this machine, one thread each.

    With one worker the work still runs in a child process, so SIGINT and
    SIGTERM reach Python at once instead of waiting for (or being swallowed
    by) a solver in C code. A caller that is itself a daemonic worker process
    cannot have children; its work then runs in-process.
    """

    kind = "local"

    def __init__(self, workers=1):
        self.workers = max(1, int(workers))

    def stream(self, setup, fn, items, batch_size=None):
        if mp.current_process().daemon or (not _can_fork() and not setup.has_recipe):
            return _SerialStream(setup, fn, items)
        return _ProcessStream(setup, fn, items, self.workers, batch_size)


class _SerialStream(Stream):
    def __init__(self, setup, fn, items):
        self._items = deque(items)
        self._setup, self._fn = setup, fn
        self._context = None

    def __next__(self):
        if not self._items:
            raise StopIteration
        if self._context is None:
            self._context = self._setup.get()
        key, item = self._items.popleft()
        return key, self._fn(self._context, item)

    def close(self):
        self._items.clear()


class SerialExecutor(Executor):
    """Everything in this process, in order (debugging; callers that are workers)."""

    kind = "serial"

    def stream(self, setup, fn, items, batch_size=None):
        return _SerialStream(setup, fn, items)

