"""Progress a person can read: the stage, n/N done, elapsed and remaining time, on stderr.

tqdm draws the bars. When stderr is not a terminal, or in a worker process (the parent
that collects the results shows them), every reporter is a no-op, so piped output stays
exactly what the commands print without it and callers never branch::

    with stage("local solves", total=20, unit="start") as bar:
        for ... in results:
            bar.update(best_f=f"{f:.4g}")
            bar.note(f"start {i}: {its} iterations")

Pipelines (diagnosis) open a bar of steps once and advance it from the functions that
run them: ``with steps("diagnose", 8): ...`` there, ``advance("diagnose", "baseline")``
here (a no-op when no such bar is open).
"""

from contextlib import contextmanager
import multiprocessing as mp
import os
import sys

from tqdm import tqdm

__all__ = ["shown", "stage", "steps", "advance", "note"]

_OPEN = {}   # name -> the open steps bar of that name (this process only)


def shown():
    """Is progress shown here: stderr is a terminal and this is not a worker process?"""
    try:
        tty = sys.stderr.isatty()
    except (AttributeError, ValueError):  # replaced or closed stderr
        return False
    return tty and mp.parent_process() is None


def _columns():
    try:
        return os.get_terminal_size(sys.stderr.fileno()).columns
    except (OSError, ValueError, AttributeError):
        return 0


class _Quiet:
    """The reporter off a terminal: does nothing."""

    started = False   # a steps bar: has its first step begun?

    def update(self, n=1, **postfix):
        """Nothing."""

    def describe(self, text):
        """Nothing."""

    def note(self, text):
        """Nothing."""

    def around(self, log):
        """``log`` itself."""
        return log


class _Bar(_Quiet):
    """A tqdm bar on stderr."""

    def __init__(self, name, total, unit, initial, fmt=None):
        # leave=None: a finished outer bar stays as a record of its stage, a nested one (a
        # diagnosis' refits, a batch record's build) goes. A terminal that reports no size
        # (a bare pseudo-terminal) would get an empty bar: 100 x 24 then.
        sized = _columns() > 0
        self._bar = tqdm(total=total, desc=name, unit=unit, initial=initial, file=sys.stderr,
                         dynamic_ncols=sized, ncols=None if sized else 100,
                         nrows=None if sized else 24, leave=None, mininterval=0.2,
                         bar_format=fmt)
        self.name = name

    def update(self, n=1, **postfix):
        """n more done; ``postfix`` (e.g. best_f="0.03") shown after the counts."""
        if postfix:
            self._bar.set_postfix(postfix, refresh=False)
        if self._bar.total is not None and self._bar.n + n > self._bar.total:
            self._bar.total = self._bar.n + n  # a pipeline that takes a further look
        self._bar.update(n)

    def describe(self, text):
        """Show ``text`` after the bar's name (the step now running)."""
        self._bar.set_description(f"{self.name}: {text}")

    def note(self, text):
        """One line above the bar (terminal only)."""
        self._bar.write(text, file=sys.stderr)

    def around(self, log):
        """``log`` clearing the bars while it writes (a line on a terminal's stdout would
        otherwise land in the middle of the bar)."""
        def write(*args, **kwargs):
            with tqdm.external_write_mode(file=sys.stdout):
                log(*args, **kwargs)
        return write

    def close(self):
        # the final n/N is drawn even when the last updates came within mininterval of the
        # previous drawing (results of parallel workers arrive together), so a stage's bar
        # always ends at its count
        self._bar.refresh()
        self._bar.close()


# a pipeline's steps take unequal times: its bar shows the step running, n/N and the time
# elapsed, but no remaining time or rate (the nested bars of a step with a count do)
STEPS_FORMAT = "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed} elapsed]"


@contextmanager
def stage(name, total=1, unit="step", initial=0, show=True, fmt=None):
    """A reporter for one stage of ``total`` items (``initial`` already done); quiet off a
    terminal, in a worker, or with ``show=False``. ``update()`` after each item; ``fmt``:
    a tqdm bar_format in place of the default (n/N, elapsed < remaining, rate)."""
    bar = _Bar(name, total, unit, initial, fmt) if show and shown() else _Quiet()
    try:
        yield bar
    finally:
        if isinstance(bar, _Bar):
            bar.close()


@contextmanager
def steps(name, total):
    """A bar of the ``total`` named steps of a pipeline, advanced by :func:`advance`."""
    with stage(name, total, unit="stage", fmt=STEPS_FORMAT) as bar:
        outer = _OPEN.get(name)
        _OPEN[name] = bar
        try:
            yield bar
            if bar.started:
                bar.update()  # the last step is done
        finally:
            if outer is None:
                _OPEN.pop(name, None)
            else:
                _OPEN[name] = outer


def advance(name, label, step=True):
    """The open steps bar ``name`` moves on to step ``label`` (the previous one is done);
    ``step=False`` only relabels the step running (e.g. its round)."""
    bar = _OPEN.get(name)
    if bar is None:
        return
    if step and bar.started:
        bar.update()
    bar.started = True
    bar.describe(label)


def note(text, show=True):
    """One line on stderr when progress is shown there (e.g. after a bar closed)."""
    if show and shown():
        tqdm.write(text, file=sys.stderr)
