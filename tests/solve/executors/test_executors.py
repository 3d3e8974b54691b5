"""Executors: same results anywhere, each worker builds once, results stream per item."""

import os
import time

import pytest

from nlp.solve.executors import Setup, TaskFailed, make_executor


class _Context:
    def __init__(self, scale):
        self.scale = scale
        self.token = os.urandom(8).hex()  # a new value at every build


def _build(scale):
    return _Context(scale)


def _square(ctx, x):
    return ctx.scale * x * x, os.getpid(), ctx.token


def _slow_at_five(ctx, x):
    if x == 5:
        time.sleep(60)
    return x


def _fails_at_three(ctx, x):
    if x == 3:
        raise ValueError("bad item three")
    return x


def _dies_at_two(ctx, x):
    if x == 2:
        os._exit(7)
    return x


@pytest.mark.parametrize("kind,workers", [("serial", 1), ("local", 1), ("local", 3)])
def test_results_and_build_once_per_worker(kind, workers):
    items = [(i, i) for i in range(40)]
    with make_executor(kind, workers=workers) as ex:
        out = ex.map(Setup(_build, 3.0), _square, items, batch_size=4)
    assert sorted(out) == list(range(40))
    assert all(out[i][0] == 3.0 * i * i for i in range(40))
    tokens = {}
    for _, pid, token in out.values():  # one context per worker process, reused
        tokens.setdefault(pid, set()).add(token)
    assert all(len(t) == 1 for t in tokens.values())
    assert 1 <= len(tokens) <= workers


def test_forked_workers_inherit_the_built_value():
    ctx = _Context(2.0)
    with make_executor("local", workers=2) as ex:
        out = ex.map(Setup(_build, 99.0, value=ctx), _square, [(i, i) for i in range(10)])
    assert {v[2] for v in out.values()} == {ctx.token}  # nothing rebuilt
    assert out[3][0] == 18.0


def test_results_stream_per_item_and_stop_is_prompt():
    with make_executor("local", workers=1) as ex:
        # one batch of 10: items 0-4 must arrive while item 5 is still running
        stream = ex.stream(Setup(_build, 1.0), _slow_at_five, [(i, i) for i in range(10)],
                           batch_size=10)
        got = [next(stream)[0] for _ in range(5)]
        t0 = time.perf_counter()
        rest = stream.stop()
        stream.close()
    assert got == [0, 1, 2, 3, 4] and rest == []
    assert time.perf_counter() - t0 < 3.0


def test_task_error_and_dead_worker_are_reported():
    with make_executor("local", workers=2) as ex:
        with pytest.raises(TaskFailed, match="bad item three"):
            ex.map(Setup(_build, 1.0), _fails_at_three, [(i, i) for i in range(6)])
        with pytest.raises(TaskFailed, match="died"):
            ex.map(Setup(_build, 1.0), _dies_at_two, [(i, i) for i in range(6)])


def test_setup_without_recipe_cannot_travel():
    import pickle
    with pytest.raises(TypeError, match="build recipe"):
        pickle.dumps(Setup(value=1))
    s = pickle.loads(pickle.dumps(Setup(_build, 5.0, value=_Context(1.0))))
    assert s.get().scale == 5.0  # the receiver builds its own


@pytest.mark.slow  # starts a Dask LocalCluster: ~15 s
def test_dask_local_cluster_same_results():
    pytest.importorskip("distributed")
    items = [(i, i) for i in range(30)]
    with make_executor("dask", workers=2) as ex:
        out = ex.map(Setup(_build, 3.0), _square, items)
    assert {k: v[0] for k, v in out.items()} == {i: 3.0 * i * i for i in range(30)}
    tokens = {}
    for _, pid, token in out.values():
        tokens.setdefault(pid, set()).add(token)
    assert all(len(t) == 1 for t in tokens.values())


_KILLED_PARENT = r"""
import os, sys, time
from nlp.solve.executors import Setup, make_executor

def slow(ctx, x):
    time.sleep(120)
    return x

ex = make_executor("local", workers=2)
stream = ex.stream(Setup(value=None), slow, [(0, 0), (1, 1)])
print(" ".join(str(p.pid) for p in stream._procs), flush=True)
time.sleep(120)
"""


@pytest.mark.skipif(not os.sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux")
def test_workers_die_with_a_killed_parent():
    """A parent killed with SIGKILL runs no clean-up: the kernel must end its workers."""
    import signal
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-c", _KILLED_PARENT], stdout=subprocess.PIPE,
                         text=True)
    pids = [int(x) for x in p.stdout.readline().split()]
    assert len(pids) == 2
    for pid in pids:
        os.kill(pid, 0)     # alive while their parent is
    p.send_signal(signal.SIGKILL)
    p.wait()
    deadline = time.time() + 10
    alive = set(pids)
    while alive and time.time() < deadline:
        for pid in list(alive):
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                alive.discard(pid)
        time.sleep(0.1)
    assert not alive, f"workers {sorted(alive)} outlived their killed parent"
