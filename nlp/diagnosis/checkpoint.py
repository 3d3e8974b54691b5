"""The checkpoint of a diagnosis: each finished search and round of refits, for --resume.

Where: ``DIR.partial/diagnosis/`` beside the output folder ``DIR`` (as the run's search
checkpoint, :mod:`nlp.solve.checkpoint`, so an interrupted diagnosis finds it), removed
when the diagnosis completes. It holds ``header.json`` (the format and a hash of the case,
its files and the diagnosis settings) and one file per finished step,
``NNN-<step>.pkl``, numbered in the order the pipeline reaches them. Each is written to a
temporary file and renamed into place, so a killed diagnosis leaves whole steps only.

On resume the pipeline runs again from the start: the stages between the steps are
deterministic and cheap, and each step found in the checkpoint (same number, same step,
same inputs) is read instead of computed, so the resumed diagnosis.json is the one an
uninterrupted diagnosis writes. A step whose inputs differ from the record (a changed
case is refused by the header before that) is computed again, and so are those after it.

Ctrl-C (SIGINT) or SIGTERM during a recorded diagnosis is held until the step running is
recorded, and the diagnosis stops there (exit status 130): an in-process CasADi solve
turns a KeyboardInterrupt into a solve cut short and goes on, which would change the
diagnosis. A second Ctrl-C stops at once, losing the step running. A signal after the
last step lets the diagnosis finish and write its result.

The records are Python pickles of numbers, arrays and the candidates' dataclasses: read
only checkpoints this program wrote.
"""

from contextlib import contextmanager
import hashlib
import json
import os
import pickle
import shutil
import signal
import sys
import threading
import time

import numpy as np

from nlp import __version__
from nlp.diagnosis.fitting import diagnosis_problem
from nlp.diagnosis.refit import REFIT_ITER
from nlp.errors import InputError
from nlp.output.provenance import provenance
from nlp.output.results import write_atomic

__all__ = ["recording", "step", "logged_step", "refits_step", "repolish_step", "fingerprint",
           "checkpoint_dir", "budget_spent", "budget_over", "budget_note", "budget_report",
           "FORMAT"]

FORMAT = "frf-nlp-diagnosis-checkpoint/1"
_OPEN = []   # the checkpoint of the diagnosis running in this process (innermost last)


def checkpoint_dir(out):
    """Where the diagnosis checkpoint of output folder ``out`` lives."""
    return os.path.join(os.path.abspath(out).rstrip(os.sep) + ".partial", "diagnosis")


def fingerprint(*parts):
    """A short hash of a step's inputs: arrays by their bytes, anything else by repr."""
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, np.ndarray):
            h.update(np.ascontiguousarray(p, dtype=float).tobytes())
        else:
            h.update(repr(p).encode())
    return h.hexdigest()[:32]


def _case_hash(cfg, settings):
    """What decides every step: the case as loaded (overrides included), the bytes of its
    files, the diagnosis settings and the package version."""
    files = {p: f.get("sha256") for p, f in (provenance(cfg).get("files") or {}).items()}
    return fingerprint(repr(cfg), sorted(files.items()), settings, __version__)


class _Interrupts:
    """SIGINT and SIGTERM during a recorded diagnosis: the first is held (check raises it
    between steps), a second stops the process at once."""

    def __init__(self):
        self.pending, self.old = None, {}

    def install(self):
        if threading.current_thread() is not threading.main_thread():
            return   # signals are handled in the main thread only
        for s in (signal.SIGINT, signal.SIGTERM):
            self.old[s] = signal.getsignal(s)
            signal.signal(s, self.handler)

    def restore(self):
        for s, h in self.old.items():
            signal.signal(s, h)
        self.old = {}

    def handler(self, signum, frame):
        if self.pending is None:
            self.pending = signum
            sys.stderr.write("frf-nlp: interrupted: the diagnosis stops once the step running "
                             "is recorded for --resume (Ctrl-C again stops at once)\n")
            return
        self.restore()
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)

    def check(self):
        if self.pending is not None:
            raise KeyboardInterrupt(signal.Signals(self.pending).name)


class _Checkpoint:
    """The steps of one diagnosis on disk; ``resume`` reads the finished ones first."""

    def __init__(self, folder, header, resume):
        self.folder, self.n, self.reused, self.valid = folder, 0, 0, resume
        self.budget = None
        self.interrupts = _Interrupts()
        head = os.path.join(folder, "header.json")
        if resume:
            if not os.path.isfile(head):
                raise InputError("<arguments>", "--resume", "a checkpoint of an interrupted "
                                 f"diagnosis at {folder}; there is none (run without --resume)")
            with open(head) as fh:
                old = json.load(fh)
            if old != header:
                raise InputError(head, "hash", "the same case, data files and settings as the "
                                 "interrupted diagnosis, got a different one (run without "
                                 "--resume to start over)")
        else:
            shutil.rmtree(folder, ignore_errors=True)
            os.makedirs(folder)
            write_atomic(head, json.dumps(header) + "\n")

    def step(self, name, key, compute, dump, load):
        self.interrupts.check()
        self.n += 1
        path = os.path.join(self.folder, f"{self.n:03d}-{name}.pkl")
        if self.valid and os.path.isfile(path):
            with open(path, "rb") as fh:
                rec = pickle.load(fh)
            if rec["key"] == key:
                self.reused += 1
                return load(rec["value"])
        if self.valid:   # from here on the record no longer follows this diagnosis
            self.valid = False
            for f in os.listdir(self.folder):
                if f.endswith(".pkl") and int(f[:3]) >= self.n:
                    os.unlink(os.path.join(self.folder, f))
        value = compute()
        write_atomic(path, pickle.dumps({"key": key, "value": dump(value)}), mode="wb")
        self.interrupts.check()
        return value


