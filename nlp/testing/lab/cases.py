"""The lab benchmark's case list and one case: the real structure in the imperfect lab,
its simulated test(s), records, case.yaml (the blind benchmark's recipe) and truth.json."""

import json
import os

import numpy as np
import yaml

from nlp.testing.blind.cases import describe_test, real_system
from nlp.testing.blind.experiment import SIM_FACTOR, drive, write_csv
from nlp.testing.blind.recipe import case_yaml
from nlp.testing.blind.structures import (DASHPOT_CAP, FAMILIES, SIZE_DETECTABLE, SIZES,
                                          real_structure)
from nlp.testing.lab.chain import CALIBRATION, draw_chain, draw_orders
from nlp.testing.lab.detectable import FISHER_FAMILIES, damper_rule, detectability
from nlp.testing.lab.experiment import simulate, record
from nlp.testing.lab.links import (OUTSIDE, OUTSIDE_SIZES, crack, family_nonlinearity, friction,
                                   joints, sliding_mass)
from nlp.testing.lab.noise import COMMON, LEVEL, PINK
from nlp.testing.lab.structures import RHO, eccentric_frame, flexible_frame, shear_maps
from nlp.testing.lab.table import draw_shaker, draw_table

WEIGHING = 0.01        # |relative error| of the weighed total mass
CATEGORIES = ("null_lab", "in_catalogue", "out_of_catalogue", "non_shear", "torsion")
VERDICTS = {"null_lab": ["adequate", "setup_error"],
            "in_catalogue": ["missing_physics"],
            "out_of_catalogue": ["partly_explained", "ambiguous"],
            # frame action is a catalogue family: naming it is missing_physics
            "non_shear": ["missing_physics", "partly_explained", "ambiguous"],
            "torsion": ["partly_explained", "ambiguous"]}


def draw_lab(rng, test, st, names):
    """Every channel's chain, the noise, and the table or shaker of this test."""
    force = test["excitation"] == "force"
    orders = draw_orders(rng)
    lab = {"chains": {k: draw_chain(rng, k, test["fs"], orders, force_input=force) for k in names},
           "noise": {"common": float(rng.uniform(*COMMON)), "pink": float(rng.uniform(*PINK)),
                     "level": {k: float(rng.uniform(*LEVEL)) for k in names}}}
    if force:
        lab["shaker"] = draw_shaker(rng, st["m"][test["force_floor"] - 1], st["f_n"][0])
    else:
        lab["table"] = draw_table(rng, float(np.sum(st["m"])), st["f_n"][-1])
    lab["weighing_error"] = float(rng.uniform(-WEIGHING, WEIGHING))
    return lab


def column_names(test):
    """The recorded columns of the test."""
    names = ["input"] + (["base_acc"] if test["excitation"] == "ground" else [])
    return names + [f"acc{i + 1}" for i in range(test["storeys"])] + [f"lvdt{i}" for i in test["lvdt_floors"]]


def structure(rng, spec):
    """The real structure of the spec's category (dict of structures.py / blind)."""
    n = spec["storeys"]
    if spec["category"] == "non_shear":
        return flexible_frame(rng, n, spec["rho"])
    if spec["category"] == "torsion":
        return eccentric_frame(rng, n)
    st = real_structure(rng, n, False)
    st.update(shear_maps(n, n))
    return st


def system_of(st, mats, test, links=()):
    """What simulate() reads: matrices, maps and links, the force DOF of a shaker test."""
    maps = st if "torsion" in st else shear_maps(mats[0].shape[0], test["storeys"])
    ff = test["force_floor"]
    return {"mats": tuple(mats), "out": maps["out"], "r": maps["r"],
            "force_dof": maps["force_dof"](ff) if ff else None, "links": list(links)}


def plant(rng, spec, st, test, lab, u):
    """The real system with its effects and links; the truth entries. Linear runs at
    levels 1 and 3 size the nonlinear links on the case's own drifts."""
    mats = (st["M"], st["C"], st["K"], np.zeros_like(st["K"]))
    truth_effects, sensor, nl_spec = [], None, None
    if spec["category"] == "in_catalogue":
        mats, truth_effects, sensor, nl_spec = real_system(rng, st, spec["effects"], test)
    lin = system_of(st, mats, test)
    q1 = simulate(lin, lab, test, u, 1.0)[1]
    links = []
    base = test.get("base_dof")
    shear = spec["category"] in ("null_lab", "in_catalogue", "out_of_catalogue")
    if shear and not np.any(mats[3]):
        links += joints(rng, st["k"], q1, u, base)
    if nl_spec:
        q3 = simulate(lin, lab, test, u, 3.0)[1]
        s = nl_spec[0]
        links.append(family_nonlinearity(rng, s, nl_spec[1], st["k"][s - 1], q3, u, base))
    where = None
    if spec["category"] == "out_of_catalogue":
        kind, size = spec["outside"]
        n = test["storeys"]
        if kind == "sliding_mass":
            fl = int(rng.integers(1, n + 1))
            cols = simulate(lin, lab, test, u, 1.0)[0]
            a_peak = float(np.max(np.abs(cols[f"acc{fl}"])))
            *mats3, lk = sliding_mass(rng, *mats[:3], fl, size, a_peak, st["f_n"][0], st["f_n"][-1])
            mats = (*mats3, np.zeros_like(mats3[0]))
            where = {"floor": fl}
        else:
            s = int(rng.integers(1, n + 1))
            lk = (crack(s, size, st["k"][s - 1]) if kind == "breathing_crack" else
                  friction(s, size, st["k"][s - 1], q1, _velocity(q1, test), u))
            where = {"between": [s - 1, s]}
        links.append(lk)
    if sensor:
        ch = lab["chains"][sensor[1]]
        if sensor[0] == "sensor_gain":
            ch["gain"] *= 1 + sensor[2]
        else:
            ch["delay_s"] += sensor[2] * 1e-3
    return system_of(st, mats, test, links), truth_effects, where, sensor


