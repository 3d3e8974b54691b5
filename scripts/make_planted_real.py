"""Planted effects in the real Cristallo recordings (issue 45, item 3).

Known effects are planted into the measured accelerances by exact frequency-based
substructuring (nlp/testing/plant.py), which keeps the real noise and the frame's own
unmodelled physics. Per source file (Experimental.csv: shaker at floor 1; test_2.csv:
shaker at floor 2), with sizes drawn from --seed:

* 2 appendages at the driving point p: mass 2-5 % of the model's total nominal mass,
  tuned to 0.85-1.15 of a measured peak (the n_peaks highest local maxima of the
  channel-summed |A| inside the case's fmin-fmax; two different peaks), damping
  ratio 1-3 %;
* 2 added masses at p: 20-40 % of the nominal mass of floor p (the case's prior is 10 %);
* 2 gains on two different channels: 0.85-0.93 or 1.07-1.15 (each side equally likely);
* 2 delays on two different channels: 1-5 ms;
* control: the data unchanged, through the same writer and case treatment;
* control_ref: as control, but with the source case's validation_file kept (an
  unchanged copy of the other test), to compare with the reference diagnosis.

Planted cases and the control drop data.validation_file: it would point to the other
test, which does not carry the planted effect. Each folder holds the data file (same
name and `;`-separated complex format as the source), case.yaml, truth.json and the
data licence (DATA_LICENSE.md).

    python scripts/make_planted_real.py --out /work/planted [--seed N]
"""

import argparse
import json
import os
import secrets
import shutil

import numpy as np
import yaml

from nlp.testing.plant import added_mass_z, appendage_z, attach_accelerance, delay, gain

SRC = os.path.join("cases", "cristallo_three_storey")
SOURCES = (("exp", "case.yaml"), ("t2", "case_test2.yaml"))
LICENCE = "DATA_LICENSE.md"


def read_table(path):
    """Rows of Python complex literals separated by `;`: (n_f, 1 + n_ch) complex."""
    with open(path) as fh:
        return np.array([[complex(t) for t in ln.split(";")] for ln in fh if ln.strip()])


def format_value(z):
    """The source's spelling: Python's complex repr without parentheses (round-trips)."""
    return repr(complex(z)).strip("()")


def write_table(path, table):
    with open(path, "w") as fh:
        fh.write("\n".join(";".join(format_value(z) for z in row) for row in table) + "\n")


def measured_peaks(f, A, fmin, fmax, n, min_gap=2.0):
    """The n highest local maxima [Hz] of sum |A| over channels in (fmin, fmax), at least
    min_gap [Hz] apart, in increasing frequency."""
    s = np.abs(A).sum(axis=0)
    i = np.arange(1, len(f) - 1)
    i = i[(s[i] > s[i - 1]) & (s[i] >= s[i + 1]) & (f[i] > fmin) & (f[i] < fmax)]
    picked = []
    for k in i[np.argsort(s[i])[::-1]]:
        if all(abs(f[k] - f[j]) >= min_gap for j in picked):
            picked.append(k)
        if len(picked) == n:
            break
    return sorted(float(f[k]) for k in picked)


def appendage_truth(rng, m, p, peak):
    """An appendage at floor p: 2-5 % of the total nominal mass, tuned to 0.85-1.15 of the
    measured peak [Hz], damping ratio 1-3 %."""
    frac, ratio, zeta = rng.uniform(0.02, 0.05), rng.uniform(0.85, 1.15), rng.uniform(0.01, 0.03)
    m_a, f_a = frac * m.sum(), ratio * peak
    return {"family": "secondary_oscillator", "location": {"floor": p},
            "size": {"m_a_kg": m_a, "fraction_of_total_mass": frac, "mu_to_mean_floor_mass":
                     m_a / m.mean(), "f_a_hz": f_a, "tuned_to_peak_hz": peak,
                     "tuning_ratio": ratio, "zeta_a": zeta}}


def mass_truth(rng, m, p):
    """An added mass of 20-40 % of the nominal mass of floor p."""
    frac = rng.uniform(0.20, 0.40)
    return {"family": "added_mass", "location": {"floor": p},
            "size": {"dm_kg": frac * m[p - 1], "fraction_of_floor": frac}}


def sensor_truths(rng, chans):
    """Two gains (0.85-0.93 or 1.07-1.15) and two delays (1-5 ms), each pair on two
    different channels: [(name, truth)]."""
    out = []
    for k, ch in enumerate(rng.choice(len(chans), 2, replace=False)):
        g = rng.uniform(0.85, 0.93) if rng.random() < 0.5 else rng.uniform(1.07, 1.15)
        out.append((f"gain{k + 1}", {"family": "sensor_gain", "location": {"channel": chans[ch]},
                                     "size": {"gain": g, "gain_minus_1": g - 1}}))
    for k, ch in enumerate(rng.choice(len(chans), 2, replace=False)):
        out.append((f"delay{k + 1}", {"family": "sensor_delay", "location": {"channel": chans[ch]},
                                      "size": {"delay_ms": rng.uniform(1.0, 5.0)}}))
    return out


def draw(rng, case, peaks):
    """The eight planted effects of one source file: list of (name, truth)."""
    m = np.asarray(case["model"]["masses"], dtype=float)
    p = int(case["excitation"]["floor"])
    chans = [c["name"] for c in case["data"]["channels"]]
    out = [(f"appendage{k + 1}", appendage_truth(rng, m, p, peaks[mode]))
           for k, mode in enumerate(rng.choice(len(peaks), 2, replace=False))]
    out += [(f"mass{k + 1}", mass_truth(rng, m, p)) for k in range(2)]
    return out + sensor_truths(rng, chans)


