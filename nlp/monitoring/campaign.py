"""Batch updating: the same model updated from every record of a campaign.

``frf-nlp batch CASE.yaml RECORDS... --out DIR`` runs the case's update (its
model, parameters, frequency selection, search) once per record, each record
taking the place of ``data.file``, and writes the parameter history:

* ``history.csv``: one row per record (time stamp, status, objective, every
  free physical parameter and its standard error);
* ``changes.json``: the steps found in each parameter history
  (:mod:`nlp.monitoring.changes`), with the record and time at which they happen;
* ``trend.png``: the history of every mass and stiffness (relative to its
  median over the records before the first change), with +-2 standard errors
  and the detected steps; ``report.html`` shows both.

Records are updated independently, so they run in worker processes and come
back as they finish; ``records.jsonl`` keeps each finished record, so an
interrupted batch resumed with ``--resume`` updates only the rest.
"""

import datetime as dt
import glob
import json
import os
import re
import time

import numpy as np

from nlp.case.assemble import assemble, build_problem
from nlp.errors import InputError, SearchFailed
from nlp.monitoring.changes import detect_changes
from nlp.monitoring.report import plot_trend, write_batch_report
from nlp.output.progress import stage
from nlp.output.provenance import provenance
from nlp.output.results import jsonable, summarize, write_atomic, write_json
from nlp.solve.executors import Setup, interrupts_as_keyboard, make_executor
from nlp.solve.search import SearchConfig, scatter_search

__all__ = ["find_records", "record_time", "update_record", "history_table", "run_batch"]

_STAMP = re.compile(r"(\d{4})-?(\d{2})-?(\d{2})(?:[T_ ]?(\d{2})[:\-]?(\d{2})(?:[:\-]?(\d{2}))?)?")
_EXTS = (".npz", ".csv", ".txt", ".mat", ".uff", ".unv")


def find_records(items, source="<arguments>"):
    """Record files from paths, folders (their data files) and glob patterns, sorted.

    Raises InputError when an item matches nothing.
    """
    found = []
    for it in items:
        if os.path.isdir(it):
            hits = [os.path.join(it, n) for n in os.listdir(it) if n.lower().endswith(_EXTS)]
        elif any(ch in it for ch in "*?["):
            hits = glob.glob(it)
        else:
            hits = [it] if os.path.isfile(it) else []
        if not hits:
            raise InputError(source, "RECORDS", "record files, folders holding them, or glob "
                             "patterns that match some", it)
        found += hits
    return sorted(dict.fromkeys(os.path.abspath(h) for h in found))


def record_time(path):
    """ISO 8601 time stamp of a record: the ``timestamp`` array of an NPZ file, else a
    date (and time) in the file name such as ``rec_2026-01-05T0600.npz``; None if neither."""
    if path.lower().endswith(".npz"):
        try:
            with np.load(path, allow_pickle=False) as z:
                if "timestamp" in z.files:
                    return str(z["timestamp"])
        except (OSError, ValueError):
            pass
    m = _STAMP.search(os.path.basename(path))
    if not m:
        return None
    y, mo, d, h, mi, s = (int(g) if g else 0 for g in m.groups())
    try:
        return dt.datetime(y, mo, d, h, mi, s).isoformat(timespec="minutes")
    except ValueError:
        return None


def update_record(cfg, path):
    """Update the case's model from one record; a JSON-able row of the history.

    A record that cannot be used (bad data, no converged solve) gives a row with
    ``status`` saying why and no parameters: one bad record does not stop a
    campaign.
    """
    row = {"record": os.path.basename(path), "path": path, "time": record_time(path)}
    t0 = time.perf_counter()
    try:
        case = assemble(cfg, data_file=path)
        problem = build_problem(case)
        s = cfg.search
        # the record is already one task of the batch's executor: its starts run here
        with make_executor("serial") as ex:
            search = scatter_search(problem, SearchConfig.of(s, workers=1),
                                    progress=False, executor=ex)
        res = summarize(case, problem, search)
    except InputError as exc:
        row["status"] = f"input error: {exc}"
        return row
    except SearchFailed as exc:
        row["status"] = f"no converged solve: {exc}"
        return row
    row["status"] = "ok"
    row["objective"] = float(res["objective"]["updated"])
    row["n_residuals"] = int(res["n_residuals"])
    row["solver_status"] = res["solver"]["status"]
    row["parameters"] = {p["name"]: {"value": p["updated"], "se": p["standard_error"],
                                     "group": p["group"], "unit": p["unit"]}
                         for p in res["parameters"] if not p["fixed"]}
    row["natural_frequencies_hz"] = res["modal"]["updated"]["natural_frequencies_hz"]
    row["seconds"] = time.perf_counter() - t0
    return row


def history_table(rows):
    """(names, values (N, P), standard errors (N, P)) of the rows, NaN where a record failed."""
    names = []
    for r in rows:
        for nm in r.get("parameters", {}):
            if nm not in names:
                names.append(nm)
    X = np.full((len(rows), len(names)), np.nan)
    S = np.full_like(X, np.nan)
    for i, r in enumerate(rows):
        for j, nm in enumerate(names):
            p = r.get("parameters", {}).get(nm)
            if p is not None:
                X[i, j], S[i, j] = p["value"], p["se"]
    return names, X, S


