"""An independent simulator of small shear frames for the noise-model tests and
research/check_noise.py.

The data are simulated without the package: the frame's state-space model is
integrated by scipy.signal.lsim at a fine step (10x the recorded rate, linear
interpolation of the input), then sampled; white noise is added to every channel,
the input included. FRFs for FRF files come from a direct solve of the dynamic
stiffness. Only `reduced_chi2`, the check itself, fits a case with the package.
"""

import math
import os
from dataclasses import replace

import numpy as np
import yaml
from scipy import signal

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.frf import noise
from nlp.solve.search import SearchConfig, scatter_search
from nlp.testing.frames import shear_K

MASSES = np.array([5.0, 4.5, 4.0])
STIFF = np.array([4000.0, 3200.0, 2600.0])


def damping(M, K, zeta=0.02):
    """Rayleigh C with ratio zeta at modes 1 and n, plus a dashpot on story 2
    (non-proportional, still inside the general-damping model class)."""
    w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    a0, a1 = np.linalg.solve([[1 / (2 * w[0]), w[0] / 2], [1 / (2 * w[-1]), w[-1] / 2]],
                             [zeta, zeta])
    C = a0 * M + a1 * K
    C[0, 0] += 1.0
    C[1, 1] += 1.0
    C[0, 1] -= 1.0
    C[1, 0] -= 1.0
    return C


def frame(masses=MASSES, stiff=STIFF):
    """M, C, K of the 3-storey null frame (masses [kg], story stiffnesses [N/m])."""
    M = np.diag(masses)
    K = shear_K(stiff)
    return M, damping(M, K), K


def _state_space(M, C, K, ground):
    """x = [q, dq] (q relative to the ground); outputs: absolute accelerations
    (-M^-1 (K q + C dq): the ground acceleration cancels in q'' + ag)."""
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    B = np.concatenate([np.zeros(n), -np.ones(n)]) if ground else \
        np.concatenate([np.zeros(n), Mi[:, 0]])
    Cq = np.hstack([-Mi @ K, -Mi @ C])
    D = np.zeros(n) if ground else Mi[:, 0]
    return A, B[:, None], Cq, D[:, None]


def simulate(x_fine, fs_fine, M, C, K, ground=True, decim=10):
    """Absolute accelerations of every floor for the input x_fine (ground
    acceleration [m/s^2] or force at floor 1 [N]) sampled at fs_fine; returns the
    input and outputs sampled every decim-th fine step."""
    A, B, Cq, D = _state_space(M, C, K, ground)
    t = np.arange(x_fine.size) / fs_fine
    _, y, _ = signal.lsim((A, B, Cq, D), x_fine, t)
    y = np.atleast_2d(y.T)
    return x_fine[::decim], y[:, ::decim]


def add_noise(x, y, level, rng):
    """White noise of `level` x the RMS of each record (input and outputs)."""
    xn = x + level * np.std(x) * rng.standard_normal(x.size)
    yn = y + level * np.std(y, axis=1, keepdims=True) * rng.standard_normal(y.shape)
    return xn, yn


def chirp_input(fs_fine, f0, f1, sweep_s, pre_s, post_s):
    """A linear chirp of sweep_s seconds between rest portions (starts and ends at rest)."""
    t = np.arange(int(round(sweep_s * fs_fine))) / fs_fine
    s = signal.chirp(t, f0, sweep_s, f1) * signal.windows.tukey(t.size, 0.02)
    return np.concatenate([np.zeros(int(pre_s * fs_fine)), s, np.zeros(int(post_s * fs_fine))])


def random_input(fs_fine, f_hi, seconds, rng):
    """Band-limited Gaussian noise (0 to f_hi Hz, zero-phase Butterworth)."""
    w = rng.standard_normal(int(seconds * fs_fine))
    sos = signal.butter(6, f_hi, fs=fs_fine, output="sos")
    return signal.sosfiltfilt(sos, w)


def frf_exact(M, C, K, f, ground=True):
    """Absolute accelerances (ground input) or accelerances (force at floor 1), (n, n_f)."""
    n = M.shape[0]
    out = np.empty((n, f.size), complex)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        Z = K - w**2 * M + 1j * w * C
        b = -M @ np.ones(n) if ground else np.eye(n)[0]
        out[:, k] = -w**2 * np.linalg.solve(Z, b) + (1.0 if ground else 0.0)
    return out


def write_records(path, fs, x, y, names):
    """CSV with a time column, the input 'ag' and one column per channel."""
    t = np.arange(x.size) / fs
    header = ",".join(["t", "ag"] + list(names))
    np.savetxt(path, np.column_stack([t, x, y.T]), delimiter=",", header=header, comments="")


# ------------------------------------------------------------------ null cases
FS_FINE, DECIM = 1000.0, 10
ROUTES = ("transient", "welch", "frf_scatter", "frf_coherence", "frf_welch", "frf_welch_bare")


