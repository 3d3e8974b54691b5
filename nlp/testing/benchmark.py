"""The concealed-effect benchmark for `frf-nlp diagnose`: its case list and one case's
simulation.

Every case is a 3- to 5-storey shear frame whose "real" structure differs from the
case file's nominal model by ordinary parameter changes (stories 0-15 % softer or
stiffer) and, in most cases, by one piece of missing physics. Tests are simulated as
noisy time histories (band-limited random ground acceleration on a shake table, or a
random force from a shaker at one floor; accelerometers with 1 % noise) and turned
into H1 FRFs by the case file itself. Floor masses are weighed (fixed); damping is
Rayleigh in the model. Truth goes to truth.json, which `diagnose` never reads;
scripts/score_benchmark.py does.

Linear responses come from the package's `nlp.frf.simulate` and the damping from
`rayleigh_from_ratios`: these cases score diagnosis, not those functions (the blind
benchmark, `nlp.testing.blind`, shares no code with the package).
"""

import json
import os

import numpy as np
import yaml
from scipy.linalg import expm

from nlp.frf.simulate import simulate
from nlp.model.damping import rayleigh_from_ratios
from nlp.model.nominal import shear_stiffness

FS = 60.0
SECONDS = 900.0
NPERSEG = 4096
FAMILIES = ("added_mass", "base_flexibility", "secondary_oscillator", "local_damper",
            "hysteretic_damping", "nonadjacent_coupling", "sensor_gain", "sensor_delay",
            "nonlinearity")


def _structure(rng, n):
    m = rng.uniform(4.0, 6.0, n)
    k = rng.uniform(2000.0, 4000.0, n)
    return m, k


def _augment(A, couple, diag):
    return np.block([[A, couple[:, None]], [couple[None, :], np.array([[diag]])]])


def true_system(m, k, zeta, family, loc, value):
    """M, C, K, Kh of the real structure (floors first, extra DOFs after)."""
    n = m.size
    M, K = np.diag(m), shear_stiffness(k)
    a0, a1 = rayleigh_from_ratios(M, K, zeta)
    C = a0 * M + a1 * K
    Kh = np.zeros((n, n))
    if family == "added_mass":
        M[loc - 1, loc - 1] += value
    elif family == "local_damper":
        i, j = loc
        e = np.zeros(n)
        e[j - 1] = 1.0
        if i:
            e[i - 1] = -1.0
        C = C + value * np.outer(e, e)
    elif family == "hysteretic_damping":
        Kh = value * (K if loc is None else shear_stiffness(k * (np.arange(n) == loc - 1)))
    elif family == "nonadjacent_coupling":
        i, j = loc
        e = np.zeros(n)
        e[i - 1], e[j - 1] = 1.0, -1.0
        K = K + value * np.outer(e, e)
    elif family == "secondary_oscillator":
        mu, fs, zs = value
        ms = mu * m.mean()
        ks, cs = ms * (2 * np.pi * fs) ** 2, 2 * zs * ms * 2 * np.pi * fs
        e = np.eye(n)[loc - 1]
        M = _augment(M, np.zeros(n), ms)
        K = _augment(K + ks * np.outer(e, e), -ks * e, ks)
        C = _augment(C + cs * np.outer(e, e), -cs * e, cs)
        Kh = _augment(Kh, np.zeros(n), 0.0)
    elif family == "base_flexibility":
        mb, kb, cb = value
        one = np.ones(n)
        M = _augment(M, np.zeros(n), mb)
        K = _augment(K, -K @ one, one @ K @ one + kb)
        # the structure's Rayleigh law covers its base, as an FE program assembles it;
        # c_b is the foundation's damping beyond it
        C = a0 * M + a1 * K
        C[n, n] += cb
        Kh = _augment(Kh, np.zeros(n), 0.0)
    return M, C, K, Kh


def _random_input(rng, seconds):
    """Unit-RMS random input band-limited to 0.3-20 Hz, at 8x the recorders' rate: the
    first-order hold of the simulation then filters the band of interest by < 0.1 %."""
    fs_sim = 8 * FS
    t = np.arange(0, seconds, 1 / fs_sim)
    spec = np.fft.rfft(rng.standard_normal(t.size))
    fr = np.fft.rfftfreq(t.size, 1 / fs_sim)
    spec[(fr < 0.3) | (fr > 20.0)] = 0
    u = np.fft.irfft(spec, t.size)
    return t, u / np.std(u)


def _records(M, C, K, Kh, n, excitation, dof, rng, level=1.0, seconds=SECONDS):
    """Simulated input and absolute floor accelerations (n, N) at the recorders' rate."""
    fs_sim = 8 * FS
    t, u = _random_input(rng, seconds)
    u = level * u
    if np.any(Kh):
        # Hysteretic damping has no causal time-domain form: filter the record in
        # the frequency domain with the exact FRF instead (periodic, long record).
        return t[::8], u[::8], _filter(M, C, K, Kh, u, fs_sim, excitation, dof, n)[:, ::8]
    if excitation == "ground":
        resp = simulate(M, C, K, u, fs_sim, input="ground")
    else:
        resp = simulate(M, C, K, u, fs_sim, input="force", dof=dof)
    return t[::8], u[::8], resp.a[:n, ::8]


