"""Command-line overrides of a loaded case: --starts, --seed, --workers, --executor,
--scheduler and --solver replace the case file's search and solver settings."""

from dataclasses import replace

from nlp.case.reader import scheduler_address
from nlp.case.schema import SOLVERS
from nlp.errors import ARGUMENTS, InputError

__all__ = ["apply_overrides"]


def apply_overrides(cfg, ov, rd):
    """The case ``cfg`` with the CLI overrides ``ov`` (a dict, None values ignored); ``rd``:
    the case file's Reader, to name the file when a setting of it conflicts."""
    search, solver = cfg.search, cfg.solver
    for key in ("starts", "seed", "workers"):
        if ov.get(key) is not None:
            v = ov[key]
            if key != "seed" and v < 1:
                raise InputError(ARGUMENTS, f"--{key}", "an integer >= 1", v)
            search = replace(search, **{key: int(v)})
    if ov.get("executor") is not None:
        search = replace(search, executor=ov["executor"])
    if ov.get("scheduler") is not None:
        search = replace(search, scheduler=scheduler_address(
            lambda k, e, g: InputError(ARGUMENTS, k, e, g), ov["scheduler"], "--scheduler"))
    if search.scheduler is not None and search.executor != "dask":
        raise InputError(ARGUMENTS if ov.get("scheduler") else rd.file, "--scheduler"
                         if ov.get("scheduler") else "search.scheduler",
                         "executor 'dask' with a scheduler (--executor dask)", search.executor)
    if ov.get("solver") is not None:
        if ov["solver"] not in SOLVERS:
            raise InputError(ARGUMENTS, "--solver", f"one of {list(SOLVERS)}", ov["solver"])
        if ov["solver"] != solver.name:
            solver = replace(solver, name=ov["solver"], options={})
    return replace(cfg, search=search, solver=solver)
