"""report.html: every table and figure of a run or a diagnosis, rebuilt from its files.

``frf-nlp report DIR`` calls :func:`write_report` on a finished folder: a run
(summary.json, result.json files and the PNG figures beside them) or a
diagnosis (diagnosis.json, residual_map.png, frf_diagnosis_*.png). Numbers are
shown as the console shows them: relative quantities in percent, values to 6
significant figures, round-off (below 1e-12 of the largest entry) as 0; a
diagnosis' findings in physical units with relative errors, as its printed
conclusion gives them (nlp.diagnosis.plain). The page is rebuilt identically
from the same files.
"""

import datetime
import glob
import html
import json
import os

from nlp import __version__
from nlp.diagnosis.plain import (REFERENCES, alone_rows, beyond_fit, finding_note, finding_title,
                                 finding_values,
                                 hypotheses, other_statements, paragraph, unconfirmed_lines)
from nlp.errors import InputError
from nlp.output.results import write_atomic

__all__ = ["write_report", "fmt_value", "fmt_percent"]

_CSS = """body{font-family:sans-serif;max-width:1150px;margin:2em auto;color:#222;line-height:1.35}
table{border-collapse:collapse;margin:0.6em 0}td,th{border:1px solid #bbb;padding:3px 8px;
text-align:right}th{background:#eee}td:first-child,th:first-child{text-align:left}
img{max-width:100%;border:1px solid #ddd;margin:4px 0}h2{border-bottom:1px solid #ccc}
.note{color:#555;font-size:90%}.text td{text-align:left}.prov td{text-align:left}.verdict{font-size:120%}"""


def fmt_value(x, sig=6, scale=None):
    """A number to ``sig`` significant figures; |x| below 1e-12 x ``scale`` (round-off) is 0."""
    if x is None:
        return "n/a"
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return str(x)
    if x != x:  # NaN
        return "n/a"
    if scale is not None and abs(x) <= 1e-12 * abs(scale):
        return "0"
    return f"{x:.{sig}g}"


def fmt_percent(x, digits=2, signed=True):
    """A fraction as percent with ``digits`` decimals (console style: -0.57 %)."""
    if x is None or x != x:
        return "n/a"
    return f"{100 * x:{'+' if signed else ''}.{digits}f} %"


def _cell(c):
    return c if isinstance(c, str) else fmt_value(c)


