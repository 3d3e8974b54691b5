"""An independent simulator of small shear frames for the noise-model tests.

Written without the package: the frame's state-space model is integrated by
scipy.signal.lsim at a fine step (10x the recorded rate, linear interpolation
of the input), then sampled; white noise is added to every channel, the input
included. FRFs for FRF files come from a direct solve of the dynamic stiffness.
"""

import numpy as np
from scipy import signal

from conftest import shear_K

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
