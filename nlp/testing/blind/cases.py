"""The blind benchmark's case list and one case: its real system, simulated test,
records (or FRF file), case.yaml and truth.json."""

import json
import os

import numpy as np
import yaml
from scipy import signal

from nlp.testing.blind.experiment import (G, SIM_FACTOR, drive, load_vector, record, run_test,
                                          write_csv)
from nlp.testing.blind.recipe import case_yaml, welch_frf
from nlp.testing.blind.simulators import newmark
from nlp.testing.blind.structures import FAMILIES, SIZES, real_structure, with_effect


def location(family, loc, channel=None):
    """The location in the tool's terms (floors 1..n, 0 = ground)."""
    if family in ("added_mass", "secondary_oscillator"):
        return {"floor": loc}
    if family in ("local_damper", "nonadjacent_coupling"):
        return {"between": sorted(loc)}
    if family == "hysteretic_damping":
        return {} if loc is None else {"between": [loc - 1, loc]}
    if family == "nonlinearity":
        return {"between": [loc - 1, loc]}
    if family in ("sensor_gain", "sensor_delay"):
        return {"channel": channel}
    return {}


def _draw_location(rng, family, n):
    if family in ("added_mass", "secondary_oscillator", "sensor_gain", "sensor_delay",
                  "nonlinearity"):
        return int(rng.integers(1, n + 1))
    if family == "local_damper":
        i = int(rng.integers(1, n + 1))
        return (i, i - 1)
    if family == "nonadjacent_coupling":
        i = int(rng.integers(1, n - 1))
        return (i, int(rng.integers(i + 2, n + 1)))
    if family == "hysteretic_damping":
        return None if rng.uniform() < 0.5 else int(rng.integers(1, n + 1))
    return None


def describe_test(rng, spec, st):
    """The test: sampling rate, band (around the real structure's modes), LVDT floors,
    shaker floor, drive amplitude and sensor noise level."""
    n = spec["storeys"]
    ground = spec["excitation"] == "ground"
    fs = 100.0 if st["f_n"][-1] < 14 else 200.0
    f1 = float(np.ceil(1.3 * st["f_n"][-1] * (1 + 0.2 * rng.uniform())))   # the test's band
    f0 = float(np.round(max(0.2, 0.5 * st["f_n"][0]), 1))
    lvdt = sorted(set([n, int(rng.integers(1, n + 1))]))
    return {"storeys": n, "excitation": spec["excitation"], "fs": fs, "f0": f0, "f1": f1,
            "signal": spec["signal"], "zeta": st["zeta"], "f_first": st["f_n"][0],
            "seconds": 400.0, "lvdt_floors": lvdt,
            "force_floor": int(rng.integers(1, n + 1)) if not ground else None,
            "amplitude": 0.05 * G if ground else 5.0,
            "noise": float(rng.uniform(0.015, 0.02))}


def real_system(rng, st, effects, test):
    """The real system: the effects composed on top of each other. Returns its matrices
    (M, C, K, Kh), the truth entry of each effect, the sensor distortion and the
    nonlinear spring's (story, size, kind), if any; a flexible base sets test["base_dof"]."""
    n = test["storeys"]
    mats = (st["M"], st["C"], st["K"], np.zeros_like(st["K"]))
    truth_effects, sensor, nonlin_spec = [], None, None
    for fam, size in effects:
        loc = _draw_location(rng, fam, n)
        channel = None
        if fam in ("sensor_gain", "sensor_delay"):
            channel = f"a{loc}"
            sign = 1 if fam == "sensor_delay" else rng.choice([-1, 1])
            sensor = (fam, f"acc{loc}", float(sign * size))
            par = {"gain" if fam == "sensor_gain" else "delay_ms": float(sign * size)}
        elif fam == "nonlinearity":
            nonlin_spec = (loc, size, str(rng.choice(["cubic", "contact"])))
            par = {"stiffening_high_level": size, "kind": nonlin_spec[2]}
        else:
            *mats, par = with_effect(st, mats, fam, loc, size, rng)
            if fam == "base_flexibility":
                test["base_dof"] = mats[0].shape[0] - 1
        truth_effects.append({"family": fam, "size": float(size),
                              "location": location(fam, loc, channel),
                              "parameters": {k: v if isinstance(v, str) else float(v)
                                             for k, v in par.items()}})
    return tuple(mats), truth_effects, sensor, nonlin_spec


def calibrated_spring(mats, test, u, st, nonlin_spec):
    """The nonlinear story spring, calibrated on the linear drift d at the high level:
    equivalent stiffening 3 k3 E[d^2] (cubic) or k_c P(|d| > gap) (contact) = size x k_story."""
    story, size, kind = nonlin_spec
    M = mats[0]
    q = newmark(M, mats[1], mats[2], load_vector(M, test), 3.0 * test["amplitude"] * u,
                1 / (test["fs"] * SIM_FACTOR))[0]
    d = q[story - 1] - (q[story - 2] if story > 1 else 0.0)
    d = d[np.abs(u) > 0] if test["signal"] == "chirp" else d
    ks = st["k"][story - 1]
    if kind == "cubic":
        return {"story": story, "kind": kind, "k_nl": size * ks / (3 * np.var(d)), "gap": 0.0}
    gap = float(np.std(d))
    return {"story": story, "kind": kind,
            "k_nl": size * ks / max(float(np.mean(np.abs(d) > gap)), 1e-3), "gap": gap}


