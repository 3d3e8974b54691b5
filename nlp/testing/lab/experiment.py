"""One test in the imperfect lab: the table or shaker coupled to the structure, the
simulation (linear, hysteretic or with nonlinear links), and the channels' chains,
decimation, coloured common-mode noise and units."""

import numpy as np

from nlp.testing.blind.experiment import G, SIM_FACTOR
from nlp.testing.blind.simulators import freq_domain, newmark
from nlp.testing.lab.chain import apply_chain
from nlp.testing.lab.effects import newmark_links
from nlp.testing.lab.noise import lab_noise
from nlp.testing.lab.table import cell_force, command_force, with_shaker, with_table


def coupled_system(sysm, lab, test):
    """The structure with the table (shake-table test: last DOF is the table) or the
    shaker (force test) attached; returns M, C, K, Kh and the load vector b."""
    M, C, K, Kh = sysm["mats"]
    if test["excitation"] == "ground":
        tb = lab["table"]
        Ma, Ca, Ka, Kha = with_table(M, C, K, Kh, sysm["r"], tb["m_t"], tb["k_a"], tb["c_a"])
        b = np.zeros(Ma.shape[0])
        b[-1] = 1.0
        return Ma, Ca, Ka, Kha, b
    dof = sysm["force_dof"]
    M, C, K = with_shaker(M, C, K, dof, lab["shaker"])
    return M, C, K, Kh, np.eye(M.shape[0])[dof]


def drive_input(u, test, lab, level):
    """The load signal: the servo's force for the commanded table acceleration, or the
    shaker's coil force."""
    fs = test["fs"] * SIM_FACTOR
    x = level * test["amplitude"] * u
    if test["excitation"] == "ground":
        tb = lab["table"]
        return command_force(x, fs, 0.5 * test["f0"], tb["k_a"], tb["c_a"])
    return x


def simulate(sysm, lab, test, u, level=1.0):
    """Physical signals at the simulation rate (SI): input (table acceleration or cell
    force), base_acc, acc1..n (absolute x-acceleration at each floor sensor), lvdt floors
    (relative to the table), and the drift of every DOF for calibration (q)."""
    M, C, K, Kh, b = coupled_system(sysm, lab, test)
    h = 1.0 / (test["fs"] * SIM_FACTOR)
    F = drive_input(u, test, lab, level)
    if sysm.get("links"):
        q, v, a = newmark_links(M, C, K, b, F, h, sysm["links"])
    elif np.any(Kh):
        q, v, a = freq_domain(M, C, K, Kh, b, F, h)
    else:
        q, v, a = newmark(M, C, K, b, F, h)
    out = sysm["out"]
    ground = test["excitation"] == "ground"
    n_s = out.shape[1]
    if ground:
        a_t = a[-1]
        cols = {"input": a_t, "base_acc": a_t + (a[test["base_dof"]] if test.get("base_dof") else 0.0)}
        rel_q, rel_a = q[:n_s], a[:n_s]
    else:
        cols = {"input": cell_force(F, q, v, a, sysm["force_dof"], lab["shaker"])}
        rel_q, rel_a = q, a
        a_t = 0.0
    acc = out @ rel_a + a_t
    disp = out @ rel_q
    for i in range(out.shape[0]):
        cols[f"acc{i + 1}"] = acc[i]
    for i in test["lvdt_floors"]:
        cols[f"lvdt{i}"] = disp[i - 1]
    return cols, q


def record(t, cols, test, lab, rng, sigma=None):
    """Each channel through its own chain, decimated, with coloured common-mode noise
    (sigma: absolute noise SD per channel [SI]; None: from this record's RMS and the
    drawn shares, returned for the other levels), then in the records' units."""
    fs_sim = test["fs"] * SIM_FACTOR
    rec = {name: apply_chain(x, lab["chains"][name], fs_sim)[::SIM_FACTOR] for name, x in cols.items()}
    if sigma is None:
        sigma = {k: lab["noise"]["level"][k] * float(np.std(y)) for k, y in rec.items()}
    nz = lab["noise"]
    noise = lab_noise(rng, list(rec), t[::SIM_FACTOR].size, test["fs"], sigma, nz["common"], nz["pink"])
    out = {"t": t[::SIM_FACTOR]}
    ground = test["excitation"] == "ground"
    for name, y in rec.items():
        y = y + noise[name]
        if name in ("input", "base_acc") and ground or name.startswith("acc"):
            y = y / G
        elif name.startswith("lvdt"):
            y = y * 1e3
        out[name] = y
    return out, sigma
