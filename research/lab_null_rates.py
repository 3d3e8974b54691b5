"""Decision statistics of `diagnose` on the lab generator's development nulls (issue 48, item 3).

A null of ``scripts/make_lab_benchmark.py`` (cases 0-7 of a seed) is a shear frame with the
lab's imperfections (calibration spread, per-channel conditioning chains, coloured and common-mode
noise, table interaction, slightly nonlinear joints) and no concealed effect. Each decision
constant of the diagnosis thresholds a statistic; on these nulls that statistic's values are
the null distribution the constant must sit above. Printed per constant: the statistic, its
values over the nulls (median and largest), and how many nulls cross the constant, with a
Wilson 95 % interval; then the structural findings (false alarms by the benchmark's rule).

    python research/lab_null_rates.py --out DIR --run --seeds 4 5 [--only 0-7] [--timeout 2400]
    python research/lab_null_rates.py --out DIR          # the table of what DIR holds

--run generates each null into DIR/seed_S (only the missing ones) and diagnoses it with its log
kept (CASE/diagnose.log); cases already diagnosed are kept. Development seeds only (0-99): exam
seeds are never diagnosed outside their scoring.
"""

import argparse
import glob
import json
import os
import re
import subprocess
import sys

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "scripts"))

from nlp.diagnosis import decide, driver, evidence, loss, phase, priors  # noqa: E402
import score_lab  # noqa: E402

SETUP = ("sensor_gain", "sensor_delay")
CANDIDATE = re.compile(r"\s+\[(\d+)\] (\w+) (\{.*?\}|\{\}): score [-\d.e+]+, dBIC ([-\d.e+]+) "
                       r"\(phi [-\d.e+]+\), held-out ([-\d.e+na]+)")


def wilson(k, n, z=1.96):
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(c - h, 0.0), min(c + h, 1.0)


def run(out, seeds, only, timeout):
    for s in seeds:
        if not 0 <= s <= 99:
            raise SystemExit(f"seed {s}: development seeds are 0-99")
        d = os.path.join(out, f"seed_{s}")
        for k in only:
            if not glob.glob(os.path.join(d, f"{k:02d}_*", "truth.json")):
                subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "make_lab_benchmark.py"),
                                "--out", d, "--seed", str(s), "--only", str(k)], check=True,
                               stdout=subprocess.DEVNULL)
            case = glob.glob(os.path.join(d, f"{k:02d}_*"))[0]
            if os.path.isfile(os.path.join(case, "diagnosis", "diagnosis.json")):
                continue
            print(f"diagnose seed {s} case {k:02d}", flush=True)
            with open(os.path.join(case, "diagnose.log"), "w") as log:
                try:
                    subprocess.run([sys.executable, "-m", "nlp", "diagnose",
                                    os.path.join(case, "case.yaml"), "--out",
                                    os.path.join(case, "diagnosis")], stdout=log,
                                   stderr=subprocess.STDOUT, timeout=timeout, cwd=ROOT)
                except subprocess.TimeoutExpired:
                    log.write(f"timed out after {timeout} s\n")


def candidates(log_path):
    """(family, dBIC, held-out) of every candidate refit in the log."""
    out = []
    if os.path.isfile(log_path):
        for line in open(log_path):
            m = CANDIDATE.match(line)
            if m:
                out.append((m.group(2), float(m.group(4)), float(m.group(5))))
    return out