class _Budget:
    """A diagnosis's time budget [s] from its start, and the stages it stopped before."""

    def __init__(self, seconds):
        self.seconds, self.t0, self.stops = float(seconds), time.monotonic(), []


def budget_spent(where):
    """Whether the diagnosis's time budget is spent as ``where`` (a stage) is about to start;
    False without a budget. The answer is recorded as a step, so a resumed diagnosis with the
    same budget decides as the first did (a different budget decides afresh)."""
    if not _OPEN or _OPEN[-1].budget is None:
        return False
    b = _OPEN[-1].budget
    spent = step("budget", fingerprint(where, b.seconds),
                 lambda: time.monotonic() - b.t0 > b.seconds)
    if spent:
        b.stops.append(where)
    return spent


def budget_over():
    """Whether the time budget is spent now, not recorded: for a loop inside a recorded step,
    whose value records what the loop did (False without a budget)."""
    b = _OPEN[-1].budget if _OPEN else None
    return b is not None and time.monotonic() - b.t0 > b.seconds


def budget_note(where):
    """Say that the diagnosis stopped short at ``where`` inside a recorded step."""
    if _OPEN and _OPEN[-1].budget is not None:
        _OPEN[-1].budget.stops.append(where)


def budget_report():
    """{"minutes", "stopped_before": [stages]} when the diagnosis stopped at its budget, else
    None."""
    b = _OPEN[-1].budget if _OPEN else None
    if b is None or not b.stops:
        return None
    return {"minutes": b.seconds / 60, "stopped_before": list(b.stops)}


@contextmanager
def recording(out, cfg, settings, resume=False, log=print, budget=None):
    """Record the steps of the diagnosis of ``cfg`` into ``out``'s checkpoint (``out``: the
    final output folder); with ``resume`` take the finished ones from it. The checkpoint
    is removed when the block completes and kept when it is interrupted or stopped at its
    time ``budget`` [s] (None: none), so that --resume with a larger one goes on."""
    folder = checkpoint_dir(out)
    ck = _Checkpoint(folder, {"format": FORMAT, "hash": _case_hash(cfg, settings)}, resume)
    ck.budget = _Budget(budget) if budget else None
    _OPEN.append(ck)
    ck.interrupts.install()
    try:
        yield ck
    except KeyboardInterrupt:
        done = sum(f.endswith(".pkl") for f in os.listdir(folder)) if os.path.isdir(folder) else 0
        log(f"diagnosis interrupted: {done} finished steps are kept in {folder}; continue "
            "with --resume")
        raise
    else:
        if resume:
            log(f"resumed: {ck.reused} finished steps taken from {folder}")
        if ck.interrupts.pending is not None:
            log("the interrupt came after the last recorded step: the diagnosis finished")
        if ck.budget is not None and ck.budget.stops:
            log(f"stopped at its time budget: the finished steps are kept in {folder}; "
                "--resume with a larger --budget goes on from them")
            return
        shutil.rmtree(folder, ignore_errors=True)
        try:
            os.rmdir(os.path.dirname(folder))   # DIR.partial, when nothing else is in it
        except OSError:
            pass
    finally:
        ck.interrupts.restore()
        _OPEN.remove(ck)


def _same(x):
    return x


def step(name, key, compute, dump=_same, load=_same):
    """``compute()``, recorded as the next step ``name`` with inputs ``key`` (see
    fingerprint) when a diagnosis is being recorded, and read from the record on resume.
    ``dump`` makes the value picklable (drops what can be rebuilt), ``load`` rebuilds it."""
    if not _OPEN:
        return compute()
    return _OPEN[-1].step(name, key, compute, dump, load)


def logged_step(name, key, compute, log):
    """A step whose ``compute(log)`` writes log lines: they are written as it runs and
    recorded, and written again when the step is read on resume."""
    lines = []

    def run():
        def both(*args, **kwargs):
            lines.append((args, kwargs))
            log(*args, **kwargs)
        return compute(both), lines

    value, said = step(name, key, run)
    if said is not lines:   # read from the record
        for args, kwargs in said:
            log(*args, **kwargs)
    return value


def _without_problems(results):
    """Refit results without their NLPs (CasADi functions do not pickle), each marked with
    whether it had one."""
    return [dict(r, problem=None, had_problem=r.get("problem") is not None) for r in results]


def refits_step(key, compute, case, target, current):
    """A round's candidate refits (nlp.diagnosis.refit.refit_all). On resume each NLP a
    refit kept is rebuilt as refit built it (capped at REFIT_ITER), so an adopted
    candidate's later solves are the uninterrupted diagnosis' own."""
    def load(results):
        out = []
        for r in results:
            r = dict(r)
            if r.pop("had_problem"):
                r["problem"] = diagnosis_problem(case, target, current + [r["enrichment"]],
                                                 optimize=False, max_iter=REFIT_ITER)
            out.append(r)
        return out
    return step("refits", key, compute, dump=_without_problems, load=load)


def repolish_step(key, compute, problem):
    """The re-solve of the current model (nlp.diagnosis.refit.repolish): None, or the new
    state, whose NLP is the current one (``problem``)."""
    return step("repolish", key, compute,
                dump=lambda v: None if v is None else dict(v, problem=None),
                load=lambda v: None if v is None else dict(v, problem=problem))
