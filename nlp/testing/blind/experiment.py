"""One test of the blind benchmark: drive signals, the simulated test, and the sensors
(anti-alias filter, decimation, noise, units) that record it."""

import numpy as np
from scipy import signal

from nlp.testing.blind.simulators import freq_domain, newmark, nonlinear_ivp

# standard gravity [m/s^2]; a copy of nlp.io.readers.G kept on purpose: the records'
# units are written without the package
G = 9.80665
SIM_FACTOR = 20            # simulation rate / recording rate


def chirp(rng, f0, f1, fs, n_floor_f1, zeta):
    """Linear sweep f0 -> f1 with 2-s cosine ramps, then a quiet tail long enough for
    the response to decay by > 60 dB: the record starts and ends at rest."""
    sweep = float(rng.uniform(60.0, 120.0))
    tail = min(max(7.0 / (2 * np.pi * zeta * n_floor_f1), 10.0), 90.0)
    t = np.arange(0, sweep + tail, 1 / fs)
    u = signal.chirp(t, f0, sweep, f1, method="linear")
    env = np.clip(t / 2.0, 0, 1) * np.clip((sweep - t) / 2.0, 0, 1)
    env = 0.5 - 0.5 * np.cos(np.pi * env)
    return t, u * env


def random_band(rng, f0, f1, fs, seconds):
    """Band-limited (f0-f1) Gaussian noise of unit RMS."""
    t = np.arange(0, seconds, 1 / fs)
    spec = np.fft.rfft(rng.standard_normal(t.size))
    fr = np.fft.rfftfreq(t.size, 1 / fs)
    spec[(fr < f0) | (fr > f1)] = 0
    u = np.fft.irfft(spec, t.size)
    return t, u / np.std(u)


def drive(test, seed):
    """The test's drive signal at the simulation rate (the same at every level)."""
    rng = np.random.default_rng(seed)
    fs = test["fs"] * SIM_FACTOR
    if test["signal"] == "chirp":
        return chirp(rng, test["f0"], test["f1"], fs, test["f_first"], test["zeta"])
    return random_band(rng, test["f0"], test["f1"], fs, test["seconds"])


def load_vector(M, test):
    """b of M q'' + C q' + K q = b u: the table's inertia load or a unit force at the shaker's floor."""
    if test["excitation"] == "ground":
        return -M @ np.ones(M.shape[0])
    return np.eye(M.shape[0])[test["force_floor"] - 1]


def run_test(system, test, t, u, level=1.0, nonlin=None):
    """Simulate one test; returns recorded columns (SI before units) at the simulation rate.

    Ground input: coordinates are relative to the table; absolute acceleration =
    relative + table acceleration. Force input: absolute coordinates.
    """
    M, C, K, Kh = system
    n_all = M.shape[0]
    h = 1.0 / (test["fs"] * SIM_FACTOR)
    u = level * test["amplitude"] * u
    b = load_vector(M, test)
    if nonlin is not None:
        q, v, a = nonlinear_ivp(M, C, K, b, u, h, **nonlin)
    elif np.any(Kh):
        q, v, a = freq_domain(M, C, K, Kh, b, u, h)
    else:
        q, v, a = newmark(M, C, K, b, u, h)
    n = test["storeys"]
    ground = test["excitation"] == "ground"
    cols = {"input": u}
    if ground:
        # the base accelerometer sits on the table, or on the base mass when the base is flexible
        cols["base_acc"] = u + (a[test["base_dof"]] if test.get("base_dof") else 0.0)
    for i in range(n):
        cols[f"acc{i + 1}"] = a[i] + (u if ground else 0.0)
    for i in test["lvdt_floors"]:
        cols[f"lvdt{i}"] = q[i - 1]
    return cols


def record(t, cols, test, rng, sensor=None):
    """Sensor effects at the simulation rate, anti-alias filter, decimation, noise, units."""
    fs = test["fs"]
    cols = dict(cols)
    if sensor and sensor[0] == "sensor_delay":
        name, tau = sensor[1], sensor[2] * 1e-3
        cols[name] = np.interp(t - tau, t, cols[name], left=0.0)
    if sensor and sensor[0] == "sensor_gain":
        cols[sensor[1]] = cols[sensor[1]] * (1 + sensor[2])
    sos = signal.butter(8, 0.4 * fs, fs=fs * SIM_FACTOR, output="sos")
    out = {"t": t[::SIM_FACTOR]}
    for name, x in cols.items():
        y = signal.sosfilt(sos, x)[::SIM_FACTOR]
        y = y + test["noise"] * np.std(y) * rng.standard_normal(y.size)
        if name in ("input", "base_acc") and test["excitation"] == "ground" or name.startswith("acc"):
            y = y / G                                   # accelerometers record in g
        elif name.startswith("lvdt"):
            y = y * 1e3                                 # mm
        out[name] = y
    return out


def write_csv(path, cols):
    """Recorded columns as CSV with a header line (time first)."""
    names = list(cols)
    np.savetxt(path, np.column_stack([cols[c] for c in names]), delimiter=",",
               header=",".join(names), comments="", fmt=["%.5f"] + ["%.7e"] * (len(names) - 1))
