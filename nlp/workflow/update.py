"""One run of a case: updates, their average, verification and the report.

A case updates the model once, or once per group of channels (``updates:``,
e.g. accelerances and receptances separately, as in Table 1) and averages the
updated matrices. The final model is then checked against the data: FDAC of
every channel, the held-out test file when the case names one, and the
measured input replayed in the time domain when the data are records.
"""

from dataclasses import replace
import os
import shutil
import time

import numpy as np

from nlp.case.joint import label_of
from nlp.case.assemble import assemble, build_problem
from nlp.case.selection import detection_form, detection_noise
from nlp.solve.checkpoint import Checkpoint, checkpoint_path
from nlp.case.schema import ExcitationConfig
from nlp.frf.reference import channel_frfs, modal_parameters
from nlp.output.flags import replay_flags
from nlp.frf.freqsel import plot_selection
from nlp.frf.metrics import fdac, fdac_overall, frac
from nlp.frf.peakpick import compare_modes
from nlp.output.plots import frf_quantity, plot_frf_overlays
from nlp.output.provenance import provenance
from nlp.workflow.recentre import recentre
from nlp.solve.continuation import band_continuation
from nlp.output.report import write_report
from nlp.output.results import parameters_table, summarize, with_matrix_file, write_atomic, write_json
from nlp.solve.executors import Setup
from nlp.solve.search import SearchConfig, scatter_search
from nlp.workflow.verify import plot_replay, replay

__all__ = ["run"]


def _update(cfg, label, channels, out, log, prov, checkpoint=None):
    case = assemble(cfg, channels=channels)
    tag = f"[{label}] " if label else ""
    log(f"{tag}case {cfg.name}: {case.model.n} DOF, {case.params.n_z} free parameters, "
        f"{len(case.channels)} channels x {case.selected.size} frequency points "
        f"({case.f[case.selected].min():.3g}-{case.f[case.selected].max():.3g} Hz), "
        f"residual {cfg.objective.residual}, solver {cfg.solver.name}")
    t0 = time.perf_counter()
    problem = build_problem(case)
    log(f"{tag}NLP built in {time.perf_counter() - t0:.2f} s ({problem.describe()})")
    s = cfg.search
    search = scatter_search(problem, SearchConfig.of(s),
                            setup=Setup(build_problem, case, value=problem), checkpoint=checkpoint)
    if search.resumed:
        log(f"{tag}resumed {search.resumed} finished starts from {checkpoint.path}")
    if cfg.search.band_continuation and not search.interrupted:
        # one more start: fit the low band first, then widen it (nlp.solve.continuation)
        c_problem, c_res = band_continuation(case, cfg.search.band_continuation,
                                             log=lambda m: log(tag + m))
        search = _with_start(search, c_res)
        if c_res.success and c_res.f < search.best.f:
            log(f"{tag}band continuation beats the search's best start (f {c_res.f:.6g} < "
                f"{search.best.f:.6g})")
            problem, search = c_problem, replace(search, best=c_res)
    recentred = None
    if problem.backend == "reduced" and not search.interrupted:
        # the search ran on the nominal basis: move the basis to the fit and refit (nlp.workflow.recentre)
        problem, best, recentred = recentre(case, problem, search.best,
                                            log=lambda m: log(tag + m))
        search = replace(_with_start(search, best), best=best)
    result = summarize(case, problem, search)
    if recentred is not None:
        result["reduced_basis"] = recentred
    result["provenance"] = prov
    os.makedirs(out, exist_ok=True)
    write_json(os.path.join(out, "result.json"), with_matrix_file(result, "matrices", out))
    table = parameters_table(result)
    write_atomic(os.path.join(out, "parameters.csv"), table)
    mats = result["matrices"]
    plot_frf_overlays(out, case, tuple(np.asarray(mats["initial"][k]) for k in "MKC"),
                      tuple(np.asarray(mats["updated"][k]) for k in "MKC"))
    shown = case.f <= 1.5 * case.f[case.selected].max()
    plot_selection(case.f[shown], case.H[:, shown], case.selected,
                   os.path.join(out, "selection.png"), channel_names=[c.name for c in case.channels])
    _log_result(result, table, log, tag)
    return case, result, search.interrupted