def _table(header, rows, cls=None):
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    h = f"<tr>{h}</tr>" if any(str(c) for c in header) else ""
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_cell(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table{f' class={cls!r}' if cls else ''}>{h}{body}</table>"


def _load(path):
    with open(path) as fh:
        return json.load(fh)


def _head(title):
    return [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
            f"</title><style>{_CSS}</style></head><body>", f"<h1>{html.escape(title)}</h1>"]


def _provenance(d, stamp_file, case_file=None):
    """Version, date, case: the 'provenance' entry when the writer recorded one; otherwise
    the package version, the file's modification time (UTC) and the case path."""
    prov = d.get("provenance")
    if isinstance(prov, dict) and prov:
        rows = [[k.replace("_", " "), _prov_value(k, v)] for k, v in prov.items()]
        if case_file and not any("case" in k for k in prov):
            rows.append(["case file", case_file])
    else:
        when = datetime.datetime.fromtimestamp(os.path.getmtime(stamp_file),
                                               datetime.timezone.utc)
        rows = [["frf-nlp version", __version__],
                ["written (UTC)", when.strftime("%Y-%m-%d %H:%M:%S")],
                ["case file", case_file or d.get("case_file") or "n/a"]]
    return "<h2>Provenance</h2>" + _table(["", ""], rows, cls="prov")


def _prov_value(key, v):
    """One provenance entry in words: files as 'path (sha256 first 12, bytes)'."""
    if key == "files" and isinstance(v, dict):
        return "; ".join(f"{p} (sha256 {str(i.get('sha256', ''))[:12]}, {i.get('bytes')} bytes)"
                         if isinstance(i, dict) else f"{p}: {i}" for p, i in v.items())
    if isinstance(v, dict):
        return ", ".join(f"{k}: {x}" for k, x in v.items())
    if isinstance(v, list):
        return " ".join(map(str, v))
    return str(v)


def _flags(d):
    flags = d.get("flags") or []
    if not flags:
        return ""
    return "<h2>Flags</h2><ul>" + "".join(
        f"<li><b>{html.escape(str(f.get('subject', '')))}</b>"
        + (f" ({html.escape(str(f['kind']))})" if f.get("kind") else "")
        + f": {html.escape(str(f.get('message', '')))}"
        + (f". What it means / what to do: {html.escape(str(f['advice']))}" if f.get("advice")
           else "") + "</li>"
        for f in flags) + "</ul>"


def _imgs(out, d, pattern):
    rel = os.path.relpath(d, out)
    return [f'<img src="{html.escape(os.path.normpath(os.path.join(rel, os.path.basename(p))))}">'
            for p in sorted(glob.glob(os.path.join(d, pattern)))]


def _matrix(title, A, unit):
    if A is None:  # a large model: its matrices are in an NPZ file, not in the JSON
        return ""
    n = len(A)
    scale = max((abs(v) for row in A for v in row), default=1.0)
    rows = [[f"row {i + 1}"] + [fmt_value(v, 6, scale) for v in A[i]] for i in range(n)]
    return f"<h3>{html.escape(title)} [{unit}]</h3>" + _table([""] + [f"col {j + 1}"
                                                                      for j in range(n)], rows)


def _modal_table(m0, m1):
    return _table(["mode", "f initial [Hz]", "f updated [Hz]", "change", "damping ratio initial",
                   "damping ratio updated"],
                  [[i + 1, a, b, fmt_percent(b / a - 1), fmt_percent(c, 3, False),
                    fmt_percent(e, 3, False)] for i, (a, b, c, e) in enumerate(zip(
                      m0["natural_frequencies_hz"], m1["natural_frequencies_hz"],
                      m0["damping_ratios"], m1["damping_ratios"]))])


def _update_section(out, d, label):
    res = _load(os.path.join(d, "result.json"))
    obj = res["objective"]
    parts = [f"<h2>Update{': ' + html.escape(label) if label else ''}</h2>",
             f"<p>Residual <b>{html.escape(res['residual'].replace('_', ' '))}</b>, "
             f"{res['n_residuals']} residuals; solver {html.escape(res['solver']['name'])} "
             f"({html.escape(str(res['solver']['status']))}, {res['solver']['iterations']} "
             f"iterations); objective {fmt_value(obj['initial'], 4)} &rarr; "
             f"{fmt_value(obj['updated'], 4)}; {res['search']['starts_finished']} starts, "
             f"{res['search']['starts_within_1pct_of_best']} within 1 % of the best.</p>"]
    phys = [p for p in res["parameters"] if p["group"] != "damping"]
    parts.append(_table(
        ["parameter", "unit", "initial", "updated", "change", "std. error", "lower", "upper", ""],
        [[p["name"], p["unit"], p["initial"], p["updated"],
          fmt_percent(p["relative_change"]) if p.get("relative_change") is not None else "",
          "at bound" if p.get("at_bound") and p["standard_error"] is None else p["standard_error"],
          p["lower"], p["upper"],
          "fixed" if p["fixed"] else (p["tie"] or "")] for p in phys]))
    mats = res["matrices"]
    parts.append("<h3>Damping</h3><p>The physical damping matrix C [N s/m] of the updated "
                 "model and the modal damping ratios of both models (complex eigenproblem, "
                 "Eqn 5).</p>")
    if "file" in mats:
        parts.append(f"<p class='note'>M, K, C ({mats['n']} DOFs) are in "
                     f"{html.escape(mats['file'])} (sparse).</p>")
    parts.append(_matrix("C updated", mats.get("updated", {}).get("C"), "N s/m"))
    parts.append(_matrix("C initial", mats.get("initial", {}).get("C"), "N s/m"))
    parts.append(_modal_table(res["modal"]["initial"], res["modal"]["updated"]))
    damp = [p for p in res["parameters"] if p["group"] == "damping"]
    if damp:
        parts.append("<p class='note'>Damping parameters as the solver sees them (for general "
                     "damping, entries of the Cholesky factor L of C = L L<sup>T</sup>, Eqn 25f, "
                     "in sqrt(N s/m)):</p>")
        scale = max(abs(p["updated"]) for p in damp) or 1.0
        parts.append(_table(["parameter", "initial", "updated", "std. error", ""],
                            [[p["name"], fmt_value(p["initial"], 6, scale),
                              fmt_value(p["updated"], 6, scale),
                              fmt_value(p["standard_error"], 6, scale),
                              "fixed" if p["fixed"] else ""] for p in damp]))
    parts.append(_table(["channel", "FDAC initial", "FDAC updated"],
                        [[k, res["fdac"]["initial"][k], v]
                         for k, v in res["fdac"]["updated"].items()]))
    ident = res["identifiability"]
    weak = ident["weak_directions"]
    parts.append(f"<p>Identifiability: scale {html.escape(ident['scale'])}; condition number "
                 f"of the scaled Jacobian {fmt_value(ident['condition_number'], 3)}; "
                 + (f"weak combinations: {html.escape(str([w['combination'] for w in weak]))}"
                    if weak else "no weak parameter combination") + ".</p>")
    parts += _imgs(out, d, "*.png")
    return "\n".join(parts)


def _channels_section(s):
    chans = s.get("channels")
    if not chans:
        return ""
    rows = [[c["name"], c["quantity"], c["unit"], c.get("dof", "")] for c in chans]
    return ("<h2>Channels</h2><p>Magnitudes in dB are 20 log10 |H| re 1 SI unit of each FRF "
            "(the unit column); the FRF sign convention is Y = H X with the e<sup>-jwt</sup> "
            "transform.</p>" + _table(["channel", "FRF quantity", "unit", "response DOF"], rows))


def _quality_section(q):
    rows = [[ch.replace("__input__", "input"), c["spikes"], c["dropouts"],
             fmt_percent(c["fraction_flagged"], 3, False)] for ch, c in q["channels"].items()]
    what = ("replaced by a cubic spline through the good samples" if q["removed"] else
            "left in the data (data.screen.remove: true replaces them)")
    return ("<h2>Record quality</h2>"
            + (f"<p>Spikes and dropouts found, {what}.</p>" + _table(
                ["channel", "spikes", "dropouts", "samples flagged"], rows) if rows else
               "<p>No spikes or dropouts found in the records.</p>"))


def _run_report(out):
    spath = os.path.join(out, "summary.json")
    s = _load(spath)
    parts = _head(f"frf-nlp report: {s['case']}")
    if s.get("interrupted"):
        parts.append("<p><b>The run was interrupted; results are from the starts that finished."
                     "</b></p>")
    labels = s.get("updates") or [None]
    first = next((os.path.join(out, lb) if lb else out for lb in labels
                  if os.path.isfile(os.path.join(out, lb or "", "result.json"))), None)
    case_file = _load(os.path.join(first, "result.json")).get("case_file") if first else None
    parts.append(_provenance(s, spath, case_file))
    parts.append(_flags(s))
    parts.append(_channels_section(s))
    table1 = os.path.join(out, "table1.csv")
    if os.path.isfile(table1):
        with open(table1) as fh:
            rows = [ln.split(",") for ln in fh.read().strip().splitlines()]
        parts += ["<h2>Table 1: updated masses and stiffnesses</h2>", _table(rows[0], rows[1:])]
    parts.append("<h2>Final model</h2>")
    parts.append(_table(["mode", "f [Hz]", "damping ratio"],
                        [[i + 1, f, fmt_percent(z, 3, False)] for i, (f, z) in enumerate(
                            zip(s["model"]["natural_frequencies_hz"],
                                s["model"]["damping_ratios"]))]))
    parts.append(_matrix("C of the final model", s["model"].get("C"), "N s/m"))
    needs = s.get("needs_phase")
    parts.append(_table(["channel", "FDAC", "FRAC"],
                        [[k, v, "needs phase" if needs else s.get("frac", {}).get(k)]
                         for k, v in s["fdac"].items()]))
    if needs:
        parts.append(f"<p class='note'>{html.escape(needs['reason'])}: "
                     f"{', '.join(needs['metrics'])} need phase and are not computed.</p>")
    for label, rows in s.get("modes", {}).items():
        parts.append(f"<h3>Measured modes ({html.escape(label)}, peak picking) against the "
                     "model</h3>")
        parts.append(_table(["f measured [Hz]", "f model [Hz]", "frequency error",
                             "damping ratio measured", "damping ratio model", "MAC"],
                            [[r["f_measured_hz"], r["f_model_hz"], fmt_percent(r["frequency_error"]),
                              fmt_percent(r["zeta_measured"], 3, False),
                              fmt_percent(r["zeta_model"], 3, False),
                              "needs phase" if r["mac"] is None else fmt_value(r["mac"], 4)]
                             for r in rows]))
    if "data_quality" in s:
        parts.append(_quality_section(s["data_quality"]))
    if "validation" in s:
        v = s["validation"]
        parts.append(f"<h2>Held-out test: {html.escape(os.path.basename(v['file']))}</h2>")
        parts.append(_table(["channel", "FDAC"], [[k, x] for k, x in v["fdac"].items()]))
        parts += _imgs(out, os.path.join(out, "validation"), "*.png")
    if "time_domain" in s:
        parts.append("<h2>Time-domain verification (measured input replayed)</h2>")
        parts.append(_table(["channel", "quantity", "NRMSE", "correlation", "peak error"],
                            [[k, v["quantity"], fmt_percent(v["nrmse"], 1, False),
                              fmt_value(v["correlation"], 4), fmt_percent(v["peak_error"], 1)]
                             for k, v in s["time_domain"].items()]))
        parts += _imgs(out, out, "time_*.png")
    for label in labels:
        d = out if label is None else os.path.join(out, label)
        if os.path.isfile(os.path.join(d, "result.json")):
            parts.append(_update_section(out, d, label))
    parts.append("</body></html>")
    return parts


def _finding_rows(items, refs):
    """One row per finding: what and where, its parameters in units, its evidence."""
    rows = []
    for f in items:
        ev = f.get("evidence") or {}
        rows.append([finding_title(f), "; ".join(finding_values(f, refs)),
                     fmt_value(ev.get("delta_bic"), 4), fmt_value(ev.get("held_out_chi2"), 4)])
    return rows


def _items(title, lines, note=""):
    if not lines:
        return []
    return [f"<h2>{html.escape(title)}</h2>"] + ([f"<p class='note'>{html.escape(note)}</p>"]
                                                 if note else []) + [
        "<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in lines) + "</ul>"]


def _fit_section(fit, noise):
    if not fit:
        return []
    keys = ["objective", "reduced_chi2", "held_out_chi2"]
    parts = ["<h2>Fit before and after</h2>",
             _table(["", "objective", "reduced chi-square", "held-out chi-square"],
                    [[k, *[(fit.get(k) or {}).get(x) for x in keys]]
                     for k in ("before", "after") if k in fit])]
    b = fit.get("before") or {}
    if b.get("reduced_chi2_sd"):
        parts.append(f"<p>With a right noise model the baseline's reduced chi-square would be "
                     f"1 +- {b['reduced_chi2_sd']:.2f} (one standard deviation) on these "
                     f"points: their errors are shared between channels and neighbouring "
                     f"bins, {b['effective_points']:.0f} effective independent points.</p>")
    if (noise or {}).get("statement"):
        parts.append(f"<p class='note'>{html.escape(noise['statement'])}</p>")
    return parts


def _calibration_section(cal):
    """Every channel's fitted gain inside the case's calibration tolerance (a nuisance of
    every fit, nlp.diagnosis.calibration); a released one is a finding above."""
    if not cal:
        return []
    lo, hi = cal["bounds"]
    rows = [[ch, fmt_percent(g), "named above (beyond the tolerance)" if ch in cal["released"]
             else ("on the tolerance's bound" if min(abs(g - lo), abs(g - hi)) < 1e-3 * hi
                   else "inside the tolerance")] for ch, g in cal["gains"].items()]
    ref = (f" The gains are relative to {cal['reference']}'s, which is held at 0: on a force "
           "test a gain common to every channel is a scale of the whole structure."
           if cal.get("reference") else "")
    return ["<h2>Calibration</h2>",
            f"<p>Every channel's gain was fitted inside the transducers' stated calibration "
            f"tolerance of +-{100 * cal['tolerance']:.3g} % (a gain relative to the input "
            f"between {fmt_percent(lo)} and {fmt_percent(hi)}); only a gain the data put "
            f"beyond it is a finding.{ref}</p>",
            _table(["channel", "fitted gain", ""], rows, "text")]


def _sweep_section(sw):
    """The joints' distortion of a one-segment record, divided out before the diagnosis
    (nlp.diagnosis.sweep)."""
    if not sw:
        return []
    se = sw.get("k3_se") or [float("nan")] * len(sw["k3"])
    rows = [[f"story {s}", fmt_percent(c), f"{k:.3g} +- {e:.2g}"]
            for s, c, k, e in zip(sw["stories"], sw["change"], sw["k3"], se)]
    before, after = sw.get("reduced_chi2") or (float("nan"), float("nan"))
    when = ("after the findings were in the model (the baseline's misfit was more than the "
            "bend): the final model's" if sw.get("after_findings") else
            "before the diagnosis: the baseline's")
    return ["<h2>Joints (one-segment record)</h2>",
            "<p>A sweep passes each resonance with a response many times its average, and a "
            "frame's slightly nonlinear joints bend the peaks of its one-segment FRF, which no "
            "linear model can have. Cubic story springs fitted to that bend are within the "
            "joints' band of every real frame, so their distortion (ln|H| changed by up to "
            f"{sw['largest_ln_change']:.2g}) was divided out of the data {when} reduced "
            f"chi-square went from {before:.3g} to {after:.3g}. The changes are each story's "
            "equivalent stiffness change between this test's level and three times it.</p>",
            *([] if sw.get("confirmed", True) else [
                "<p>With the findings in the model the bend is no longer proven (estimated "
                "again from the data as measured): the correction made before them may hold "
                "part of what they explain, and the joints above are not a finding.</p>"]),
            _table(["story", "change, level to 3x", "k3 [N/m^3] +- SE"], rows, "text")]


def _discrepancy_row(x):
    """One model-discrepancy resonance: fitted (with errors) or beyond the fitted band."""
    seen = ", ".join(x["channels"]) or "no channel clearly"
    if x.get("fitted") is False:
        lo, hi = x["band_hz"]
        side = "above" if x["frequency_hz"] > hi else "below"
        return [f"{x['frequency_hz']:.2f} ({side} the fitted {lo:.1f}-{hi:.1f} Hz: not fitted)",
                "-", seen]
    return [f"{x['frequency_hz']:.2f} ± {x['frequency_se_hz']:.2g}",
            f"{100 * x['damping_ratio']:.2g} ± {100 * x['damping_ratio_se']:.2g}", seen]


def _discrepancy_section(d):
    """Model discrepancy (resonances outside the model class) and where the rest of a partly
    explained mismatch sits, as tables."""
    parts = []
    disc = d.get("model_discrepancy") or []
    if disc:
        parts += ["<h2>Model discrepancy: resonances the model class cannot have</h2>",
                  "<p>Those inside the fitted band are kept in every fit as a modal term, so "
                  "no finding is accepted for absorbing them; those beyond it are seen in the "
                  "data and not fitted. None is a finding.</p>",
                  _table(["frequency [Hz]", "damping ratio [%]", "seen by"],
                         [_discrepancy_row(x) for x in disc], "text")]
    left = d.get("mismatch_left") or {}
    cells = (left.get("cells") or [])[:8]
    if cells:
        span = left.get("fitted_band_hz")
        parts += ["<h2>Where the rest of the mismatch sits</h2>",
                  _table(["channel", "band [Hz]", "mean squared misfit / noise"],
                         [[c["channel"], f"{c['band_hz'][0]:.1f}-{c['band_hz'][1]:.1f}"
                           + (" (beyond the fitted band)" if beyond_fit(c, span) else ""),
                           f"{c['chi2']:.3g}"] for c in cells], "text")]
    return parts


def _diagnosis_report(out):
    """Verdict and findings first (in physical units, nlp.diagnosis.plain), the paragraph in
    plain words, what else was seen, the evidence and figures; provenance last."""
    dpath = os.path.join(out, "diagnosis.json")
    d = _load(dpath)
    rpath = os.path.join(out, REFERENCES)
    refs = _load(rpath) if os.path.isfile(rpath) else None
    folder = os.path.basename(os.path.normpath(out)).removesuffix(".staging")
    parts = _head(f"frf-nlp diagnosis: {d.get('case', folder)}")
    parts.append(f"<p class='verdict'>Verdict: <b>{html.escape(d['verdict'].replace('_', ' '))}"
                 "</b></p>")
    hdr = ["what and where", "parameters (± standard error)", "BIC change",
           "held-out chi-square"]
    if d.get("findings"):
        parts += ["<h2>Findings</h2>", _table(hdr, _finding_rows(d["findings"], refs), "text")]
        parts += [f"<p>{html.escape(n)}</p>" for n in map(finding_note, d["findings"]) if n]
    parts += ["<h2>In plain words</h2>", f"<p>{html.escape(paragraph(d, refs))}</p>"]
    parts += _discrepancy_section(d)
    if d.get("tests_alone"):
        parts += ["<h2>Each test alone, with the joint findings</h2>",
                  _table(["test", "finding", "fitted on this test alone", "joint fit",
                          "this test"], alone_rows(d, refs), "text")]
    parts += _items("Also seen", other_statements(d))
    parts += _items("Not confirmed by the other tests", unconfirmed_lines(d, refs))
    parts += _items("What the updated parameters may have absorbed (hypotheses)", hypotheses(d),
                    "Effects the case's own parameters can take up, listed only where the "
                    "fitted parameters point at them. They are not findings.")
    if d.get("alternatives"):
        parts += ["<h2>Alternatives (fit worse, or tie)</h2>",
                  _table(hdr, _finding_rows(d["alternatives"], refs), "text")]
    parts += _items("Suggested measurements", d.get("suggested_measurements") or [])
    parts += _fit_section(d.get("fit") or {}, d.get("noise"))
    parts += _calibration_section(d.get("calibration"))
    parts += _sweep_section(d.get("sweep_joints"))
    parts.append("<h2>Residual map</h2><p>Mean squared residual / noise in each channel and "
                 "band, fitted points and held-out shoulders, before and after the added "
                 "physics; 1 (log10: 0) is the noise level, white cells have no held-out "
                 "point near their band.</p>")
    parts += _imgs(out, out, "residual_map.png")
    parts.append("<h2>FRFs: measured, baseline and with the added physics</h2>")
    parts += _imgs(out, out, "frf_diagnosis_*.png")
    parts.append(_provenance(d, dpath))
    parts.append("</body></html>")
    return parts


def write_report(out):
    """Write ``out/report.html`` from the files of a finished run or diagnosis; returns its path."""
    if os.path.isfile(os.path.join(out, "summary.json")):
        parts = _run_report(out)
    elif os.path.isfile(os.path.join(out, "diagnosis.json")):
        parts = _diagnosis_report(out)
    else:
        raise InputError(out, "summary.json", "a run folder written by 'frf-nlp run' (or "
                         "diagnosis.json: a folder written by 'frf-nlp diagnose')")
    path = os.path.join(out, "report.html")
    write_atomic(path, "\n".join(p for p in parts if p))
    return path