def statistics(case):
    """The null statistics of one diagnosed case (None when it has no result)."""
    path = os.path.join(case, "diagnosis", "diagnosis.json")
    if not os.path.isfile(path):
        return None
    d = json.load(open(path))
    fb = d["fit"]["before"]
    nu_sd = fb.get("reduced_chi2_sd") or float("nan")
    st = {"case": os.path.relpath(case, os.path.dirname(os.path.dirname(case))),
          "chi2_sds": (fb["reduced_chi2"] - decide.ADEQUATE_CHI2) / nu_sd,
          "chi2": fb["reduced_chi2"], "held": fb["held_out_chi2"]}
    rows = d.get("phase_check") or []
    # a channel's own delay against the others' median, as phase at the top of the band
    st["phase_own"] = max((abs(r["delay_ms"] - float(np.median([o["delay_ms"] for o in rows
                                                                  if o is not r]))) * 1e-3
                           * r["omega_max"] for r in rows if len(rows) > 1), default=0.0)
    st["delay_z"] = max((abs(r["delay_ms"]) / r["standard_error_ms"] for r in rows
                         if r.get("explained", 0) >= phase.EXPLAINED), default=0.0)
    lc = (d.get("loss_check") or {}).get("rows") or []
    st["loss_z"] = max((r["eta"] / r["standard_error"] for r in lc
                        if r.get("explained", 0) >= loss.EXPLAINED and r["standard_error"] > 0),
                       default=0.0)
    st["loss_explained"] = max((r.get("explained", 0.0) for r in lc if r["standard_error"] > 0
                                and r["eta"] > loss.LOSS_Z * r["standard_error"]), default=0.0)
    st["level_misfit"] = max(fb["reduced_chi2"], fb["held_out_chi2"])
    st["extra_modes"] = len(d.get("extra_modes") or [])
    st["hot_spots"] = len((d.get("whole_band") or {}).get("hot_spots_hz") or [])
    dd = d.get("damping_decomposition") or {}
    z, ex, se = (dd.get(k) or [] for k in ("story_zeta_ratio_lower", "excess", "excess_se"))
    st["story_zeta"] = max(z, default=0.0)
    st["unexplained"] = dd.get("unexplained_fraction") or 0.0
    st["damper_z"] = max((e / s for e, s in zip(ex, se) if s and s > 0), default=0.0)
    cands = candidates(os.path.join(case, "diagnose.log"))
    structural = [c for c in cands if c[0] not in SETUP]
    st["best_dbic"] = min((c[1] for c in structural), default=0.0)
    # the held-out gate of the structural candidates that pass on BIC: their held-out
    # chi-square over the baseline's (first round's), the least of them
    st["held_ratio"] = min((c[2] / fb["held_out_chi2"] for c in structural
                            if c[1] <= -evidence.BIC_ACCEPT and fb["held_out_chi2"] > 0),
                           default=float("nan"))
    st["best_appendage_dbic"] = min((c[1] for c in cands if c[0] == "secondary_oscillator"),
                                    default=0.0)
    lc = d.get("level_comparison") or {}
    nl = [f for f in d["findings"] if f["physics"] == "nonlinearity"]
    st["level_change"] = abs(nl[0]["parameters"]["relative_change"]) if nl else 0.0
    sh = lc.get("shared_stiffness") or {}
    st["level_excess"] = sh["excess"] / sh["limit"] if sh.get("limit") else 0.0
    st["structural_findings"] = [f["physics"] for f in d["findings"] if f["physics"] not in SETUP]
    st["setup_findings"] = [f["physics"] for f in d["findings"] if f["physics"] in SETUP]
    st["verdict"] = d["verdict"]
    # the lab scoring's own rule (scripts/score_lab.py): an `ambiguous` verdict without a
    # finding is wrong on a null too
    with open(os.path.join(case, "truth.json")) as fh:
        st["ok"] = bool(score_lab.judge(json.load(fh), d)[1])
    return st