def _with_start(search, res):
    """The search with one more finished local solve (listed after its starts)."""
    return replace(search, results=search.results + [res],
                   indices=list(search.indices) + [max(search.indices, default=-1) + 1])


def _log_result(result, table, log, tag):
    srch = result["search"]
    log(f"{tag}search: {srch['starts_finished']}/{srch['starts_requested']} local solves in "
        f"{srch['seconds']:.2f} s; {srch['starts_within_1pct_of_best']} within 1 % of the best"
        + ("  (INTERRUPTED: partial result)" if srch["interrupted"] else ""))
    obj = result["objective"]
    log(f"{tag}objective: {obj['initial']:.4g} -> {obj['updated']:.4g}  "
        f"(best start: {result['solver']['status']}, {result['solver']['iterations']} iterations)")
    for line in table.strip().splitlines()[:4]:
        log("  " + line.replace(",", "\t"))
    for wk in result["identifiability"]["weak_directions"]:
        log(f"{tag}warning: weakly identified combination {wk['combination']} "
            f"(sigma ratio {wk['sigma_ratio']:.1e})")
    _log_flags(result.get("flags", ()), log, tag)


def _log_flags(flags, log, tag=""):
    for fl in flags:
        log(f"{tag}WARNING ({fl['kind']}): {fl['message']}")
        log(f"{tag}  what it means / what to do: {fl['advice']}")


def _fdac_of(model, case):
    """FDAC per channel, FDAC overall and FRAC per channel of a model against a case's data."""
    M, K, C = model
    tg = case.target
    Ha = channel_frfs(M, C, K, tg.omega, case.channels, tg.excitation, tg.force_dof,
                      tg.ground_r)
    names = [c.name for c in case.channels]
    # FRAC compares complex FRFs: magnitude-only data have no phase to compare
    fr = frac(Ha, tg.H).tolist() if case.has_phase else [None] * len(names)
    return (dict(zip(names, fdac(Ha, tg.H).tolist())), float(fdac_overall(Ha, tg.H)),
            dict(zip(names, fr)))


def _modes_of(model, case):
    """Peak-picked modes of the measured FRFs against the model (frequency, damping, MAC)."""
    M, K, C = model
    fc = case.config.frequencies
    # a shape is read from one driving point: tests fitted jointly give their first test's
    rows = [i for i, ch in enumerate(case.channels) if label_of(ch) == ""]
    chans, H = tuple(case.channels[i] for i in rows), case.H[rows]
    det = detection_form(case.f, H, chans, case.target.excitation)
    sigma = None if case.noise is None else \
        detection_noise(case.f, H, det, chans, case.noise.detect[rows])
    return compare_modes(M, C, K, case.f, H, chans, detection=det,
                         fmin=fc.fmin, fmax=fc.fmax, phase=case.has_phase, sigma=sigma)


def _log_quality(q, log):
    """One line per screened channel with spikes or dropouts."""
    if not q["channels"]:
        log("records screened: no spikes or dropouts")
    for ch, c in q["channels"].items():
        name = ch.replace("__input__", "input")
        log(f"records: {name}: {c['spikes']} spikes, {c['dropouts']} dropouts "
            f"({100 * c['fraction_flagged']:.2g} % of samples)"
            + (", replaced by interpolation" if q["removed"] else
               " (data.screen.remove: true replaces them by interpolation)"))


