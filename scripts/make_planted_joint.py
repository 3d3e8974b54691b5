"""Planted effects in both Cristallo tests at once, for the joint diagnosis (issue 45).

The joint case (cases/cristallo_three_storey/case_joint.yaml) fits Experimental.csv
(shaker at floor 1) and test_2.csv (shaker at floor 2) as one structure measured by one
set of sensors. A planted effect must then be what the real change would be: in both
tests. Per case, planted into both files by exact frequency-based substructuring
(nlp/testing/plant.py), which keeps the real noise and the frame's own unmodelled physics:

* an appendage at floor p (1 and 2, one case each): mass 2-5 % of the model's total
  nominal mass, tuned to 0.85-1.15 of a measured peak, damping ratio 1-3 %;
* an added mass at floor p (1 and 2): 20-40 % of the nominal floor mass (prior 10 %);
* a gain on one channel (two cases, two channels), the same sensor in both tests:
  0.85-0.93 or 1.07-1.15;
* a delay on one channel (two cases, two channels), in both tests: 1-5 ms;
* control: both files unchanged, through the same writer.

A structural change at floor p reaches the test driven at b != p through its transfer
receptances: R'_rb = R_rb - R_rp z R_pb / (1 + z R_pp), with R_rp and R_pp from the test
driven at p and R_pb from the test driven at b (no reciprocity assumed). The planted cases
are scored against the control by scripts/score_planted_real.py (tag `joint`).

    python scripts/make_planted_joint.py --out /work/planted_joint [--seed N]
"""

import json
import os
import shutil

import numpy as np
import yaml

from make_planted_real import (LICENCE, SRC, appendage_truth, arguments, check_control, mass_truth,
                               measured_peaks, print_case, read_table, sensor_truths,
                               write_manifest, write_table)
from nlp.testing.plant import (accelerance, added_mass_z, appendage_z, attach_transfer, delay,
                               gain, receptance)

CASE = "case_joint.yaml"
TAG = "joint"


def tests_of(case):
    """[(data file, driven floor)] of the joint case: the main file, then data.tests."""
    d = case["data"]
    return [(d["file"], int(case["excitation"]["floor"]))] + \
        [(t["file"], int(t["force_floor"])) for t in d.get("tests", [])]


def floor_columns(case):
    """Table columns (1 + data column) of the channels in floor order 1..n."""
    by_floor = {int(c["floor"]): 1 + int(c["column"]) for c in case["data"]["channels"]}
    return [by_floor[j] for j in range(1, len(by_floor) + 1)]


def draw(rng, case, peaks):
    """The eight planted effects: an appendage and an added mass at each driven floor, two
    gains and two delays (make_planted_real's sizes): list of (name, truth)."""
    m = np.asarray(case["model"]["masses"], dtype=float)
    driven = [b for _, b in tests_of(case)]
    modes = rng.choice(len(peaks), 2, replace=False)
    out = [(f"appendage{k + 1}", appendage_truth(rng, m, p, peaks[mode]))
           for k, (p, mode) in enumerate(zip(driven, modes))]
    out += [(f"mass{k + 1}", mass_truth(rng, m, p)) for k, p in enumerate(driven)]
    return out + sensor_truths(rng, [c["name"] for c in case["data"]["channels"]])


def structural_z(w, truth):
    """Dynamic stiffness [N/m] of the planted mass or appendage."""
    s = truth["size"]
    if truth["family"] == "added_mass":
        return added_mass_z(w, s["dm_kg"])
    wa = 2 * np.pi * s["f_a_hz"]
    return appendage_z(w, s["m_a_kg"], s["m_a_kg"] * wa**2, 2 * s["zeta_a"] * s["m_a_kg"] * wa)


def plant(tables, case, truth):
    """{driven floor: table} with truth planted in every test (columns: f, then channels)."""
    out = {b: t.copy() for b, t in tables.items()}
    f = next(iter(tables.values()))[:, 0].real
    if np.any(f <= 0) or any(not np.array_equal(t[:, 0].real, f) for t in tables.values()):
        raise ValueError("the tests must share one frequency grid, f > 0")
    w = 2 * np.pi * f
    fam, loc = truth["family"], truth["location"]
    if fam in ("added_mass", "secondary_oscillator"):
        p, cols = loc["floor"], floor_columns(case)
        if p not in tables:
            raise ValueError(f"floor {p} is driven in no test: its transfer receptances are unknown")
        z = structural_z(w, truth)
        R = {b: receptance(t[:, cols].T, w) for b, t in tables.items()}
        for b in tables:
            out[b][:, cols] = accelerance(attach_transfer(R[b], R[p], R[b][p - 1], R[p][p - 1], z),
                                          w).T
        return out
    c = {ch["name"]: 1 + int(ch["column"]) for ch in case["data"]["channels"]}[loc["channel"]]
    for b, t in tables.items():
        out[b][:, c] = gain(t[:, c], truth["size"]["gain"]) if fam == "sensor_gain" else \
            delay(t[:, c], w, 1e-3 * truth["size"]["delay_ms"])
    return out


def write_case(folder, case, files, tables, truth):
    """Both data files, case.yaml, truth.json and the licence into folder."""
    os.makedirs(folder, exist_ok=True)
    c = json.loads(json.dumps(case))                 # a deep copy
    c["name"] = f"{case['name']}_{os.path.basename(folder)}"
    for name, b in files:
        write_table(os.path.join(folder, os.path.basename(name)), tables[b])
    with open(os.path.join(folder, "case.yaml"), "w") as fh:
        fh.write(f"# {truth['source_case']} with an effect planted in both tests "
                 "(scripts/make_planted_joint.py; what: truth.json).\n"
                 "# Data and licence: DATA_LICENSE.md.\n")
        yaml.safe_dump(c, fh, sort_keys=False)
    with open(os.path.join(folder, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    shutil.copy(os.path.join(SRC, LICENCE), os.path.join(folder, LICENCE))


def main():
    out, seed, rng = arguments(__doc__, "planted_joint")
    with open(os.path.join(SRC, CASE)) as fh:
        case = yaml.safe_load(fh)
    files = tests_of(case)
    tables = {b: read_table(os.path.join(SRC, name)) for name, b in files}
    fr = case["frequencies"]
    main_table = tables[files[0][1]]
    peaks = measured_peaks(main_table[:, 0].real, main_table[:, floor_columns(case)].T,
                           fr["fmin"], fr["fmax"], int(fr["n_peaks"]))
    base = {"source_files": [n for n, _ in files], "source_case": f"{SRC}/{CASE}",
            "driven_floors": [b for _, b in files], "seed": seed, "measured_peaks_hz": peaks}
    names = []
    for name, truth in draw(rng, case, peaks) + [("control", {"family": None})]:
        truth = {"family": truth["family"], "location": truth.get("location"),
                 "size": truth.get("size"), **base}
        planted = plant(tables, case, truth) if truth["family"] else tables
        folder = os.path.join(out, f"{TAG}_{name}")
        write_case(folder, case, files, planted, truth)
        names.append(f"{TAG}_{name}")
        print_case(TAG, name, truth)
    for name, b in files:
        check_control(os.path.join(out, f"{TAG}_control", os.path.basename(name)), tables[b])
    write_manifest(out, seed, names, "make_planted_joint.py")


if __name__ == "__main__":
    main()
