"""The Python API: the steps of the ``frf-nlp`` command, returning typed results.

Each call writes the same folder as the command (transactionally: a failed call
leaves no half-written folder) and returns the content of its JSON files as a
frozen dataclass, with the file's whole content in ``.data``::

    import nlp
    case = nlp.load_case("cases/four_story_shear_frame/case.yaml")
    result = nlp.run(case, out="results/four_story", starts=4, seed=0)
    result.parameters["k1"].updated        # N/m
    result.objective                       # Eqn 25 objective at the optimum

Units are SI throughout (kg, N/m, N s/m, Hz). Overrides (``starts``, ``seed``,
``workers``, ``solver``, ``executor``, ``scheduler``) are those of the command line and
are validated the same way; a mistake raises :class:`nlp.errors.InputError` naming
the key and what is expected.
"""

import json
import os
from dataclasses import dataclass, field

from nlp.case.load import load_case as _load_config
from nlp.diagnosis.driver import diagnose as _diagnose
from nlp.errors import InputError
from nlp.monitoring.campaign import find_records, run_batch
from nlp.output.outdir import check_writable, output_folder
from nlp.output.report import write_report
from nlp.solve.executors.threads import one_blas_thread
from nlp.workflow.update import run as _run

__all__ = ["ParameterEstimate", "UpdateResult", "RunResult", "Diagnosis", "BatchResult",
           "load_case", "run", "diagnose", "batch"]

OVERRIDES = ("starts", "seed", "workers", "solver", "executor", "scheduler")


@dataclass(frozen=True)
class ParameterEstimate:
    """One updating parameter of result.json, in physical units (``unit``).

    ``standard_error`` is the Gauss-Newton error of ``updated``; it is None when the
    parameter sits at a bound (the error does not hold there) and 0 when it is fixed.
    """
    name: str
    group: str
    unit: str
    initial: float
    updated: float
    standard_error: "float | None"
    lower: float
    upper: float
    fixed: bool

    @classmethod
    def from_row(cls, row):
        """From one entry of result.json's ``parameters``."""
        return cls(row["name"], row["group"], row["unit"], row["initial"], row["updated"],
                   row["standard_error"], row["lower"], row["upper"], row["fixed"])


@dataclass(frozen=True)
class UpdateResult:
    """One update of a run (``result.json``): its parameters, objective and flags."""
    name: str
    folder: str
    objective: float
    objective_initial: float
    parameters: dict
    flags: list
    data: dict = field(repr=False)

    @classmethod
    def read(cls, folder, name=""):
        """Read ``folder/result.json``."""
        with open(os.path.join(folder, "result.json")) as fh:
            doc = json.load(fh)
        params = {r["name"]: ParameterEstimate.from_row(r) for r in doc["parameters"]}
        return cls(name, folder, doc["objective"]["updated"], doc["objective"]["initial"],
                   params, doc["flags"], doc)


@dataclass(frozen=True)
class RunResult:
    """A finished run: its updates (one per ``updates`` entry of the case, else one) and
    ``summary.json`` (the final, averaged model); ``status`` is 0, or 130 when it was
    interrupted and kept the starts that had finished."""
    out: str
    status: int
    updates: dict
    summary: dict = field(repr=False)

    def _only(self):
        if len(self.updates) != 1:
            raise ValueError(f"this run has {len(self.updates)} updates "
                             f"({', '.join(self.updates)}): use .updates[name]")
        return next(iter(self.updates.values()))

    @property
    def objective(self):
        """The objective of the single update at its optimum."""
        return self._only().objective

    @property
    def parameters(self):
        """The parameters of the single update, by name."""
        return self._only().parameters

    @property
    def flags(self):
        """Every flag the run raised, each naming its update (summary.json)."""
        return self.summary["flags"]


@dataclass(frozen=True)
class Diagnosis:
    """A finished diagnosis (``diagnosis.json``): the verdict and the findings."""
    out: str
    verdict: "str | None"
    findings: list
    data: dict = field(repr=False)


@dataclass(frozen=True)
class BatchResult:
    """A finished batch (``changes.json``): the parameter steps found per parameter."""
    out: str
    status: int
    changes: dict
    data: dict = field(repr=False)


def load_case(path, **overrides):
    """The case file at ``path``, validated once and typed (:class:`nlp.case.load.CaseConfig`);
    ``overrides`` as on the command line (``starts=8, seed=1``)."""
    return _load_config(path, _overrides(overrides))


def _overrides(given):
    unknown = sorted(set(given) - set(OVERRIDES))
    if unknown:
        raise InputError("<arguments>", unknown[0], f"one of {list(OVERRIDES)}", given[unknown[0]])
    return {k: given.get(k) for k in OVERRIDES}


def _config(case, overrides):
    """The typed case with overrides applied (re-read and validated when there are any)."""
    if isinstance(case, (str, os.PathLike)):
        return load_case(case, **overrides)
    if any(v is not None for v in overrides.values()):
        return load_case(case.path, **overrides)
    return case


def _folder(out):
    out = os.path.abspath(out)
    check_writable(out)
    return out


def run(case, out, resume=False, log=print, **overrides):
    """Update the case's model (Eqn 25) into folder ``out``, as ``frf-nlp run`` does.

    ``case`` is a path or a loaded case; overrides given here re-read the case file
    (so they are validated as the command line's are).
    """
    cfg = _config(case, overrides)
    out = _folder(out)
    with output_folder(out, "run") as stage, one_blas_thread():
        status = _run(cfg, stage, log=log, resume=resume, ckpt_out=out)
        stage.interrupted = status == 130
    with open(os.path.join(out, "summary.json")) as fh:
        summary = json.load(fh)
    updates = {n: UpdateResult.read(os.path.join(out, n) if n else out, n)
               for n in summary["updates"] or [""]}
    return RunResult(out, status, updates, summary)


def diagnose(case, out, resume=False, log=print, budget=None, **overrides):
    """Find what physics the model leaves out, as ``frf-nlp diagnose`` does.

    Each finished search and round of refits is kept in ``out.partial/diagnosis/`` until
    the diagnosis completes; ``resume`` continues an interrupted one from there (the same
    diagnosis.json as without the interruption). budget [min]: no stage starts after it is
    spent; the result says where it stopped, and the steps stay for ``resume``.
    """
    cfg = _config(case, overrides)
    out = _folder(out)
    with output_folder(out, "diagnose") as stage, one_blas_thread():
        _diagnose(cfg, stage, log=log, resume=resume, ckpt_out=out,
                  budget=None if budget is None else 60.0 * budget)
        write_report(stage)
    with open(os.path.join(out, "diagnosis.json")) as fh:
        doc = json.load(fh)
    return Diagnosis(out, doc.get("verdict"), doc.get("findings", []), doc)


def batch(case, records, out, resume=False, log=print, **overrides):
    """Update the same model from every record (files, folders or glob patterns), as
    ``frf-nlp batch`` does; returns the steps found in each parameter's history."""
    cfg = _config(case, overrides)
    out = os.path.abspath(out)
    paths = find_records([records] if isinstance(records, str) else records)
    with one_blas_thread():
        status = run_batch(cfg, paths, out, resume=resume, log=log)
    with open(os.path.join(out, "changes.json")) as fh:
        doc = json.load(fh)
    return BatchResult(out, status, doc["changes"], doc)