def _velocity(q, test):
    return np.gradient(q, 1.0 / (test["fs"] * SIM_FACTOR), axis=1)


def levels_of(spec):
    """Excitation levels: 1 and 3 when the case compares levels."""
    return [1.0, 3.0] if spec.get("two_levels") else [1.0]


def write_records(folder, sysm, lab, test, t, u, levels, seed):
    """Simulate each level and write records.csv (records_level2.csv); same absolute
    noise SD at every level."""
    rng = np.random.default_rng(seed + 1)
    files, sigma = [], None
    for j, lv in enumerate(levels):
        cols = simulate(sysm, lab, test, u, lv)[0]
        rec, sigma = record(t, cols, test, lab, rng, sigma)
        name = "records.csv" if j == 0 else f"records_level{j + 1}.csv"
        write_csv(os.path.join(folder, name), rec)
        files.append(name)
    return files


def describe(spec, test, st, lab, files, base_channel, residual, prior):
    """What the recipe (`case_yaml`) may read: the test as the lab describes it."""
    n, f0, f1, lvdt = (test[k] for k in ("storeys", "f0", "f1", "lvdt_floors"))
    ground = test["excitation"] == "ground"
    text = (f"{n}-storey frame, {'shake-table' if ground else 'shaker at floor %d' % test['force_floor']} "
            f"test, {test['signal']} excitation {f0:g}-{f1:g} Hz"
            + (", repeated at 3x the level" if len(files) > 1 else "")
            + f"; accelerometers on every floor{' and the table' if ground and base_channel else ''}, "
            f"LVDTs on floor(s) {', '.join(map(str, lvdt))}; design masses and stiffnesses"
            + ("; the whole frame weighed" if ground else ""))
    weighed = float(np.sum(st["m"])) * (1 + lab["weighing_error"])
    return {"storeys": n, "excitation": test["excitation"], "force_floor": test["force_floor"],
            "route": "one_segment" if test["signal"] == "chirp" else "welch",
            "signal": test["signal"], "f0": f0, "f1": f1, "lvdt_floors": lvdt,
            "base_channel": base_channel, "level_files": files[1:],
            "nperseg": 4096 if test["fs"] == 100.0 else 8192, "prior": prior,
            "m_design": st["m_design"], "k_design": st["k_design"], "residual": residual,
            "weighed_total_mass": round(weighed, 3), "text": text}


def truth_of(spec, st, test, lab, sysm, effects, where, seed):
    """truth.json: the category, what a right answer says, the lab's imperfections, the
    real system."""
    cat = spec["category"]
    tr = {"category": cat, "acceptable_verdicts": VERDICTS[cat], "effects": effects,
          "location": where, "seed": seed, "storeys": test["storeys"],
          "excitation": test["excitation"], "force_floor": test["force_floor"],
          "signal": test["signal"], "route": "one_segment" if test["signal"] == "chirp" else "welch",
          "levels": levels_of(spec), "natural_frequencies_hz": st["f_n"],
          "design_masses": st["m_design"], "design_stiffnesses": st["k_design"], "masses": st["m"],
          "lab": lab, "links": sysm["links"],
          "system": {"M": sysm["mats"][0], "C": sysm["mats"][1], "K": sysm["mats"][2],
                     "Kh": sysm["mats"][3], "out": sysm["out"], "r": sysm["r"],
                     "force_dof": sysm["force_dof"], "base_dof": test.get("base_dof")}}
    if cat == "null_lab":
        # a calibration or timing finding names the lab, not the structure
        tr["acceptable_families"] = ["sensor_gain", "sensor_delay"]
    if cat == "out_of_catalogue":
        tr["outside_effect"] = {"kind": spec["outside"][0], "size": spec["outside"][1]}
    if cat == "non_shear":
        tr["frame"] = st["frame"]
        # non-shear behaviour must be named: frame action, or a coupling of non-adjacent
        # floors; calibration or timing findings name the lab
        tr["acceptable_families"] = ["frame_action", "nonadjacent_coupling", "sensor_gain",
                                     "sensor_delay"]
        tr["must_name_one_of"] = ["frame_action", "nonadjacent_coupling"]
        tr["design_natural_frequencies_hz"] = st["design_f_n"]
    if cat == "torsion":
        tr["torsion"] = st["torsion"]
        tr["design_natural_frequencies_hz"] = st["design_f_n"]
    if "k" in st:
        tr["stiffnesses"] = st["k"]
    return tr