def _filter(M, C, K, Kh, u, fs, excitation, dof, n):
    """Absolute floor accelerations by exact FRF filtering of the input record."""
    U = np.fft.rfft(u)
    w = 2 * np.pi * np.fft.rfftfreq(u.size, 1 / fs)
    nd = M.shape[0]
    b = -M @ np.ones(nd) if excitation == "ground" else np.eye(nd)[dof]
    A = np.empty((n, w.size), complex)
    for i, wk in enumerate(w):
        q = np.linalg.solve(K - wk**2 * M + 1j * (wk * C + Kh), b)[:n]
        A[:, i] = -(wk**2) * q + (1.0 if excitation == "ground" else 0.0)
    return np.fft.irfft(A * U, u.size)


def _simulate_cubic(M, C, K, u, fs, excitation, dof, story, k3):
    """Frame with a cubic spring k3 * drift^3 in one story: exact ZOH for the linear part,
    the nonlinear force held over each (8x oversampled) step."""
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    b = -M @ np.ones(n) if excitation == "ground" else np.eye(n)[dof]
    g = np.zeros(n)
    g[story - 1] = 1.0
    if story > 1:
        g[story - 2] = -1.0
    dt = 1 / fs
    Phi = expm(A * dt)
    Gam = np.linalg.solve(A, Phi - np.eye(2 * n))
    Gu = Gam @ np.concatenate([np.zeros(n), Minv @ b])
    Gn = Gam @ np.concatenate([np.zeros(n), -Minv @ g])
    x = np.zeros(2 * n)
    acc = np.empty((n, u.size))
    for k in range(u.size):
        q, v = x[:n], x[n:]
        f = k3 * (g @ q) ** 3
        acc[:, k] = Minv @ (b * u[k] - C @ v - K @ q - g * f)
        x = Phi @ x + Gu * u[k] + Gn * f
    if excitation == "ground":
        acc += u
    return acc


def _nonlinear_records(M, C, K, n, excitation, dof, rng, story, stiffening, seconds):
    """Records at a low and a high level; k3 makes the story stiffer by `stiffening`
    (equivalent linearisation, 3 k3 E[drift^2]) at the high level."""
    fs_sim = 8 * FS
    t, u = _random_input(rng, seconds)
    lin = simulate(M, C, K, 3.0 * u, fs_sim, input=excitation, dof=None if excitation == "ground" else dof)
    drift = lin.q[story - 1] - (lin.q[story - 2] if story > 1 else 0.0)
    k_story = K[story - 1, story - 1] if story == n else -K[story - 1, story]
    k3 = stiffening * k_story / (3 * np.var(drift))
    out = []
    for level in (1.0, 3.0):
        acc = _simulate_cubic(M, C, K, level * u, fs_sim, excitation, dof, story, k3)
        out.append((t[::8], level * u[::8], acc[:n, ::8]))
    return out, k3


def _noisy(t, u, acc, n, family, loc, value, rng, noise=0.01):
    """Recorded columns: 1 % sensor noise, and the sensor families' distortions."""
    cols = {"t": t, "input": u + noise * np.std(u) * rng.standard_normal(t.size)}
    for i in range(n):
        cols[f"a{i + 1}"] = acc[i] + noise * np.std(acc[i]) * rng.standard_normal(t.size)
    if family == "sensor_gain":
        cols[f"a{loc}"] = cols[f"a{loc}"] * (1 + value)
    if family == "sensor_delay":
        cols[f"a{loc}"] = np.interp(t - value * 1e-3, t, cols[f"a{loc}"])
    return cols


def _write_records(path, cols):
    names = list(cols)
    np.savetxt(path, np.column_stack([cols[c] for c in names]), delimiter=",",
               header=",".join(names), comments="", fmt=["%.5f"] + ["%.6e"] * (len(names) - 1))


