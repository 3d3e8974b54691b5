"""Result files: result.json and the Table-1-like parameters.csv, written atomically."""

import csv
import io
import json
import os
import tempfile

import numpy as np
import scipy.sparse as sp

from nlp.output.flags import (bound_flag, iteration_flag, misfit_flag, single_start_flag,
                              undetermined_flag)
from nlp.frf.noise import sigma_ln
from nlp.frf.reference import channel_frfs, modal_parameters
from nlp.solve.identify import jacobian_report, standard_errors
from nlp.frf.metrics import fdac

__all__ = ["summarize", "write_atomic", "write_json", "jsonable", "parameters_table", "UNITS",
           "MATRIX_MAX", "with_matrix_file", "load_matrices"]

UNITS = {"stiffness": "N/m", "mass": "kg", "damping": "-"}
MATRIX_MAX = 200  # DOFs: above, M, K, C go to an NPZ file in sparse (CSC) form, not into the JSON


def write_atomic(path, data, mode="w"):
    """Write to a temporary file beside ``path`` and rename it into place."""
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-")
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; results are ordinary files
        with os.fdopen(fd, mode) as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_json(path, obj):
    """Write ``obj`` as indented JSON atomically (numpy arrays and scalars converted)."""
    write_atomic(path, json.dumps(obj, indent=2, default=jsonable) + "\n")


def jsonable(x):
    """``json.dumps`` default: numpy arrays as lists, numpy scalars as Python numbers."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    raise TypeError(type(x).__name__)


def with_matrix_file(doc, key, folder, name="matrices.npz"):
    """``doc`` ready for JSON: large matrices under ``key`` moved to ``folder/name``.

    ``doc[key]`` maps labels to {"M", "K", "C"} arrays (or is one such dict). Up to
    MATRIX_MAX DOFs the doc is returned as it is; above, the matrices are written
    sparse (CSC, :func:`load_matrices` reads them back) and ``doc[key]`` becomes
    {"file": name, "storage": ..., "n": n}. ``doc`` itself is not changed.
    """
    mats = doc[key]
    nested = "M" not in mats
    groups = mats if nested else {"": mats}
    n = np.shape(next(iter(groups.values()))["M"])[0]
    if n <= MATRIX_MAX:
        return doc
    arrays = {}
    for label, g in groups.items():
        for k, A in g.items():
            A = sp.csc_matrix(np.asarray(A) if not sp.issparse(A) else A)
            A.eliminate_zeros()
            pre = f"{label}_{k}" if label else k
            arrays.update({pre + "_data": A.data, pre + "_indices": A.indices,
                           pre + "_indptr": A.indptr, pre + "_shape": np.array(A.shape)})
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_atomic(os.path.join(folder, name), buf.getvalue(), mode="wb")
    return {**doc, key: {"file": name, "n": int(n),
                         "storage": f"scipy.sparse CSC: <label>_<M|K|C>_data/indices/indptr/shape "
                                    f"(n > {MATRIX_MAX} DOFs; nlp.output.results.load_matrices)"}}


def load_matrices(path):
    """{label: {"M", "K", "C"}} (or {"M", "K", "C"}) as scipy.sparse CSC from a matrices NPZ."""
    with np.load(path) as z:
        out = {}
        for pre in sorted({k.rsplit("_", 1)[0] for k in z.files}):
            A = sp.csc_matrix((z[pre + "_data"], z[pre + "_indices"], z[pre + "_indptr"]),
                              shape=tuple(z[pre + "_shape"]))
            label, _, k = pre.rpartition("_")
            (out.setdefault(label, {}) if label else out)[k] = A
    return out


def _physical(p, value):
    return p.nominal * (1 + value) if p.nominal is not None else value


def _modal(M, C, K):
    fn, zeta, _ = modal_parameters(M, C, K)
    return {"natural_frequencies_hz": fn, "damping_ratios": zeta}


def _parameter_rows(params, theta0, theta, se_theta, spread):
    """(rows, flags): one result.json row per parameter (physical values), at-bound flags."""
    rows = []
    flags = []
    for i, p in enumerate(params.params):
        scale = p.nominal if p.nominal is not None else 1.0
        se = 0.0 if p.fixed else float(scale * se_theta[i])
        flag = None if p.fixed else bound_flag(
            p.name, _physical(p, theta[i]), _physical(p, p.lower), _physical(p, p.upper),
            UNITS[p.group], _bound_keys(p))
        if flag:
            flags.append(flag)
        rows.append({
            "name": p.name, "group": p.group, "unit": p.unit or UNITS[p.group],
            "initial": _physical(p, theta0[i]), "updated": _physical(p, theta[i]),
            "relative_change": float(theta[i]) if p.nominal is not None else None,
            "lower": _physical(p, p.lower), "upper": _physical(p, p.upper),
            "fixed": p.fixed, "tie": p.tie,
            # at a bound the Gauss-Newton error does not hold: no number, say why
            "standard_error": None if flag else se,
            "at_bound": flag["bound"] if flag else None,
            "standard_error_if_interior": se if flag else None,
            "spread_near_best": {"min": _physical(p, spread["min"][i]),
                                 "max": _physical(p, spread["max"][i])},
        })
    return rows, flags


def _fit_flags(case, search, Ha):
    """Flags of the fit as a whole: a best objective one start reached, a misfit far
    above the data's noise (:mod:`nlp.output.flags`)."""
    converged = sum(1 for r in search.results if r.success)
    flags = [single_start_flag(len(search.near_best), converged, search.rel_tol)]
    tg = case.target
    used = tg.weight > 0
    with np.errstate(all="ignore"):
        err = np.log(np.abs(Ha)) - np.log(np.abs(tg.H))
    sig = sigma_ln(case, case.selected)
    if sig.shape == err.shape and used.any():
        flags.append(misfit_flag(float(np.sqrt(np.mean(err[used] ** 2))),
                                 float(np.sqrt(np.mean(sig[used] ** 2))), int(used.sum())))
    return [f for f in flags if f]