def make_case(folder, spec, seed, base_channel=True, residual="log_magnitude", prior=None):
    """Simulate one case in the imperfect lab and write records, case.yaml, truth.json."""
    rng = np.random.default_rng(seed)
    st = structure(rng, spec)
    test = describe_test(rng, spec, st)
    lab = draw_lab(rng, test, st, column_names(test))
    levels = levels_of(spec)
    nonlinear = spec["category"] in ("null_lab", "in_catalogue", "out_of_catalogue")
    if nonlinear:
        test["seconds"] = 200.0
    t, u = drive(test, seed + 7)
    sysm, effects, where, _ = plant(rng, spec, st, test, lab, u)
    os.makedirs(folder, exist_ok=True)
    files = write_records(folder, sysm, lab, test, t, u, levels, seed)
    desc = describe(spec, test, st, lab, files, base_channel, residual, prior)
    y = case_yaml(os.path.basename(folder), desc)
    # what the lab's calibration certificates state of every transducer (not the draws)
    y["data"] = {"calibration": CALIBRATION[1], **y["data"]}
    with open(os.path.join(folder, "case.yaml"), "w") as fh:
        yaml.safe_dump(y, fh, sort_keys=False)
    truth = truth_of(spec, st, test, lab, sysm, effects, where, seed)
    if spec["category"] == "in_catalogue":
        truth["detectability"] = detectable_of(effects[0], st, sysm, test, y,
                                               os.path.join(folder, files[0]))
    with open(os.path.join(folder, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2, default=lambda x: np.asarray(x).tolist())


def detectable_of(effect, st, sysm, test, case, records_path):
    """Whether the records determine the planted effect (detectable.py): the Cramer-Rao
    rule for the structural families, the size rank for sensor and level effects."""
    fam = effect["family"]
    if fam == "local_damper":
        return damper_rule(effect["size"], DASHPOT_CAP)
    if fam not in FISHER_FAMILIES:
        rank = SIZES[fam].index(effect["size"])
        return {"rule": "size_rank", "rank": rank, "detectable": rank >= SIZE_DETECTABLE}
    data = np.genfromtxt(records_path, delimiter=",", names=True)
    records = {k: data[k] for k in data.dtype.names}
    system = {"out": sysm["out"], "r": sysm["r"], "force_dof": sysm["force_dof"],
              "base_dof": test.get("base_dof")}
    return detectability(fam, effect["size"], effect["parameters"], st, sysm["mats"], system,
                         test, records, case)


# ------------------------------------------------------------------ the case list
def specs(rng):
    """40 cases: 8 nulls (half at two levels), the nine families at sizes 2 and 4 (18),
    the three effects outside the families at two sizes (6), 4 flexible-beam frames
    (rho 0.5-5, log-uniform), 4 eccentric frames."""
    out = [{"category": "null_lab", "two_levels": r % 2 == 0} for r in range(8)]
    for fam in FAMILIES:
        for rank in (2, 4):
            out.append({"category": "in_catalogue", "effects": [(fam, SIZES[fam][rank])],
                        "two_levels": fam == "nonlinearity"})
    for kind in OUTSIDE:
        for size in OUTSIDE_SIZES[kind]:
            out.append({"category": "out_of_catalogue", "outside": (kind, size), "two_levels": True})
    lo, hi = np.log(RHO[0]), np.log(RHO[1])
    for r in range(4):
        out.append({"category": "non_shear", "rho": float(np.exp(lo + (hi - lo) * (r + rng.uniform()) / 4))})
    out += [{"category": "torsion"} for _ in range(4)]
    for s in out:
        s["storeys"] = int(rng.integers(3, 6))
        s["excitation"] = str(rng.choice(["ground", "force"]))
        s["signal"] = str(rng.choice(["chirp", "random"]))
    return out


def case_name(k, s):
    """Folder name of case k: number, category, and the effect."""
    what = {"in_catalogue": lambda: s["effects"][0][0], "out_of_catalogue": lambda: s["outside"][0],
            "non_shear": lambda: f"rho{s['rho']:.1f}"}.get(s["category"], lambda: "")()
    return f"{k:02d}_{s['category']}" + (f"_{what}" if what else "")
