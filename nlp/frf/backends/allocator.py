"""Keep freed memory in the process for the next evaluation of a numeric FRF backend.

One evaluation of r and J (:class:`nlp.frf.backends.sparse.SparseFRF`) allocates and frees
arrays of 0.1-30 MB. glibc's malloc hands blocks above its mmap threshold back to the
operating system when they are freed, and trims the top of its heap, so the next evaluation
faults every page in again: 3,500 page faults and 40 % of the wall time of one evaluation at
64 storeys (measured; a fault costs several microseconds on a virtual machine). A fixed
mmap threshold of 32 MB (glibc's largest) and a trim threshold of 512 MB keep those blocks
in the heap, where the next evaluation reuses them. Numbers are not touched. Elsewhere than
glibc the call does nothing.
"""

import ctypes

__all__ = ["retain_freed_memory"]

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc <malloc.h>
MMAP_THRESHOLD = 32 << 20
TRIM_THRESHOLD = 512 << 20
_done = []


def retain_freed_memory():
    """Set glibc's malloc thresholds once per process; True where they were set."""
    if not _done:
        try:
            mallopt = ctypes.CDLL(None).mallopt
            ok = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and \
                bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
        except (OSError, AttributeError):
            ok = False
        _done.append(ok)
    return _done[0]