def _search_section(cfg, search):
    """The ``search`` entry of result.json: the starts and how the search ended."""
    return {"seed": cfg.search.seed, "trial_points": search.n_trial,
            "starts_requested": search.n_requested, "starts_finished": len(search.results),
            "interrupted": search.interrupted, "seconds": search.seconds,
            "starts_within_1pct_of_best": len(search.near_best),
            "starts_resumed": search.resumed,
            # starts that stopped at a limit but agree on the minimum (search.agreed_minimum)
            "starts_agreeing_at_limit": list(search.agreed),
            # success: converged (only those compete); f is null for a failed solve
            "starts": [{"index": i, "f": r.f if np.isfinite(r.f) else None,
                        "success": r.success, "status": r.status,
                        "iterations": r.iterations, "prefit_iterations": r.prefit_iterations,
                        "seconds": r.seconds}
                       for i, r in zip(search.indices, search.results)]}


def _open_relative(params, se_theta, at_bound):
    """Indices of the free relative parameters the undetermined flag judges: one per tied
    group, none on a bound (its own flag says so, and its Gauss-Newton error does not hold)."""
    rel, ties = [], set()
    for i, p in enumerate(params.params):
        if p.nominal is not None and not p.fixed and se_theta[i] > 0 and p.tie not in ties \
                and p.name not in at_bound:
            rel.append(i)
            if p.tie:
                ties.add(p.tie)
    return rel