def _csv(rows, names, X, S):
    head = ["record", "time", "status", "objective"]
    for nm in names:
        head += [nm, f"se_{nm}"]
    lines = [",".join(head)]
    for i, r in enumerate(rows):
        cells = [r["record"], r.get("time") or "", r["status"].replace(",", ";"),
                 f"{r['objective']:.6g}" if "objective" in r else ""]
        for j in range(len(names)):
            cells += ["" if np.isnan(X[i, j]) else f"{X[i, j]:.6g}",
                      "" if np.isnan(S[i, j]) else f"{S[i, j]:.3g}"]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _update_task(cfg, path):
    return update_record(cfg, path)


def _config(cfg):
    return cfg


def _finished_records(done_file, resume):
    """{path: row} of the records.jsonl of an earlier run (with ``resume``); else removes it."""
    done = {}
    if resume and os.path.exists(done_file):
        with open(done_file) as fh:
            for line in fh:
                line = line.strip()
                if line:
                    row = json.loads(line)
                    done[row["path"]] = row
    elif os.path.exists(done_file):
        os.unlink(done_file)
    return done


def _update_records(cfg, todo, done, n_records, done_file, log):
    """Update every record of ``todo`` on the case's executor, appending each finished row
    to ``done`` and to records.jsonl; returns True when interrupted."""
    s = cfg.search
    interrupted = False

    def keep(p, row, fh):
        done[p] = row
        fh.write(json.dumps(row, default=jsonable) + "\n")
        fh.flush()
        bar.update(last=row["record"])
        bar.around(log)(f"  [{len(done)}/{n_records}] {row['record']}: {row['status']}"
                        + (f", objective {row['objective']:.4g}" if "objective" in row else ""))

    with open(done_file, "a") as fh, interrupts_as_keyboard(), \
            make_executor(s.executor, workers=s.workers, scheduler=s.scheduler) as ex, \
            stage("records", total=n_records, unit="record", initial=len(done)) as bar:
        stream = ex.stream(Setup(_config, cfg, value=cfg), _update_task, [(p, p) for p in todo],
                           batch_size=1)
        try:
            for p, row in stream:
                keep(p, row, fh)
        except KeyboardInterrupt:
            interrupted = True
            for p, row in stream.stop():
                keep(p, row, fh)
            log("batch interrupted: finished records are kept in records.jsonl; rerun with --resume")
        finally:
            stream.close()
    return interrupted


def _history_changes(rows, names, X, S, w, threshold):
    """{parameter: [the steps found in its history (:func:`detect_changes`)]}."""
    N = len(rows)
    changes = {}
    for j, nm in enumerate(names):
        found = detect_changes(X[:, j], S[:, j], window=w, threshold=threshold) if N >= 2 * w else []
        changes[nm] = [{"record": rows[c.index]["record"], "index": c.index,
                        "time": rows[c.index].get("time"), "before": c.before, "after": c.after,
                        "relative_change": c.relative, "z": c.z} for c in found]
    return changes


def _log_outcome(changes, failed, out, log):
    moved = {nm: c for nm, c in changes.items() if c}
    if moved:
        for nm, cs in moved.items():
            for c in cs:
                log(f"change: {nm} moved {100 * c['relative_change']:+.1f} % at record "
                    f"{c['index']} ({c['record']}{', ' + c['time'] if c['time'] else ''}), "
                    f"{abs(c['z']):.1f} times its uncertainty")
    else:
        log("no parameter moved beyond its uncertainty")
    if failed:
        log(f"warning: {len(failed)} record(s) gave no result: {', '.join(failed[:5])}"
            + (" ..." if len(failed) > 5 else ""))
    log(f"wrote {out}: history.csv, changes.json, trend.png, report.html")


def run_batch(cfg, record_paths, out, resume=False, window=None, threshold=6.0, log=print):
    """Update ``cfg``'s model from every record into folder ``out``; returns 0 or 130.

    Records run on the case's executor (``search.executor``, ``workers``,
    ``scheduler``): each record is one task, its starts run inside that task.
    """
    os.makedirs(out, exist_ok=True)
    done_file = os.path.join(out, "records.jsonl")
    done = _finished_records(done_file, resume)
    todo = [p for p in record_paths if p not in done]
    s = cfg.search
    log(f"batch {cfg.name}: {len(record_paths)} records ({len(done)} already done), "
        f"executor {s.executor}, {s.workers} worker(s)")
    t0 = time.perf_counter()
    interrupted = _update_records(cfg, todo, done, len(record_paths), done_file, log)
    rows = [done[p] for p in record_paths if p in done]
    names, X, S = history_table(rows)
    N = len(rows)
    w = window or int(np.clip(N // 8, 3, 10))
    changes = _history_changes(rows, names, X, S, w, threshold)
    failed = [r["record"] for r in rows if r["status"] != "ok"]
    summary = {"case": cfg.name, "case_file": cfg.path, "records": N,
               "records_requested": len(record_paths), "failed": failed,
               "interrupted": interrupted, "window": w, "threshold": threshold,
               "seconds": time.perf_counter() - t0, "changes": changes,
               "provenance": provenance(cfg)}
    write_atomic(os.path.join(out, "history.csv"), _csv(rows, names, X, S))
    write_json(os.path.join(out, "changes.json"), summary)
    if N:
        plot_trend(os.path.join(out, "trend.png"), rows, names, X, S, changes, cfg.name)
    write_batch_report(out, summary, rows, names, X, S)
    _log_outcome(changes, failed, out, log)
    return 130 if interrupted else 0