def _table1(results, average):
    """Table 1: a column per mass and stiffness, a row per update and the average."""
    first = next(iter(results.values()))[1]
    cols = [p for p in first["parameters"] if p["group"] in ("mass", "stiffness")]
    cols.sort(key=lambda p: p["group"] != "mass")
    lines = [",".join(["Parameter (kg or N/m)"] + [p["name"] for p in cols]),
             ",".join(["Initial"] + [f"{p['initial']:.6g}" for p in cols])]
    for label, (_, res) in results.items():
        upd = {p["name"]: p["updated"] for p in res["parameters"]}
        lines.append(",".join([f"Updated ({label})"] + [f"{upd[p['name']]:.6g}" for p in cols]))
    lines.append(",".join(["Average of the updated"] + [f"{average[p['name']]:.6g}" for p in cols]))
    return "\n".join(lines) + "\n"


def _model_file(summary, out):
    """summary.json's model: large M, K, C to model.npz (sparse), modal data kept in the JSON."""
    model = summary["model"]
    mats = {k: model[k] for k in "MKC"}
    doc = with_matrix_file({"model": mats}, "model", out, name="model.npz")
    if doc["model"] is mats:
        return summary
    rest = {k: v for k, v in model.items() if k not in "MKC"}
    return {**summary, "model": {**rest, "matrices": doc["model"]}}


def _run_updates(cfg, out, log, prov, resume, ckpt_out):
    """({label: (case, result)}, interrupted): the case's updates, one per channel group."""
    groups = cfg.updates or {None: None}
    results = {}
    interrupted = False
    for label, channels in groups.items():
        d = out if label is None else os.path.join(out, label)
        ckpt = Checkpoint(checkpoint_path(ckpt_out or out, label), resume=resume)
        case, result, interrupted = _update(cfg, label, channels, d, log, prov, ckpt)
        results[label] = (case, result)
        if interrupted:
            break
    return results, interrupted


def _summary(cfg, results, model, interrupted, prov):
    """summary.json of the averaged model against every update's data (before validation
    and replay)."""
    M, K, C = model
    fn, zeta, _ = modal_parameters(M, C, K)
    summary = {"case": cfg.name, "updates": [k for k in results if k is not None],
               "interrupted": interrupted, "provenance": prov,
               "flags": [dict(fl, update=label) for label, (_, r) in results.items()
                         for fl in r.get("flags", ())],
               "model": {"M": M, "K": K, "C": C, "natural_frequencies_hz": fn,
                         "damping_ratios": zeta},
               "fdac": {}, "fdac_overall": {}, "frac": {}, "modes": {}}
    summary["channels"] = [
        dict(zip(("name", "quantity", "unit", "dof"),
                 (ch.name, *frf_quantity(ch.output, case.target.excitation), ch.dof + 1)))
        for case, _ in results.values() for ch in case.channels]
    for label, (case, _) in results.items():
        per, overall, fr = _fdac_of(model, case)
        summary["fdac"].update(per)
        summary["fdac_overall"][label or "all"] = overall
        summary["frac"].update(fr)
        summary["modes"][label or "all"] = _modes_of(model, case)
        if case.quality is not None:
            summary["data_quality"] = case.quality.to_dict()
    if not cfg.data.has_phase:
        summary["needs_phase"] = {"metrics": ["FRAC", "MAC"], "reason": f"data.format "
                                  f"{cfg.data.format} has no phase; FDAC compares magnitudes"}
    return summary


def _average_parameters(results):
    """Each parameter's updated value averaged over the updates."""
    avg = {}
    for name in [p["name"] for p in next(iter(results.values()))[1]["parameters"]]:
        avg[name] = float(np.mean([{p["name"]: p["updated"] for p in r["parameters"]}[name]
                                   for _, r in results.values()]))
    return avg


def _log_model(summary, log):
    """The final model's modes, FDAC, peak-picked modes and data quality."""
    model = summary["model"]
    log("final model: " + ", ".join(f"{f:.3f} Hz ({100 * z:.2f} %)" for f, z in
                                    zip(model["natural_frequencies_hz"], model["damping_ratios"])))
    log("FDAC: " + ", ".join(f"{k} {v:.4f}" for k, v in summary["fdac"].items()))
    for label, rows in summary["modes"].items():
        log(f"measured modes ({label}, peak picking) vs model: " + "; ".join(
            f"{r['f_measured_hz']:.3f} Hz {100 * r['frequency_error']:+.2f} %, "
            + ("MAC needs phase" if r["mac"] is None else f"MAC {r['mac']:.3f}") for r in rows))
    if "data_quality" in summary:
        _log_quality(summary["data_quality"], log)


