"""Figures and report.html of a batch run (parameter history and its changes)."""

import datetime as dt
import html
import os

import matplotlib.dates as mdates
import numpy as np
from matplotlib.figure import Figure

from nlp.output.results import write_atomic

__all__ = ["plot_trend", "write_batch_report"]


def _x_axis(rows):
    """Record times as datetimes when every record has one, else record numbers."""
    times = [r.get("time") for r in rows]
    if all(times):
        try:
            return [dt.datetime.fromisoformat(t) for t in times], "record time"
        except ValueError:
            pass
    return np.arange(len(rows)), "record"


def plot_trend(path, rows, names, X, S, changes, title):
    """History of every mass and stiffness parameter relative to its reference level [%].

    The reference is the median before the parameter's first change (all
    records when it has none); bars are +-2 standard errors; a dashed line marks
    each detected change.
    """
    groups = [j for j, nm in enumerate(names)
              if any(r.get("parameters", {}).get(nm, {}).get("group") in ("mass", "stiffness")
                     for r in rows)] or list(range(len(names)))
    x, xlabel = _x_axis(rows)
    fig = Figure(figsize=(9, 1.9 * len(groups) + 0.8), layout="constrained")
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    for ax, j in zip(axes, groups):
        nm = names[j]
        cs = changes.get(nm, [])
        stop = cs[0]["index"] if cs else len(rows)
        ref = np.nanmedian(X[:stop, j])
        y = 100 * (X[:, j] / ref - 1)
        e = 200 * S[:, j] / ref
        ax.errorbar(x, y, yerr=e, fmt=".", ms=3, lw=0.6, color="tab:blue", ecolor="0.6")
        for c in cs:
            ax.axvline(x[c["index"]], color="tab:red", ls="--", lw=1)
            ax.text(x[c["index"]], 0.95, f" {100 * c['relative_change']:+.1f} %",
                    color="tab:red", va="top", transform=ax.get_xaxis_transform(), fontsize=8)
        ax.axhline(0, color="0.3", lw=0.6)
        ax.set_ylabel(f"{nm} [%]")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{title}: parameters relative to their reference level "
                      "(bars: +-2 standard errors; dashed: detected change)", fontsize=9)
    axes[-1].set_xlabel(xlabel)
    if xlabel == "record time":
        loc = mdates.AutoDateLocator()
        axes[-1].xaxis.set_major_locator(loc)
        axes[-1].xaxis.set_major_formatter(mdates.ConciseDateFormatter(loc))
    tmp = os.path.join(os.path.dirname(path) or ".", ".tmp-" + os.path.basename(path))
    fig.savefig(tmp, dpi=110, format="png")
    os.replace(tmp, path)
    return path


def write_batch_report(out, summary, rows, names, X, S):
    """report.html: the changes, the trend figure and the history table."""

    esc = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{esc(summary['case'])}"
             " batch</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
             "table{border-collapse:collapse;font-size:12px}td,th{border:1px solid #ccc;"
             "padding:2px 6px;text-align:right}</style></head><body>",
             f"<h1>{esc(summary['case'])}: parameter history</h1>",
             f"<p>{summary['records']} of {summary['records_requested']} records updated"
             f"{' (interrupted)' if summary['interrupted'] else ''}; case file "
             f"<code>{esc(summary['case_file'])}</code>.</p><h2>Changes</h2>"]
    moved = [(nm, c) for nm, cs in summary["changes"].items() for c in cs]
    if moved:
        parts.append("<table><tr><th>parameter</th><th>record</th><th>time</th><th>before</th>"
                     "<th>after</th><th>change</th><th>|step| / uncertainty</th></tr>")
        for nm, c in moved:
            parts.append(f"<tr><td>{esc(nm)}</td><td>{c['index']} {esc(c['record'])}</td>"
                         f"<td>{esc(c['time'] or '')}</td><td>{c['before']:.5g}</td>"
                         f"<td>{c['after']:.5g}</td><td>{100 * c['relative_change']:+.2f} %</td>"
                         f"<td>{abs(c['z']):.1f}</td></tr>")
        parts.append("</table>")
    else:
        parts.append("<p>No parameter moved beyond its uncertainty.</p>")
    parts.append(f"<p>A change is a step between the medians of the {summary['window']} records "
                 f"before and after a record larger than {summary['threshold']:g} times the "
                 "root-mean-square of that difference elsewhere in the same history (what "
                 "temperature, drift and estimation noise make it wander by), and at least that "
                 "many times what the estimates' standard errors alone allow.</p>")
    if summary["failed"]:
        parts.append(f"<p><b>Records without a result:</b> {esc(', '.join(summary['failed']))}</p>")
    if os.path.exists(os.path.join(out, "trend.png")):
        parts.append("<h2>History</h2><img src='trend.png' style='max-width:100%'>")
    units = {}
    for r in rows:
        for nm, p in r.get("parameters", {}).items():
            units.setdefault(nm, p.get("unit") or "")
    parts.append("<h2>Table</h2><p>Updated value &plusmn; standard error per record.</p><table>"
                 "<tr><th>#</th><th>record</th><th>time</th><th>status</th>"
                 + "".join(f"<th>{esc(nm)}" + (f" [{esc(units[nm])}]" if units.get(nm) not in
                                                ("", "-") else "") + "</th>" for nm in names)
                 + "</tr>")
    for i, r in enumerate(rows):
        cells = "".join("<td></td>" if np.isnan(X[i, j]) else
                        f"<td>{X[i, j]:.5g} &plusmn; {S[i, j]:.2g}</td>" for j in range(len(names)))
        parts.append(f"<tr><td>{i}</td><td>{esc(r['record'])}</td><td>{esc(r.get('time') or '')}"
                     f"</td><td>{esc(r['status'])}</td>{cells}</tr>")
    parts.append("</table>")
    p = summary.get("provenance")
    if p:
        parts.append(f"<p style='color:#555;font-size:12px'>frf-nlp {esc(str(p.get('version')))}"
                     f", {esc(str(p.get('date_utc')))}, <code>{esc(str(p.get('command_line')))}"
                     "</code></p>")
    parts.append("</body></html>")
    path = os.path.join(out, "report.html")
    write_atomic(path, "\n".join(parts) + "\n")
    return path