def make_case(folder, spec, seed):
    """Write case.yaml, records.csv and truth.json for one benchmark case."""
    rng = np.random.default_rng(seed)
    n = spec["storeys"]
    m, k = _structure(rng, n)
    zeta = rng.uniform(0.01, 0.02)
    family, loc, value = spec.get("family"), spec.get("location"), spec.get("value")
    excitation = spec["excitation"]
    dof = spec.get("shaker_floor", 1) - 1
    M, C, K, Kh = true_system(m, k, zeta, family, loc, value)
    k_nominal = k * (1 + rng.uniform(-0.15, 0.15, n)) if spec.get("ordinary", True) else k
    levels = spec.get("levels", 1)
    if family == "nonlinearity":
        recs, k3 = _nonlinear_records(M, C, K, n, excitation, dof, rng, loc, value,
                                      spec.get("seconds", SECONDS))
    else:
        recs = [_records(M, C, K, Kh, n, excitation, dof, rng, level=lv,
                         seconds=spec.get("seconds", SECONDS)) for lv in (1.0, 3.0)[:levels]]
    os.makedirs(folder, exist_ok=True)
    files = []
    for j, (t, u, acc) in enumerate(recs):
        cols = _noisy(t, u, acc, n, family, loc, value, rng)
        name = "records.csv" if j == 0 else f"records_level{j + 1}.csv"
        _write_records(os.path.join(folder, name), cols)
        files.append(name)
    inp = ({"column": "input", "quantity": "ground_acceleration", "unit": "m/s^2"}
           if excitation == "ground" else
           {"column": "input", "quantity": "force", "unit": "N", "floor": dof + 1})
    case = {
        "name": os.path.basename(folder),
        "model": {"type": "shear_frame", "masses": [round(float(x), 4) for x in m],
                  "stiffnesses": [round(float(x), 2) for x in k_nominal]},
        "parameters": {"fixed": {f"m{i + 1}": round(float(m[i]), 4) for i in range(n)},
                       "stiffness_bounds": [-0.5, 1.0]},
        "damping": {"model": "rayleigh", "zeta": 0.015},
        "data": {"type": "time_histories", "file": "records.csv", "input": inp,
                 **({"level_files": files[1:]} if len(files) > 1 else {}),
                 "estimator": "H1", "nperseg": NPERSEG, "overlap": 0.5, "window": "hann",
                 "channels": [{"name": f"a{i + 1}", "floor": i + 1, "quantity": "acceleration",
                               "unit": "m/s^2", "column": f"a{i + 1}"} for i in range(n)]},
        "frequencies": {"method": "half_power", "k": 2.0, "fmin": 0.4, "fmax": 15.0,
                        "min_coherence": 0.5},
        "objective": {"residual": "complex" if family == "sensor_delay" else "log_magnitude"},
        "search": {"starts": 8, "seed": 0, "workers": 1},
    }
    with open(os.path.join(folder, "case.yaml"), "w") as fh:
        yaml.safe_dump(case, fh, sort_keys=False)
    truth = {"family": family, "location": _location(family, loc), "value": value,
             "excitation": excitation, "storeys": n, "masses": m.tolist(),
             "stiffnesses": k.tolist(), "nominal_stiffnesses": k_nominal.tolist(),
             "rayleigh_zeta": zeta, "seed": seed}
    with open(os.path.join(folder, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2, default=float)


def _location(family, loc):
    if family is None or family in ("base_flexibility",):
        return {}
    if family == "hysteretic_damping":
        return {} if loc is None else {"between": [loc - 1, loc]}
    if family in ("local_damper", "nonadjacent_coupling"):
        return {"between": list(loc)}
    if family in ("sensor_gain", "sensor_delay"):
        return {"channel": f"a{loc}"}
    if family == "nonlinearity":
        return {"between": [loc - 1, loc]}
    return {"floor": loc}


def specs(rng, per_family=2):
    """The benchmark's case list: effect cases per family, null and ordinary cases."""
    out = []
    for fam in FAMILIES:
        for r in range(per_family):
            n = int(rng.integers(3, 6))
            ex = ("ground", "force")[r % 2]
            s = {"storeys": n, "excitation": ex, "family": fam, "shaker_floor": 1}
            i = int(rng.integers(1, n + 1))
            if fam == "added_mass":
                s.update(location=i, value=float(rng.uniform(0.2, 0.35)) * 5.0)
            elif fam == "base_flexibility":
                s.update(location=None, value=[2.5, float(rng.uniform(3, 6)) * 3000.0, 2.0])
            elif fam == "secondary_oscillator":
                s.update(location=i, value=[0.04, float(rng.uniform(2.0, 6.0)), 0.02])
            elif fam == "local_damper":
                s.update(location=(i - 1, i), value=float(rng.uniform(8.0, 15.0)))
            elif fam == "hysteretic_damping":
                s.update(location=None, value=float(rng.uniform(0.03, 0.05)))
            elif fam == "nonadjacent_coupling":
                i = int(rng.integers(1, n - 1))
                s.update(location=(i, i + 2), value=float(rng.uniform(0.25, 0.4)) * 3000.0)
            elif fam == "sensor_gain":
                s.update(location=i, value=float(rng.choice([-0.25, 0.3])))
            elif fam == "sensor_delay":
                s.update(location=i, value=float(rng.uniform(20.0, 40.0)))
            elif fam == "nonlinearity":
                s.update(location=i, value=float(rng.uniform(0.06, 0.1)), levels=2)
            out.append(s)
    for r in range(per_family * 2):
        n = int(rng.integers(3, 6))
        out.append({"storeys": n, "excitation": ("ground", "force")[r % 2], "family": None,
                    "ordinary": r % 2 == 0, "levels": 2 if r < 2 else 1})
    return out
