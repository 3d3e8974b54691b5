"""Dask distributed: a scheduler by address, or an in-process LocalCluster.

What travels to the workers: the Setup (the build function by reference and
its arguments, e.g. the assembled case with its data arrays, pickled), the
task function by reference, and the items. Each worker builds the context once
per Setup key and keeps it for later batches. The package must be importable
on the workers; the compiled CasADi library is taken from the worker's cache
or compiled there from the generated source (gcc needed on the workers, else
CasADi's virtual machine runs the same functions, slower).

Items travel in batches (each task carries tens of milliseconds of work at
least); a stop event is polled between items (at most once a second: each
poll is a round trip to the scheduler), so an interrupt returns the results a
batch had finished instead of discarding them. On a cluster of your own, start
the workers with ``--nthreads 1`` and consider ``distributed.worker.profile.enabled:
false`` in the Dask configuration (the LocalCluster sets it).
"""

import logging
import math
import time
import uuid

from nlp.errors import InputError
from nlp.solve.executors.base import Executor, Stream, TaskFailed, batches

__all__ = ["DaskExecutor"]

_POLL_SECONDS = 1.0  # how often a running batch asks the scheduler whether to stop


def _run_batch(setup, fn, batch, stop_name):
    from distributed import Event

    context = setup.get()
    stop = Event(stop_name)
    out = []
    last = time.monotonic()
    for key, item in batch:
        if time.monotonic() - last > _POLL_SECONDS:
            last = time.monotonic()
            if stop.is_set():
                break
        out.append((key, fn(context, item)))
    return out


class _DaskStream(Stream):
    def __init__(self, client, setup, fn, items, workers, batch_size):
        from distributed import Event, as_completed

        items = list(items)
        if batch_size is None:  # ~16 batches per worker: balance against scheduler overhead
            batch_size = max(1, math.ceil(len(items) / (16 * max(1, workers))))
        self._client = client
        self._stop_name = f"frf-nlp-stop-{uuid.uuid4().hex}"
        self._stop = Event(self._stop_name, client=client)
        setup_f = client.scatter(setup, broadcast=True, hash=False)
        self._futures = [client.submit(_run_batch, setup_f, fn, b, self._stop_name, pure=False)
                         for b in batches(items, batch_size)]
        self._setup_f = setup_f
        self._seen = set()
        self._ready = []
        self._ac = as_completed(self._futures)

    def _take(self, fut):
        self._seen.add(fut.key)
        try:
            return fut.result()
        except Exception as exc:
            raise TaskFailed(f"a Dask task failed: {type(exc).__name__}: {exc}") from exc

    def __next__(self):
        while not self._ready:
            try:
                fut = next(self._ac)
            except StopIteration:
                self.close()
                raise
            self._ready = list(reversed(self._take(fut)))
        return self._ready.pop()

    def stop(self):
        from distributed import wait

        done = list(reversed(self._ready))
        self._ready = []
        try:
            self._stop.set()
            running = [f for f in self._futures if f.key not in self._seen]
            wait(running, timeout=_POLL_SECONDS + 0.5)
            for f in running:
                if f.status == "finished":
                    done += f.result()
        except Exception:  # an interrupt must not fail on a cluster problem
            pass
        self.close()
        return done

    def close(self):
        if self._futures:
            try:
                self._client.cancel(self._futures + [self._setup_f])
                self._stop.clear()
            except Exception:
                pass
            self._futures = []


class DaskExecutor(Executor):
    """Tasks on a Dask cluster; see the module docstring for what travels."""

    kind = "dask"

    def __init__(self, workers=1, scheduler=None):
        try:
            import dask
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError("<arguments>", "--executor", "Dask installed for executor 'dask' "
                             "(pip install 'frf-nlp[dask]')", "dask") from None
        self._cluster = None
        if scheduler:
            try:
                self._client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError("<arguments>", "--scheduler", "the address of a running Dask "
                                 f"scheduler ({type(exc).__name__}: {exc})", scheduler) from None
            self.workers = max(1, len(self._client.scheduler_info()["workers"]))
        else:
            self.workers = max(1, int(workers))
            # processes, one thread each: IPOPT/MUMPS is not thread-safe. The statistical
            # profiler samples every 10 ms and took ~20 % of a worker's time on 10-ms solves.
            # glibc's default trimming, not Dask's MALLOC_TRIM_THRESHOLD_=65536: IPOPT and
            # CasADi allocate per iteration, and the forced trims cost 25-35 % CPU per solve
            with dask.config.set({"distributed.worker.profile.enabled": False,
                                  "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_":
                                  None}):
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                             processes=True, dashboard_address=":0",
                                             silence_logs=logging.ERROR)
            self._client = Client(self._cluster)

    def stream(self, setup, fn, items, batch_size=None):
        return _DaskStream(self._client, setup, fn, items, self.workers, batch_size)

    def close(self):
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None
