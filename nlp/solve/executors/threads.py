"""One BLAS thread per process: the numeric FRF backends run many small matrix products,
and parallel work is spread over processes, not BLAS threads.

On a busy 2-core machine a multi-threaded BLAS made a 66 x 66 product 500x slower
(measured), so every entry point (:mod:`nlp.api`, hence the command) and every worker
that builds its context elsewhere limits BLAS to one thread at run time (threadpoolctl),
without touching the environment. An explicit user setting of the thread count wins.
"""

import os
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

__all__ = ["one_blas_thread", "limit_blas_threads"]

USER_SETTINGS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _user_chose():
    return any(k in os.environ for k in USER_SETTINGS)


@contextmanager
def one_blas_thread():
    """Inside the block BLAS uses one thread (unless the user set a thread count)."""
    if _user_chose():
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def limit_blas_threads():
    """Limit BLAS to one thread for the rest of this process (a worker's setup)."""
    if not _user_chose():
        threadpool_limits(limits=1, user_api="blas")