def summarize(case, problem, search):
    """The content of result.json for a finished (or interrupted) search."""
    params = case.params
    z_best = search.best.z
    theta0 = np.array([p.initial for p in params.params])
    theta = problem.theta(z_best)
    r, J = problem.residuals(z_best)
    G = problem.constraint_jacobian()
    cov_z, s2, dof = standard_errors(J, r, problem.n_used, G)
    cov_theta = params.T @ cov_z @ params.T.T
    se_theta = np.sqrt(np.clip(np.diag(cov_theta), 0, None))
    search_doc = _search_section(case.config, search)
    rows, flags = _parameter_rows(params, theta0, theta, se_theta, search.spread(problem.theta))
    M0, K0, C0 = problem.matrices(params.z0)
    M, K, C = problem.matrices(z_best)
    tg = case.target
    Ha0 = channel_frfs(M0, C0, K0, tg.omega, case.channels, tg.excitation,
                      tg.force_dof, tg.ground_r)
    Ha = channel_frfs(M, C, K, tg.omega, case.channels, tg.excitation,
                      tg.force_dof, tg.ground_r)
    cfg = case.config
    limit = iteration_flag(search.best, search.results, cfg.solver.name,
                           agreed=len(search.agreed))
    if limit:
        flags.append(limit)
    flags += _fit_flags(case, search, Ha)
    rel = _open_relative(params, se_theta, {f["subject"] for f in flags if f["kind"] == "at_bound"})
    weak = undetermined_flag(cov_theta[np.ix_(rel, rel)], [params.params[i].name for i in rel],
                             theta[rel])
    if weak:
        flags.append(weak)
    return {
        "case": cfg.name, "case_file": cfg.path,
        "flags": flags,
        "excitation": {"type": tg.excitation,
                       "floor": None if tg.force_dof is None else tg.force_dof + 1},
        "residual": cfg.objective.residual,
        "frequencies_hz": (tg.omega / (2 * np.pi)),
        "n_residuals": problem.n_used,
        "parameters": rows,
        "matrices": {"initial": {"M": M0, "K": K0, "C": C0}, "updated": {"M": M, "K": K, "C": C}},
        "modal": {"initial": _modal(M0, C0, K0), "updated": _modal(M, C, K)},
        "objective": {"initial": problem.objective(params.z0), "updated": search.best.f,
                      "noise_variance_estimate": s2, "degrees_of_freedom": dof},
        "fdac": {"initial": dict(zip([c.name for c in case.channels], fdac(Ha0, tg.H))),
                 "updated": dict(zip([c.name for c in case.channels], fdac(Ha, tg.H)))},
        "identifiability": {
            "scale": ("anchored by total mass" if cfg.parameters.total_mass is not None
                      else "fixed by force input" if tg.excitation == "force"
                      else "anchored by fixed mass parameter(s)"),
            **jacobian_report(J, params.z_names, G=G)},
        "solver": {"name": cfg.solver.name, "options": cfg.solver.options,
                   "compiled": problem.compiled, "status": search.best.status,
                   "iterations": search.best.iterations, "seconds": search.best.seconds},
        "search": search_doc,
    }


def _bound_keys(p):
    """The case-file keys that set a parameter's bounds."""
    group = {"stiffness": "parameters.stiffness_bounds", "mass": "parameters.mass_bounds"}
    return f"parameters.bounds.{p.name}" + (f" or {group[p.group]}" if p.group in group else "")


def _cell(p, key):
    if key == "standard_error" and p[key] is None:
        return f"n/a (at {p.get('at_bound') or 'a'} bound)"
    return f"{p[key]:.6g}"


def parameters_table(result):
    """Table 1 layout: a column per mass/stiffness, rows initial/updated/error/bounds."""
    cols = [p for p in result["parameters"] if p["group"] in ("mass", "stiffness")]
    cols.sort(key=lambda p: (p["group"] != "mass",))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["Parameter (kg or N/m)"] + [p["name"] for p in cols])
    for label, key in (("Initial", "initial"), ("Updated", "updated"),
                       ("Standard error", "standard_error"), ("Lower bound", "lower"),
                       ("Upper bound", "upper")):
        w.writerow([label] + [_cell(p, key) for p in cols])
    w.writerow(["Fixed"] + ["yes" if p["fixed"] else "no" for p in cols])
    return buf.getvalue()
