"""SIGINT and SIGTERM handled alike: both raise KeyboardInterrupt in the main thread.

Inside ``guard.deferred()`` (e.g. while a checkpoint line is written) the
interrupt waits until the block ends, so a received result is never half kept.
"""

import contextlib
import signal
import threading

__all__ = ["interrupts_as_keyboard"]


class _Guard:
    def __init__(self):
        self.depth = 0
        self.pending = False

    def handler(self, signum, frame):
        if self.depth:
            self.pending = True
            return
        raise KeyboardInterrupt(signal.Signals(signum).name)

    @contextlib.contextmanager
    def deferred(self, swallow=False):
        """Hold signals during the block; raise afterwards, or drop them with
        ``swallow`` (while already stopping, a second Ctrl-C asks the same)."""
        self.depth += 1
        try:
            yield
        finally:
            self.depth -= 1
            if self.depth == 0 and self.pending:
                self.pending = False
                if not swallow:
                    raise KeyboardInterrupt("deferred signal")


@contextlib.contextmanager
def interrupts_as_keyboard():
    """Within the block SIGINT and SIGTERM raise KeyboardInterrupt; yields the guard.

    Outside the main thread signals cannot be handled; the guard then only
    defers nothing.
    """
    guard = _Guard()
    if threading.current_thread() is not threading.main_thread():
        yield guard
        return
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    for s in old:
        signal.signal(s, guard.handler)
    try:
        yield guard
    finally:
        for s, h in old.items():
            signal.signal(s, h)
