"""A story stiffer one way than the other (nlp/diagnosis/asymmetry.py), on records simulated
here with scipy's solve_ivp: a 3-storey shear frame on a table driven by band-limited Gaussian
ground acceleration, with a bilinear (breathing crack) story, a symmetric cubic story or none.
The model given to the test is the statistical linearisation of the real frame: a bilinear
story k closed and (1 - delta) k open has the best linear stiffness k (1 - delta / 2) for any
symmetric drift (its force's odd part), and its even part (delta k / 2) |d| is what the test
estimates."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt

from support.frames import shear_K, story_link
from nlp.diagnosis.asymmetry import asymmetry, bilinear_delta, model_drifts
from nlp.diagnosis.harmonics import story_vectors
from nlp.diagnosis.priors import story_patterns
from nlp.io.readers import TimeHistories
from nlp.solve.problem import Channel

FS, T = 100.0, 60.0
m = np.array([4.0, 3.0, 3.5])
k = np.array([6000.0, 5000.0, 4000.0])
M = np.diag(m)
C0 = 0.25 * M + 4e-4 * shear_K(k)
CHANNELS = [Channel(f"a{j + 1}", j, "absolute_accelerance") for j in range(3)]


def _ground(seed):
    """Band-limited (0.5-20 Hz) Gaussian ground acceleration [m/s^2], tapered at both ends."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, T, 1 / FS)
    a = sosfiltfilt(butter(4, [0.5, 20.0], "bandpass", fs=FS, output="sos"),
                    rng.standard_normal(t.size))
    a *= np.clip(t / 2, 0, 1) * np.clip((T - 20 - t) / 2, 0, 1)   # 20 s to ring down
    return t, 2.0 * a / a.std()


def _records(story, kind, size, noise=0.005, seed=0):
    """Absolute floor accelerations of the real frame on the table: a bilinear story
    (k when the drift d >= 0, (1 - size) k when open) or a cubic one (size * k / d_ref^2 d^3)."""
    t, ag = _ground(seed)
    Kl = shear_K(k)
    Minv = np.linalg.inv(M)
    ground = CubicSpline(t, ag)   # near band-limited between samples, as the FFT assumes

    def link(d):
        if kind == "crack":
            return -size * k[story - 1] * min(d, 0.0)
        if kind == "cubic":
            return size * k[story - 1] * d ** 3 / 1e-4
        return 0.0

    def rhs(tt, s):
        x, v = s[:3], s[3:]
        f = story_link(-M @ np.ones(3) * ground(tt), x, story, link)
        return np.r_[v, Minv @ (f - C0 @ v - Kl @ x)]

    sol = solve_ivp(rhs, (0, T), np.zeros(6), t_eval=t, rtol=1e-7, atol=1e-10, max_step=0.01)
    rel = np.array([rhs(tt, s)[3:] for tt, s in zip(sol.t, sol.y.T)]).T
    rng = np.random.default_rng(seed + 100)
    data = {"__input__": ag + noise * ag.std() * rng.standard_normal(t.size)}
    for j in range(3):
        a = rel[j] + ag
        data[f"a{j + 1}"] = a + noise * a.std() * rng.standard_normal(t.size)
    return TimeHistories(t=t, fs=FS, data=data), sol.y[:3]


def _model(story=None, delta=0.0):
    """The linear model: the bilinear story at its statistical linearisation."""
    ke = k.copy()
    if story is not None:
        ke[story - 1] *= 1 - delta / 2
    return shear_K(ke)


def _H(K):
    def H(w):
        return np.array([1 - wi ** 2 * np.linalg.solve(K - wi ** 2 * M + 1j * wi * C0,
                                                       -M @ np.ones(3)) for wi in w]).T
    return H


def _run(rec, K):
    B = np.column_stack(story_vectors(story_patterns(3)))
    return asymmetry([{"records": rec, "H_model": _H(K)}], M, C0, K, B, CHANNELS,
                     ("ground", None, None), 1.0)


def test_model_drifts_match_the_simulated_linear_drifts():
    """On the linear frame the drifts from the input record by FFT are the integrated ones
    (the record starts and ends at rest, so the periodic FFT is exact to the taper)."""
    rec, x = _records(None, None, 0.0, noise=0.0, seed=3)
    B = np.column_stack(story_vectors(story_patterns(3)))
    B = B / np.max(np.abs(B), axis=0)
    d = model_drifts(rec.data["__input__"], FS, M, C0, shear_K(k), -M @ np.ones(3), B)
    true = np.array([x[0], x[1] - x[0], x[2] - x[1]])   # the stories' drifts, signed as B
    true -= true.mean(axis=1, keepdims=True)
    assert np.sqrt(np.mean((d - true) ** 2)) < 0.01 * true.std()


@pytest.mark.parametrize("story,delta", [(1, 0.2), pytest.param(2, 0.1, marks=pytest.mark.slow),
                                         pytest.param(3, 0.2, marks=pytest.mark.slow)])
