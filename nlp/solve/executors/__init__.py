"""Executors: where independent tasks that share one built problem run.

One small interface for every parallel part of the package (scatter-search
starts, diagnosis refits, batch runs)::

    from nlp.solve.executors import Setup, make_executor

    setup = Setup(build_problem, case, value=problem)   # recipe + (optional) the built object
    with make_executor("local", workers=2) as ex:        # or "dask" (scheduler=...), "serial"
        stream = ex.stream(setup, solve_one, [(key, item), ...])
        for key, result in stream:                       # each result as soon as it finishes
            ...

``solve_one(context, item)`` is a module-level function; ``context`` is what
``setup`` builds, built once per worker process and reused for every item.
Results arrive in completion order; callers that need determinism sort by key.
On an interrupt the caller calls ``stream.stop()``, which returns the results
that finished meanwhile, and then ``stream.close()``.
"""

from nlp.solve.executors.base import Executor, Setup, Stream, TaskFailed
from nlp.solve.executors.dask import DaskExecutor
from nlp.solve.executors.local import LocalExecutor, SerialExecutor
from nlp.solve.executors.signals import interrupts_as_keyboard

__all__ = ["Executor", "Setup", "Stream", "TaskFailed", "EXECUTORS", "make_executor",
           "interrupts_as_keyboard"]

EXECUTORS = ("local", "dask", "serial")


def make_executor(kind="local", workers=1, scheduler=None):
    """An executor by name.

    Parameters
    ----------
    kind : {"local", "dask", "serial"}
        ``local``: worker processes on this machine (fork where available),
        one thread each. ``dask``: a Dask distributed cluster at ``scheduler``
        (``tcp://host:port``) or, without one, an in-process LocalCluster of
        ``workers`` single-threaded worker processes. ``serial``: in this
        process (for debugging and for callers that are themselves workers).
    workers : int
        Worker processes (ignored with a scheduler: the cluster decides).
    scheduler : str, optional
        Address of a running Dask scheduler.
    """
    if kind == "local":
        return LocalExecutor(workers)
    if kind == "serial":
        return SerialExecutor()
    if kind == "dask":  # dask and distributed are imported when the executor starts
        return DaskExecutor(workers, scheduler)
    raise ValueError(f"executor must be one of {EXECUTORS}, got {kind!r}")
