"""report.html: every table and figure of a run, rebuilt from the result files.

``frf-nlp report DIR`` calls :func:`write_report` on a finished run folder; it
reads only summary.json, result.json files and the PNG figures beside them.
"""

import glob
import html
import json
import os

from .errors import InputError
from .results import write_atomic

__all__ = ["write_report"]

_CSS = """body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}
table{border-collapse:collapse;margin:0.6em 0}td,th{border:1px solid #bbb;padding:3px 8px;
text-align:right}th{background:#eee}td:first-child,th:first-child{text-align:left}
img{max-width:100%;border:1px solid #ddd;margin:4px 0}h2{border-bottom:1px solid #ccc}"""


def _table(header, rows):
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _fmt(x):
    if isinstance(x, float):
        return f"{x:.6g}"
    return "" if x is None else str(x)


def _load(path):
    with open(path) as fh:
        return json.load(fh)


def _update_section(out, d, label):
    res = _load(os.path.join(d, "result.json"))
    rel = os.path.relpath(d, out)
    parts = [f"<h2>Update{': ' + html.escape(label) if label else ''}</h2>",
             f"<p>Residual <b>{res['residual']}</b>, {res['n_residuals']} residuals; solver "
             f"{res['solver']['name']} ({res['solver']['status']}, {res['solver']['iterations']} "
             f"iterations); objective {res['objective']['initial']:.4g} &rarr; "
             f"{res['objective']['updated']:.4g}; {res['search']['starts_finished']} starts, "
             f"{res['search']['starts_within_1pct_of_best']} within 1 % of the best.</p>"]
    rows = [[p["name"], p["unit"], p["initial"], p["updated"],
             p["standard_error"] if p["standard_error"] is not None
             else f"n/a (at {p.get('at_bound')} bound)", p["lower"], p["upper"],
             "fixed" if p["fixed"] else (p["tie"] or "")] for p in res["parameters"]]
    parts.append(_table(["parameter", "unit", "initial", "updated", "std. error", "lower", "upper",
                         ""], rows))
    m0, m1 = res["modal"]["initial"], res["modal"]["updated"]
    parts.append(_table(["mode", "f initial [Hz]", "f updated [Hz]", "zeta initial", "zeta updated"],
                        [[i + 1, a, b, c, e] for i, (a, b, c, e) in enumerate(zip(
                            m0["natural_frequencies_hz"], m1["natural_frequencies_hz"],
                            m0["damping_ratios"], m1["damping_ratios"]))]))
    parts.append(_table(["channel", "FDAC initial", "FDAC updated"],
                        [[k, res["fdac"]["initial"][k], v] for k, v in res["fdac"]["updated"].items()]))
    weak = res["identifiability"]["weak_directions"]
    parts.append(f"<p>Identifiability: scale {html.escape(res['identifiability']['scale'])}; "
                 f"condition number of the scaled Jacobian {res['identifiability']['condition_number']:.3g}; "
                 + (f"weak combinations: {html.escape(str([w['combination'] for w in weak]))}"
                    if weak else "no weak parameter combination") + ".</p>")
    for png in sorted(glob.glob(os.path.join(d, "*.png"))):
        parts.append(f'<img src="{html.escape(os.path.join(rel, os.path.basename(png)))}">')
    return "\n".join(parts)


def _flags_section(out, s):
    """Warnings first: what must not be read as a clean result (see nlp.flags)."""
    flags = list(s.get("flags", ()))
    if "flags" not in s:  # older summary.json: collect them from the result files
        for label in s.get("updates") or [None]:
            p = os.path.join(out if label is None else os.path.join(out, label), "result.json")
            if os.path.isfile(p):
                flags += [dict(f, update=label) for f in _load(p).get("flags", ())]
    if not flags:
        return "<h2>Flags</h2><p>None: no parameter on a bound, the best start converged" \
               + (", no replay anti-correlated" if "time_domain" in s else "") + ".</p>"
    items = "".join(f"<li><b>{html.escape(f['kind'])}</b>"
                    + (f" [{html.escape(str(f['update']))}]" if f.get("update") else "")
                    + f": {html.escape(f['message'])}.<br>What it means / what to do: "
                    f"{html.escape(f['advice'])}.</li>" for f in flags)
    return f"<h2>Flags ({len(flags)})</h2><ul>{items}</ul>"