def write_data(folder, spec, mats, test, drive_signal, levels, nl, sensor, seed):
    """Simulate the test at each level and write its records (records.csv,
    records_level2.csv), or the H1 FRF file of the first level; returns the file names."""
    t, u = drive_signal
    n, fs = test["storeys"], test["fs"]
    ground = test["excitation"] == "ground"
    files = []
    noise_rng = np.random.default_rng(seed + 1)
    for j, lv in enumerate(levels):
        cols = run_test(mats, test, t, u, level=lv, nonlin=nl)
        rec = record(t, cols, test, noise_rng, sensor)
        if spec.get("route") == "frf_file":
            si = {k: v * G if (k == "input" and ground) or k.startswith("acc") else v
                  for k, v in rec.items()}
            f, H, coh, nd = welch_frf(si, n, fs, spec["nperseg"])
            keep = (f > 0) & (f <= test["f1"] * 1.2)
            arrays = {"f": f[keep], "H": H[:, keep]}
            if spec.get("coherence"):
                arrays.update(coherence=coh[:, keep], n_averages=np.array(nd))
            np.savez(os.path.join(folder, "frf.npz"), **arrays)
            files.append("frf.npz")
            break
        name = "records.csv" if j == 0 else f"records_level{j + 1}.csv"
        write_csv(os.path.join(folder, name), rec)
        files.append(name)
    return files


def case_description(spec, test, st, M, files, levels, base_channel, residual, prior):
    """What the recipe (`case_yaml`) may read: the test as a lab would describe it."""
    n, fs, f0, f1, lvdt = (test[k] for k in ("storeys", "fs", "f0", "f1", "lvdt_floors"))
    ground = spec["excitation"] == "ground"
    route = spec.get("route") or ("one_segment" if spec["signal"] == "chirp" else "welch")
    nperseg = int(spec.get("nperseg", 4096 if fs == 100.0 else 8192))
    text = (f"{n}-storey frame, {'shake-table' if ground else 'shaker at floor %d' % test['force_floor']} "
            f"test, {spec['signal']} excitation {f0:g}-{f1:g} Hz"
            + (", repeated at 3x the level" if len(levels) > 1 else "")
            + f"; accelerometers on every floor{' and the table' if ground and base_channel else ''}, "
            f"LVDTs on floor(s) {', '.join(map(str, lvdt))}; design masses and stiffnesses"
            + ("; the whole frame weighed" if ground else ""))
    return {"storeys": n, "excitation": spec["excitation"], "force_floor": test["force_floor"],
            "route": route, "signal": spec["signal"], "f0": f0, "f1": f1, "lvdt_floors": lvdt,
            "base_channel": base_channel, "level_files": files[1:], "nperseg": nperseg, "prior": prior,
            "m_design": st["m_design"], "k_design": st["k_design"], "residual": residual,
            "weighed_total_mass": round(float(np.trace(M[:n, :n])), 3), "text": text}