def plant(table, case, truth):
    """The data table with the effect of truth planted (columns: f, then the channels)."""
    out = table.copy()
    f = table[:, 0].real
    if np.any(f <= 0):
        raise ValueError("substructuring on accelerances needs f > 0")
    w = 2 * np.pi * f
    col = {c["name"]: 1 + int(c["column"]) for c in case["data"]["channels"]}
    by_floor = {int(c["floor"]): 1 + int(c["column"]) for c in case["data"]["channels"]}
    fam, s = truth["family"], truth["size"]
    if fam in ("added_mass", "secondary_oscillator"):
        cols = sorted(col.values())
        p = cols.index(by_floor[truth["location"]["floor"]])
        if fam == "added_mass":
            z = added_mass_z(w, s["dm_kg"])
        else:
            wa = 2 * np.pi * s["f_a_hz"]
            z = appendage_z(w, s["m_a_kg"], s["m_a_kg"] * wa**2, 2 * s["zeta_a"] * s["m_a_kg"] * wa)
        out[:, cols] = attach_accelerance(table[:, cols].T, w, p, z).T
    elif fam == "sensor_gain":
        c = col[truth["location"]["channel"]]
        out[:, c] = gain(table[:, c], s["gain"])
    elif fam == "sensor_delay":
        c = col[truth["location"]["channel"]]
        out[:, c] = delay(table[:, c], w, 1e-3 * s["delay_ms"])
    return out


def write_case(folder, case, table, truth, keep_validation=False):
    """Data, case.yaml, truth.json and licence into folder; returns the folder."""
    os.makedirs(folder, exist_ok=True)
    c = json.loads(json.dumps(case))                 # a deep copy
    c["name"] = f"{case['name']}_{os.path.basename(folder)}"
    d = c["data"]
    write_table(os.path.join(folder, os.path.basename(d["file"])), table)
    if keep_validation:
        write_table(os.path.join(folder, os.path.basename(d["validation_file"])),
                    read_table(os.path.join(SRC, d["validation_file"])))
    else:
        d.pop("validation_file", None)
        d.pop("validation_force_floor", None)
    with open(os.path.join(folder, "case.yaml"), "w") as fh:
        fh.write(f"# {truth['source_case']} with a planted effect (scripts/make_planted_real.py; "
                 "what: truth.json).\n# Data and licence: DATA_LICENSE.md.\n")
        yaml.safe_dump(c, fh, sort_keys=False)
    with open(os.path.join(folder, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    shutil.copy(os.path.join(SRC, LICENCE), os.path.join(folder, LICENCE))
    return folder


def make_source(out, tag, case_file, rng, seed):
    """All cases of one source file; returns their names."""
    with open(os.path.join(SRC, case_file)) as fh:
        case = yaml.safe_load(fh)
    table = read_table(os.path.join(SRC, case["data"]["file"]))
    fr = case["frequencies"]
    A = table[:, [1 + int(c["column"]) for c in case["data"]["channels"]]].T
    peaks = measured_peaks(table[:, 0].real, A, fr["fmin"], fr["fmax"], int(fr["n_peaks"]))
    base = {"source_file": case["data"]["file"], "source_case": f"{SRC}/{case_file}",
            "driving_floor": int(case["excitation"]["floor"]), "seed": seed,
            "measured_peaks_hz": peaks}
    names = []
    for name, truth in draw(rng, case, peaks) + [("control", {"family": None}),
                                                 ("control_ref", {"family": None})]:
        truth = {"family": truth["family"], "location": truth.get("location"),
                 "size": truth.get("size"), **base}
        planted = plant(table, case, truth) if truth["family"] else table
        write_case(os.path.join(out, f"{tag}_{name}"), case, planted, truth,
                   keep_validation=name == "control_ref")
        names.append(f"{tag}_{name}")
        print_case(tag, name, truth)
    check_control(os.path.join(out, f"{tag}_control", os.path.basename(case["data"]["file"])),
                  table)
    return names


def print_case(tag, name, truth):
    """One line: the case, its planted family, location and sizes."""
    print(f"{tag}_{name:12s} {truth['family'] or 'none':21s} {truth['location'] or ''!s:22s} "
          + " ".join(f"{k} {v:.4g}" for k, v in (truth["size"] or {}).items()), flush=True)


def check_control(path, table):
    """The writer must reproduce the source values bit for bit."""
    if not np.array_equal(read_table(path), table):
        raise SystemExit(f"{path}: the control does not reproduce the source data exactly")


def arguments(doc, default_out):
    """--out and --seed of a planting script: (out, seed, its generator); a seed not given
    is drawn at random and printed, so the set can be written again."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", default=default_out)
    ap.add_argument("--seed", type=int, help="default: drawn at random and printed")
    a = ap.parse_args()
    seed = a.seed if a.seed is not None else secrets.randbelow(1_000_000)
    print(f"seed {seed}", flush=True)
    return a.out, seed, np.random.default_rng(seed)


def main():
    out, seed, rng = arguments(__doc__, "planted_real")
    names = []
    for tag, case_file in SOURCES:
        names += make_source(out, tag, case_file, rng, seed)
    write_manifest(out, seed, names, "make_planted_real.py")


def write_manifest(out, seed, names, script):
    """out/manifest.json: the seed, the cases and the command that rewrites them."""
    with open(os.path.join(out, "manifest.json"), "w") as fh:
        json.dump({"seed": seed, "cases": names,
                   "command": f"python scripts/{script} --out {out} --seed {seed}"}, fh, indent=1)
    print(f"wrote {len(names)} cases under {out} (seed {seed})")


if __name__ == "__main__":
    main()