def case_yaml(folder, data, frequencies=None):
    """A shear-frame case whose nominal values are 8-15 % off the truth; m1 weighed."""
    case = {"name": "null", "model": {"type": "shear_frame", "masses": [5.0, 5.0, 4.5],
                                      "stiffnesses": [3500.0, 3600.0, 2300.0]},
            "parameters": {"fixed": {"m1": float(MASSES[0])}},
            "damping": {"model": "general", "zeta": 0.02},
            "data": data, "frequencies": {"method": "half_power", "k": 2.0, **(frequencies or {})},
            "search": {"starts": 8, "seed": 0, "workers": 1}}
    path = os.path.join(str(folder), "case.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(case, fh)
    return path


def records_case(folder, x, y, extra, frequencies=None):
    """Write the records rec.csv (input ag, channels a1-a3) and their case file; returns its path."""
    names = ["a1", "a2", "a3"]
    write_records(os.path.join(str(folder), "rec.csv"), FS_FINE / DECIM, x, y, names)
    data = {"type": "time_histories", "file": "rec.csv",
            "input": {"column": "ag", "quantity": "ground_acceleration"},
            "channels": [{"name": nm, "floor": i + 1, "quantity": "acceleration", "column": nm}
                         for i, nm in enumerate(names)], **extra}
    return case_yaml(folder, data, frequencies)


def _cgauss(rng, *shape):
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / math.sqrt(2)


def null_case(route, folder, seed, frequencies=None):
    """Write a null case (physics inside the model class) for one FRF route; returns its path.

    transient: one-segment 0.5-20 Hz chirp between rest portions, 2 % noise on input
    and outputs; welch: 300 s of band-limited random input, nperseg 4096; frf_scatter:
    FRF file with 1-4 % relative complex noise; frf_coherence: .npz H1 of 30 averages
    with its coherence and n_averages, simulated per bin; frf_welch: the Welch route's
    records stored as an analyzer would, H1 (Hann, 4096 samples, half overlap) with its
    coherence and number of averages, window left at its default; frf_welch_bare: the
    same analyzer's average stored without its coherence and averages.
    """
    rng = np.random.default_rng(seed)
    M, C, K = frame()
    if route in ("frf_welch", "frf_welch_bare"):
        x, y = add_noise(*simulate(random_input(FS_FINE, 20.0, 300, rng), FS_FINE, M, C, K,
                                   decim=DECIM), 0.02, rng)
        fs = FS_FINE / DECIM
        f, s_xx = signal.welch(x, fs, nperseg=4096)
        _, s_xy = signal.csd(x[None], y, fs, nperseg=4096)
        _, s_yy = signal.welch(y, fs, nperseg=4096)
        keep = (f >= 0.5) & (f <= 12.0)
        stated = {} if route == "frf_welch_bare" else dict(
            coherence=(np.abs(s_xy) ** 2 / (s_xx * s_yy))[:, keep],
            n_averages=(x.size - 4096) // 2048 + 1)
        np.savez(os.path.join(str(folder), "frf.npz"), f=f[keep], H=(s_xy / s_xx)[:, keep],
                 **stated)
        chans = [{"name": f"a{i + 1}", "floor": i + 1, "output": "absolute_accelerance",
                  "column": i} for i in range(3)]
        return case_yaml(folder, {"file": "frf.npz", "channels": chans}, frequencies)
    if route in ("transient", "welch"):
        u = chirp_input(FS_FINE, 0.5, 20.0, 60, 5, 20) if route == "transient" else \
            random_input(FS_FINE, 20.0, 300, rng)
        x, y = add_noise(*simulate(u, FS_FINE, M, C, K, decim=DECIM), 0.02, rng)
        return records_case(folder, x, y, {"nperseg": "all" if route == "transient" else 4096},
                        frequencies)
    f = np.arange(0.5, 12.0, 0.01)
    H = frf_exact(M, C, K, f)
    chans = [{"name": f"a{i + 1}", "floor": i + 1, "output": "absolute_accelerance", "column": i}
             for i in range(3)]
    if route == "frf_scatter":
        rel = 0.01 * (1 + 3 * f / f[-1])
        H = H * (1 + rel * _cgauss(rng, *H.shape))
        with open(os.path.join(str(folder), "frf.csv"), "w") as fh:
            fh.write("".join(f"{fk:.6f}," + ",".join(repr(complex(h)).strip("()") for h in col)
                             + "\n" for fk, col in zip(f, H.T)))
        # simulated per bin in the frequency domain: no window, no resolution bias
        return case_yaml(folder, {"file": "frf.csv", "format": "complex", "channels": chans,
                                  "window": "none"}, frequencies)
    n_avg = 30
    U = _cgauss(rng, n_avg, f.size)
    X = U + 0.05 * _cgauss(rng, n_avg, f.size)
    Y = H[None] * U[:, None] + 0.3 * np.abs(H).mean(axis=1)[None, :, None] * \
        _cgauss(rng, n_avg, 3, f.size)
    s_xx = np.mean(np.abs(X) ** 2, axis=0)
    s_xy = np.mean(np.conj(X)[:, None] * Y, axis=0)
    s_yy = np.mean(np.abs(Y) ** 2, axis=0)
    np.savez(os.path.join(str(folder), "frf.npz"), f=f, H=s_xy / s_xx,
             coherence=np.abs(s_xy) ** 2 / (s_xx * s_yy), n_averages=n_avg)
    return case_yaml(folder, {"file": "frf.npz", "channels": chans, "window": "none"}, frequencies)


def reduced_chi2(path, starts=8):
    """Baseline fit weighted by the package's noise model: chi-square / degrees of
    freedom, the noise model and the case."""
    case = assemble(load_case(path))
    sig = noise.sigma_ln(case, case.selected)
    case = replace(case, target=replace(case.target, weight=1.0 / sig))
    pr = build_problem(case)
    best = scatter_search(pr, SearchConfig(starts=starts, seed=0), progress=None).best
    return 2 * best.f / (pr.n_used - pr.params.n_z), case.noise, case