def make_case(folder, spec, seed, base_channel=True, residual="log_magnitude", prior=None):
    """Simulate one test (or two levels) and write records, case.yaml and truth.json."""
    rng = np.random.default_rng(seed)
    st = real_structure(rng, spec["storeys"], spec.get("ordinary", False))
    test = describe_test(rng, spec, st)
    mats, truth_effects, sensor, nonlin_spec = real_system(rng, st, spec.get("effects", []), test)
    levels = [1.0, 3.0] if (nonlin_spec or spec.get("two_levels")) else [1.0]
    if nonlin_spec:
        test["seconds"] = 200.0
    t, u = drive(test, seed + 7)
    nl = calibrated_spring(mats, test, u, st, nonlin_spec) if nonlin_spec else None
    os.makedirs(folder, exist_ok=True)
    files = write_data(folder, spec, mats, test, (t, u), levels, nl, sensor, seed)
    desc = case_description(spec, test, st, mats[0], files, levels, base_channel, residual,
                            prior)
    with open(os.path.join(folder, "case.yaml"), "w") as fh:
        yaml.safe_dump(case_yaml(os.path.basename(folder), desc), fh, sort_keys=False)
    truth = {"effects": truth_effects, "route": desc["route"], "signal": spec["signal"],
             "excitation": spec["excitation"], "force_floor": test["force_floor"],
             "storeys": test["storeys"],
             "ordinary": bool(spec.get("ordinary", False)), "masses": st["m"], "stiffnesses": st["k"],
             "design_masses": st["m_design"], "design_stiffnesses": st["k_design"],
             "natural_frequencies_hz": st["f_n"], "rayleigh_zeta": st["zeta"], "noise": test["noise"],
             "story_dashpot_excess": st["dashpot_excess"],
             "nonlinear_spring": nl, "seed": seed,
             "system": {"M": mats[0], "C": mats[1], "K": mats[2], "Kh": mats[3],
                        "base_dof": test.get("base_dof"), "sensor": sensor}}
    with open(os.path.join(folder, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2, default=lambda x: np.asarray(x).tolist())


def check_case(folder):
    """Median |ln(H_est / H_exact)| of the floor accelerometers at the fitted band's
    resonances (+-1 half-power width): the simulation, filtering and units checked
    against the exact FRF of the truth's matrices (linear cases only)."""
    with open(os.path.join(folder, "truth.json")) as fh:
        tr = json.load(fh)
    with open(os.path.join(folder, "case.yaml")) as fh:
        cfg = yaml.safe_load(fh)
    if tr["nonlinear_spring"] or tr["route"] == "frf_file":
        return ""
    sy = tr["system"]
    M, C, K, Kh = (np.array(sy[k]) for k in ("M", "C", "K", "Kh"))
    rec = np.genfromtxt(os.path.join(folder, "records.csv"), delimiter=",", names=True)
    n = tr["storeys"]
    ground = tr["excitation"] == "ground"
    fs = 1 / (rec["t"][1] - rec["t"][0])
    nper = rec.size if cfg["data"]["nperseg"] == "all" else cfg["data"]["nperseg"]
    win = cfg["data"]["window"]
    x = rec["input"]
    f, sxx = signal.welch(x, fs, window=win, nperseg=nper)
    b = -M @ np.ones(M.shape[0]) if ground else np.eye(M.shape[0])[tr["force_floor"] - 1]
    fn = np.array(tr["natural_frequencies_hz"])
    band = np.zeros(f.size, bool)
    for fr in fn:
        band |= np.abs(f - fr) <= max(2 * 0.03 * fr, 2 * f[1])
    band &= (f >= cfg["frequencies"]["fmin"]) & (f <= cfg["frequencies"]["fmax"])
    errs = []
    for i in range(n):
        if sy["sensor"] and sy["sensor"][1] == f"acc{i + 1}":
            continue
        _, sxy = signal.csd(x, rec[f"acc{i + 1}"], fs, window=win, nperseg=nper)
        H = (sxy / sxx)[band]
        w = 2 * np.pi * f[band]
        Hx = np.array([-(wk**2) * np.linalg.solve(K + 1j * Kh - wk**2 * M + 1j * wk * C, b)[i]
                       for wk in w]) + (1.0 if ground else 0.0)
        Hx = Hx if ground else Hx / G          # accelerometers in g, force in N
        errs.append(np.median(np.abs(np.log(H / Hx))))
    return f"  (estimate vs exact FRF near the modes: median |ln ratio| {np.median(errs):.3f})"


# ------------------------------------------------------------------ the case list
def specs(rng):
    """At least 60 cases: every family at five sizes (45), two-effect cases (6), null
    cases with non-proportional damping (5), ordinary-change cases (5), FRF-file cases (4)."""
    out = []
    for fam in FAMILIES:
        for size in SIZES[fam]:
            out.append({"effects": [(fam, size)]})
    pairs = [("added_mass", "sensor_gain"), ("local_damper", "nonadjacent_coupling"),
             ("secondary_oscillator", "sensor_delay"), ("base_flexibility", "added_mass"),
             ("hysteretic_damping", "sensor_gain"), ("nonadjacent_coupling", "secondary_oscillator")]
    for a, b in pairs:
        out.append({"effects": [(a, SIZES[a][3]), (b, SIZES[b][3])]})
    for r in range(5):
        out.append({"effects": [], "two_levels": r < 2})
    for r in range(5):
        out.append({"effects": [], "ordinary": True})
    for r in range(4):
        out.append({"effects": [] if r < 2 else [(("added_mass", "sensor_gain")[r - 2],
                                                 SIZES[("added_mass", "sensor_gain")[r - 2]][3])],
                    "route": "frf_file", "coherence": r % 2 == 0, "signal": "random"})
    for s in out:
        s["storeys"] = int(rng.integers(3, 6))
        s["excitation"] = str(rng.choice(["ground", "force"]))
        s.setdefault("signal", str(rng.choice(["chirp", "random"])))
        if s.get("route") == "frf_file":
            s["nperseg"] = 4096
    return out


def case_name(k, s):
    """Folder name of case k: number, families (or null/ordinary), _frf for FRF-file cases."""
    fams = "+".join(f for f, _ in s["effects"]) or ("ordinary" if s.get("ordinary") else "null")
    return f"{k:02d}_{fams}" + ("_frf" if s.get("route") == "frf_file" else "")


def case_numbers(text, n):
    """Case numbers from a command line's --only ("0-7", "3,17,30"; None: all of 0..n-1),
    those below n, in the order given."""
    if not text:
        return list(range(n))
    out = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return [k for k in out if k < n]