def test_bilinear_story_is_located_and_sized(story, delta):
    """The breathing crack is named at its story, stiffer when closed (kappa > 0), and its
    stiffness loss delta comes within 20 % of the truth once the story's drift includes its
    own even force; the first-order kappa (the linear model's drift) understates it."""
    rec, _ = _records(story, "crack", delta, seed=story)
    Kl = _model(story, delta)
    out = _run(rec, Kl)
    assert out["best"] == story - 1
    ref = out["refined"]
    assert ref["converged"] and ref["kappa"] > 0
    assert ref["kappa"] >= out["kappa"][story - 1] > 0
    k_eq = k[story - 1] * (1 - delta / 2)
    assert abs(bilinear_delta(ref["kappa"], k_eq) - delta) < 0.2 * delta


@pytest.mark.parametrize("kind", [pytest.param(None, marks=pytest.mark.slow), "cubic"])
def test_symmetric_frames_name_nothing(kind):
    """A linear frame, or one with a cubic story whose equivalent stiffness changes by several
    per cent, has no even force: every story's z stays within sampling."""
    rec, _ = _records(2 if kind else None, kind, 0.05, seed=11)
    out = _run(rec, _model())
    assert out["best"] is None
    assert max(abs(z) for z in out["z"]) < 4
    assert "refined" not in out


def test_bilinear_delta_inverts_the_statistical_linearisation():
    """kappa = delta k / 2 and k_eq = k (1 - delta / 2) give back delta, either sign of kappa."""
    for delta in (0.05, 0.2, 0.4):
        kc = 5000.0
        assert np.isclose(bilinear_delta(delta * kc / 2, kc * (1 - delta / 2)), delta)
        assert np.isclose(bilinear_delta(-delta * kc / 2, kc * (1 - delta / 2)), delta)


def test_an_asymmetric_story_is_named_outside_the_families():
    """The finding sits at its story, its words say which side is softer and that no family
    describes it, its values print in physical units, and it makes the verdict partial."""
    from nlp.diagnosis.asymmetry import asymmetric_finding
    from nlp.diagnosis.level_kind import outside
    from nlp.diagnosis.plain import finding_line
    from nlp.diagnosis.verdict import classify
    res = {"best": 1, "z": [1.2, 40.0, -3.0], "se": [5.0, 5.0, 5.0], "gap": 1500.0, "bins": 900,
           "refined": {"kappa": 300.0, "iterations": 4, "converged": True}}
    f = asymmetric_finding(res, 1, 4000.0)
    assert f["location"] == {"between": [1, 2]}
    assert np.isclose(f["parameters"]["bilinear_delta"], 0.15 / 1.075)
    assert "softer when its drift is negative" in f["statement"]
    assert "40 standard errors" in f["statement"] and f["statement"].startswith("Story 2")
    assert outside(f) == "outside"
    line = finding_line(f)
    assert "stiffer one way" in line and "14 % softer" in line and "N/m" in line
    assert classify([], [], [], outside(f), [], False) == "partly_explained"
    res["refined"] = {"kappa": -300.0, "iterations": 30, "converged": False}
    f = asymmetric_finding(res, 1, 4000.0)
    assert f["parameters"]["bilinear_delta"] is None
    assert "positive" in f["statement"] and "not determined" in f["statement"]


def test_receptance_in_chunks_is_the_direct_solve():
    """The chunked dynamic-stiffness solve equals one solve per frequency (20 DOFs, more
    frequencies than one chunk holds), and is K^-1 b at omega = 0."""
    from nlp.diagnosis.asymmetry import _receptance
    rng = np.random.default_rng(4)
    A = rng.standard_normal((20, 20))
    Kr, Mr = A @ A.T + 20 * np.eye(20), np.diag(rng.uniform(1, 2, 20))
    Cr, b = 0.01 * Kr, rng.standard_normal(20)
    w = np.linspace(0.0, 50.0, 12001)
    got = _receptance(Mr, Cr, Kr, w, b)
    for i in (0, 1, 4999, 5000, 12000):
        want = np.linalg.solve(Kr - w[i] ** 2 * Mr + 1j * w[i] * Cr, b)
        np.testing.assert_allclose(got[i], want, rtol=1e-10)


def test_the_paragraph_does_not_say_an_asymmetric_story_was_added_to_the_fit():
    from nlp.diagnosis.asymmetry import asymmetric_finding
    from nlp.diagnosis.plain import paragraph
    res = {"best": 0, "z": [30.0, 2.0], "se": [5.0, 5.0], "gap": 800.0, "bins": 900,
           "refined": {"kappa": 300.0, "iterations": 4, "converged": True}}
    f = asymmetric_finding(res, 0, 4000.0)
    text = paragraph({"verdict": "partly_explained", "findings": [f],
                      "fit": {"before": {"reduced_chi2": 1.53, "held_out_chi2": 9.26},
                              "after": {"reduced_chi2": 1.53, "held_out_chi2": 9.26}}})
    assert "With it added" not in text and "stays as it was" in text and "1.53" in text