# (constant, its value, statistic key, the side that decides, what the statistic is)
RULES = [
    ("ADEQUATE_SDS", decide.ADEQUATE_SDS, "chi2_sds", ">", "baseline reduced chi-square, in its "
     "sampling SDs above ADEQUATE_CHI2 = 1.5 (beyond: the windows are not explained)"),
    ("ADEQUATE_HELD", decide.ADEQUATE_HELD, "held", ">", "baseline held-out mean z^2"),
    ("HELD_OUT_FLOOR", evidence.HELD_OUT_FLOOR, "held", ">", "baseline held-out mean z^2 "
     "(below the floor a candidate's held-out points need only be no worse)"),
    ("HELD_OUT_GAIN", evidence.HELD_OUT_GAIN, "held_ratio", "<", "least held-out ratio "
     "(candidate / baseline) of the structural candidates that pass on BIC (nan: none pass)"),
    ("LEVEL_MISFIT", driver.LEVEL_MISFIT, "level_misfit", ">", "max(reduced chi-square, "
     "held-out) of the baseline (beyond: no linear search on the reference level)"),
    ("MAX_UNEXPLAINED", priors.MAX_UNEXPLAINED, "unexplained", ">", "the fitted C's share "
     "outside a0 M plus story patterns (beyond: no damper is judged)"),
    ("MIN_PHASE", phase.MIN_PHASE, "phase_own", ">", "largest |delay - others' median| x "
     "omega_max over the channels, rad (a channel's own phase error at the band's top)"),
    ("loss EXPLAINED", loss.EXPLAINED, "loss_explained", ">", "largest share of the complex "
     "misfit a loss explains among rows beyond LOSS_Z"),
    ("(extra modes)", 0.0, "extra_modes", ">", "modes outside the model reported (PEAK_Z, "
     "MIN_EXCESS and the peak's shape passed)"),
    ("DELAY_Z", phase.DELAY_Z, "delay_z", ">", "largest |delay| / SE among channels whose delay "
     "explains their phase (a set-up finding)"),
    ("LOSS_Z", loss.LOSS_Z, "loss_z", ">", "largest eta / SE of the loss rows that explain enough"),
    ("STORY_ZETA", priors.STORY_ZETA, "story_zeta", ">", "largest story damping ratio over the "
     "median modal one (lower bound)"),
    ("DAMPER_SE", priors.DAMPER_SE, "damper_z", ">", "largest story dashpot excess / SE"),
    ("level price", 1.0, "level_excess", ">", "two levels' least chi-square rise for one set of "
     "masses and stiffnesses, over BIC's price (above 1: level-dependent)"),
    ("(level change)", 0.0, "level_change", ">", "|relative change| of the named nonlinearity's "
     "story stiffness between levels (single-level nulls: 0)"),
    ("BIC_ACCEPT", -evidence.BIC_ACCEPT, "best_dbic", "<", "most negative scaled dBIC of a "
     "structural candidate refit"),
    ("STRONG_BIC", -evidence.STRONG_BIC, "best_appendage_dbic", "<", "most negative scaled dBIC "
     "of an appendage refit"),
]


def table(out):
    cases = sorted(c for c in glob.glob(os.path.join(out, "seed_*", "0[0-7]_null_lab*")))
    stats = [s for s in (statistics(c) for c in cases) if s is not None]
    print(f"{len(stats)} diagnosed nulls of {len(cases)} in {out}")
    if not stats:
        return
    n = len(stats)
    print(f"{'constant':22s} {'value':>8s} {'median':>9s} {'worst':>9s}  beyond (Wilson 95 %)")
    for name, value, key, side, what in RULES:
        v = np.array([s[key] for s in stats], float)
        k = int(np.sum(v > value) if side == ">" else np.sum(v < value))
        lo, hi = wilson(k, n)
        worst = np.nanmax(v) if side == ">" else np.nanmin(v)
        print(f"{name:22s} {value:8.3g} {np.nanmedian(v):9.3g} {worst:9.3g}  "
              f"{k}/{n} ({100 * lo:.0f}-{100 * hi:.0f} %)   {what}")
    fa = [s for s in stats if s["structural_findings"]]
    lo, hi = wilson(len(fa), n)
    print(f"false alarms (a structural finding): {len(fa)}/{n} ({100 * lo:.0f}-{100 * hi:.0f} %)")
    wrong = [s for s in stats if not s["ok"]]
    lo, hi = wilson(len(wrong), n)
    print(f"wrong by the lab scoring (scripts/score_lab.py): {len(wrong)}/{n} "
          f"({100 * lo:.0f}-{100 * hi:.0f} %)")
    for s in stats:
        print(f"  {s['case']:34s} {s['verdict']:16s} chi2 {s['chi2']:7.2f} held {s['held']:6.2f}  "
              f"structural {s['structural_findings']}  set-up {s['setup_findings']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--run", action="store_true", help="generate and diagnose the missing nulls")
    ap.add_argument("--seeds", type=int, nargs="*", default=[4])
    ap.add_argument("--only", default="0-7", help="null case numbers, e.g. 0-7 or 1,3")
    ap.add_argument("--timeout", type=float, default=2400.0)
    a = ap.parse_args()
    only = []
    for part in a.only.split(","):
        lo, _, hi = part.partition("-")
        only += list(range(int(lo), int(hi or lo) + 1))
    if a.run:
        run(a.out, a.seeds, only, a.timeout)
    table(a.out)


if __name__ == "__main__":
    main()