def _provenance_section(prov):
    if not prov:
        return ""
    git = prov.get("git") or {}
    rows = [["package", f"{prov.get('package', 'frf-nlp')} {prov.get('version', '')}"],
            ["git commit", (git.get("commit", "") + (" (uncommitted changes)" if git.get("dirty")
                                                     else "")) if git else "not a checkout"],
            ["date (UTC)", prov.get("date_utc")], ["command line", prov.get("command_line")]]
    rows += [[f"sha256 {os.path.basename(f)}", v["sha256"]]
             for f, v in prov.get("files", {}).items()]
    return "<h2>Provenance</h2>" + _table(["", ""], rows)


def write_report(out):
    """Write ``out/report.html`` from the files of a finished run; returns its path."""
    spath = os.path.join(out, "summary.json")
    if not os.path.isfile(spath):
        raise InputError(out, "summary.json", "a run folder written by 'frf-nlp run'")
    s = _load(spath)
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(s['case'])}"
             f"</title><style>{_CSS}</style></head><body>",
             f"<h1>frf-nlp report: {html.escape(s['case'])}</h1>"]
    if s.get("interrupted"):
        parts.append("<p><b>The run was interrupted; results are from the starts that finished."
                     "</b></p>")
    parts.append(_flags_section(out, s))
    table1 = os.path.join(out, "table1.csv")
    if os.path.isfile(table1):
        with open(table1) as fh:
            rows = [ln.split(",") for ln in fh.read().strip().splitlines()]
        parts += ["<h2>Table 1: updated masses and stiffnesses</h2>", _table(rows[0], rows[1:])]
    parts.append("<h2>Final model</h2>")
    parts.append(_table(["mode", "f [Hz]", "zeta"], [[i + 1, f, z] for i, (f, z) in enumerate(
        zip(s["model"]["natural_frequencies_hz"], s["model"]["damping_ratios"]))]))
    parts.append(_table(["channel", "FDAC", "FRAC"], [[k, v, s.get("frac", {}).get(k)]
                                                     for k, v in s["fdac"].items()]))
    for label, rows in s.get("modes", {}).items():
        parts.append(f"<h3>Measured modes ({html.escape(label)}, peak picking) against the model</h3>")
        parts.append(_table(["f measured [Hz]", "f model [Hz]", "error", "zeta measured",
                             "zeta model", "MAC"],
                            [[r["f_measured_hz"], r["f_model_hz"], r["frequency_error"],
                              r["zeta_measured"], r["zeta_model"], r["mac"]] for r in rows]))
    if "validation" in s:
        v = s["validation"]
        parts.append(f"<h2>Held-out test: {html.escape(os.path.basename(v['file']))}</h2>")
        parts.append(_table(["channel", "FDAC"], [[k, x] for k, x in v["fdac"].items()]))
        for png in sorted(glob.glob(os.path.join(out, "validation", "*.png"))):
            parts.append(f'<img src="validation/{html.escape(os.path.basename(png))}">')
    if "time_domain" in s:
        parts.append("<h2>Time-domain verification (measured input replayed)</h2>")
        parts.append(_table(["channel", "quantity", "NRMSE", "correlation", "peak error"],
                            [[k, v["quantity"], v["nrmse"], v["correlation"], v["peak_error"]]
                             for k, v in s["time_domain"].items()]))
        for png in sorted(glob.glob(os.path.join(out, "time_*.png"))):
            parts.append(f'<img src="{html.escape(os.path.basename(png))}">')
    labels = s.get("updates") or [None]
    for label in labels:
        d = out if label is None else os.path.join(out, label)
        if os.path.isfile(os.path.join(d, "result.json")):
            parts.append(_update_section(out, d, label))
    parts.append(_provenance_section(s.get("provenance")))
    parts.append("</body></html>")
    path = os.path.join(out, "report.html")
    write_atomic(path, "\n".join(parts))
    return path