def _validation(cfg, model, results, out, log):
    """The averaged model against the held-out test file: summary entry and overlays."""
    vcfg = cfg
    if cfg.data.validation_force_floor is not None:
        vcfg = replace(cfg, excitation=ExcitationConfig("force", cfg.data.validation_force_floor))
    vcase = assemble(vcfg, data_file=cfg.data.validation_file)
    per, overall, _ = _fdac_of(model, vcase)
    entry = {"file": cfg.data.validation_file, "fdac": per,
             "fdac_overall": overall,
             "excitation": {"type": vcase.target.excitation,
                            "floor": None if vcase.target.force_dof is None
                            else vcase.target.force_dof + 1},
             "frequencies_hz": (vcase.target.omega / (2 * np.pi))}
    vdir = os.path.join(out, "validation")
    os.makedirs(vdir, exist_ok=True)
    first = next(iter(results.values()))[1]["matrices"]["initial"]
    plot_frf_overlays(vdir, vcase, tuple(np.asarray(first[k]) for k in "MKC"), model)
    log(f"held-out test {os.path.basename(cfg.data.validation_file)}: FDAC "
        + ", ".join(f"{k} {v:.4f}" for k, v in per.items()))
    return entry


def _time_domain(model, records, cfg, out, log):
    """(summary entry, flags): the measured input replayed through the model, per channel."""
    M, K, C = model
    reps = replay(M, C, K, records, cfg.data)
    entry = {}
    for name, rep in reps.items():
        plot_replay(out, name, rep, cfg.closeup_seconds)
        entry[name] = {k: rep[k] for k in ("quantity", "nrmse", "correlation", "peak_error")}
    log("time domain NRMSE: " + ", ".join(f"{k} {100 * v['nrmse']:.1f} %"
                                         for k, v in entry.items()))
    rflags = replay_flags(entry)
    _log_flags(rflags, log)
    return entry, rflags


def run(cfg, out, log=print, resume=False, ckpt_out=None):
    """Run a validated case into folder ``out``; returns the exit status (0 or 130).

    Every finished start is kept in ``out.partial/`` (:mod:`nlp.solve.checkpoint`);
    ``resume`` continues from it, and a completed run removes it. ``ckpt_out``:
    the final --out when ``out`` is its staging folder (:mod:`nlp.output.outdir`), so the
    checkpoint lives beside the final folder, where ``--resume`` looks.
    """
    prov = provenance(cfg)
    results, interrupted = _run_updates(cfg, out, log, prov, resume, ckpt_out)
    mats = [r["matrices"]["updated"] for _, r in results.values()]
    model = tuple(np.mean([np.asarray(m[k]) for m in mats], axis=0) for k in "MKC")
    summary = _summary(cfg, results, model, interrupted, prov)
    if len(results) > 1:
        avg = _average_parameters(results)
        summary["average_parameters"] = avg
        write_atomic(os.path.join(out, "table1.csv"), _table1(results, avg))
    _log_model(summary, log)
    if cfg.data.validation_file:
        summary["validation"] = _validation(cfg, model, results, out, log)
    records = next(iter(results.values()))[0].records
    if records is not None:
        summary["time_domain"], rflags = _time_domain(model, records, cfg, out, log)
        summary["flags"] += rflags
    write_json(os.path.join(out, "summary.json"), _model_file(summary, out))
    write_report(out)
    if interrupted:
        log(f"interrupted: finished starts are kept in "
            f"{os.path.dirname(checkpoint_path(ckpt_out or out))}; continue with --resume")
        return 130
    shutil.rmtree(os.path.dirname(checkpoint_path(ckpt_out or out)), ignore_errors=True)
    return 0
