"""Locating a nonlinear element from the response outside the excitation band
(nlp/diagnosis/harmonics.py), on records simulated here with scipy's solve_ivp: a
3-storey shear frame driven by a 1-15 Hz force chirp at floor 1, with and without a
cubic spring across one story."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import chirp

from support.frames import shear_K, story_link
from nlp.diagnosis.harmonics import force_frfs, harmonic_location, story_vectors
from nlp.diagnosis.priors import story_patterns
from nlp.solve.problem import Channel
from nlp.io.readers import TimeHistories

FS, T = 100.0, 30.0
m = np.array([4.0, 3.0, 3.5])
k = np.array([6000.0, 5000.0, 4000.0])


M, K = np.diag(m), shear_K(k)
C = 0.2 * M + 1e-3 * K


def _records(story, k3, noise, seed):
    """Absolute floor accelerations [m/s^2] for a force u(t) [N] at floor 1 and a cubic
    spring k3 * drift^3 across `story` (1-based; None: linear), plus noise of `noise`
    times each record's RMS on every channel, the input included."""
    t = np.arange(0, T, 1 / FS)
    env = np.clip(t / 2, 0, 1) * np.clip((T - 8 - t) / 2, 0, 1)

    def u(tt):
        e = np.clip(tt / 2, 0, 1) * np.clip((T - 8 - tt) / 2, 0, 1)
        return 20.0 * e * chirp(tt, 1.0, T - 8, 15.0)

    Minv = np.linalg.inv(M)

    def rhs(tt, s):
        x, v = s[:3], s[3:]
        f = np.zeros(3)
        f[0] = u(tt)
        story_link(f, x, story, lambda d: k3 * d ** 3)
        return np.r_[v, Minv @ (f - C @ v - K @ x)]

    sol = solve_ivp(rhs, (0, T), np.zeros(6), t_eval=t, rtol=1e-8, atol=1e-11, max_step=0.01)
    acc = np.array([rhs(tt, s)[3:] for tt, s in zip(sol.t, sol.y.T)]).T
    rng = np.random.default_rng(seed)
    x = u(t) * (env > -1)
    data = {"__input__": x + noise * x.std() * rng.standard_normal(t.size)}
    for j in range(3):
        data[f"a{j + 1}"] = acc[j] + noise * acc[j].std() * rng.standard_normal(t.size)
    return TimeHistories(t=t, fs=FS, data=data)


CHANNELS = [Channel(f"a{j + 1}", j, "accelerance") for j in range(3)]


def _H_model(w):
    """Accelerance of each floor to a force at floor 1 of the linear frame."""
    return np.array([-(wi ** 2) * np.linalg.solve(K - wi ** 2 * M + 1j * wi * C, np.eye(3)[:, 0])
                     for wi in w]).T


def test_force_frfs_of_a_story_pattern_by_hand():
    """The output per unit force with pattern b is the receptance matrix times b:
    on one DOF, 1 / (k - m w^2 + j c w); mobility and accelerance multiply by j w, -w^2."""
    M1, K1, C1 = np.array([[2.0]]), np.array([[800.0]]), np.array([[3.0]])
    w = np.array([5.0, 20.0, 31.0])
    chans = [Channel("x", 0, "receptance"), Channel("v", 0, "mobility"),
             Channel("a", 0, "accelerance")]
    G = force_frfs(M1, C1, K1, w, np.ones((1, 1)), chans)[:, :, 0]
    X = 1.0 / (800.0 - 2.0 * w ** 2 + 3j * w)
    np.testing.assert_allclose(G[:, 0], X, rtol=1e-12)
    np.testing.assert_allclose(G[:, 1], 1j * w * X, rtol=1e-12)
    np.testing.assert_allclose(G[:, 2], -w ** 2 * X, rtol=1e-12)
    # story vectors of shear-frame stiffness groups are their drift patterns (up to sign)
    bs = story_vectors(story_patterns(3))
    assert np.allclose(np.abs(bs[1]), np.array([1, 1, 0]) / np.sqrt(2))


@pytest.mark.parametrize("story", [1, 2, 3])
def test_cubic_spring_located_by_its_harmonics(story):
    """The harmonics of a cubic spring above the 15 Hz band are one force across its story:
    that story explains nearly all the out-of-band power, the others far less."""
    rec = _records(story, 3e6, 0.01, seed=story)
    B = np.column_stack(story_vectors(story_patterns(3)))
    out = harmonic_location([{"records": rec, "H_model": _H_model, "nperseg": "all",
                              "window": "boxcar"}], M, C, K, B, CHANNELS, 15.0)
    assert out["z_excess"] > 10
    assert out["best"] == story - 1
    assert out["share"][story - 1] > 0.8
    assert max(s for j, s in enumerate(out["share"]) if j != story - 1) < 0.6


def test_linear_frame_has_no_out_of_band_response():
    """Without the cubic spring the out-of-band records are noise: nothing is located."""
    rec = _records(None, 0.0, 0.01, seed=7)
    B = np.column_stack(story_vectors(story_patterns(3)))
    out = harmonic_location([{"records": rec, "H_model": _H_model, "nperseg": "all",
                              "window": "boxcar"}], M, C, K, B, CHANNELS, 15.0)
    assert abs(out["z_excess"]) < 5
    assert out["best"] is None
