"""The blind benchmark's own simulators (nlp/testing/blind, which shares no code with the
package) against closed-form answers."""

import numpy as np

from nlp.testing.blind.cases import specs as case_specs
from nlp.testing.blind.simulators import freq_domain, newmark, nonlinear_ivp
from nlp.testing.blind.structures import (DASHPOT_CAP, FAMILIES, SIZES, real_structure,
                                          with_effect)
from nlp.testing.frames import shear_K


def _system():
    m = np.array([4.0, 3.0, 2.0])
    k = np.array([3000.0, 2500.0, 2000.0])
    M, K = np.diag(m), shear_K(k)
    C = 0.2 * M + 1e-3 * K
    C[0, 0] += 3.0                       # a dashpot to the ground at floor 1: not proportional
    return M, C, K


def test_shear_K_is_the_shear_chain():
    K = shear_K([3.0, 2.0, 1.0])
    assert np.allclose(K, [[5, -2, 0], [-2, 3, -1], [0, -1, 1]])


def test_newmark_steady_state_matches_the_exact_frf():
    M, C, K = _system()
    b = np.array([0.0, 1.0, 0.0])
    f0, h = 3.0, 1 / 4000
    t = np.arange(0, 40, h)
    q, _, a = newmark(M, C, K, b, np.sin(2 * np.pi * f0 * t), h)
    w = 2 * np.pi * f0
    X = np.linalg.solve(K - w**2 * M + 1j * w * C, b)     # steady state of sin(w t) = Im(e^{jwt})
    tail = t > 30
    expect = np.imag(np.outer(X, np.exp(1j * w * t[tail])))
    assert np.max(np.abs(q[:, tail] - expect)) < 2e-3 * np.max(np.abs(expect))
    assert np.allclose(a[:, tail], -w**2 * expect, atol=5e-3 * w**2 * np.max(np.abs(expect)))


def test_frequency_domain_and_ivp_agree_with_newmark_on_a_linear_system():
    M, C, K = _system()
    b = -M @ np.ones(3)
    h = 1 / 2000
    t = np.arange(0, 8, h)
    u = np.sin(2 * np.pi * 1.5 * t) * np.exp(-((t - 3) / 1.0) ** 2)   # starts and ends at rest
    qn = newmark(M, C, K, b, u, h)[0]
    qf = freq_domain(M, C, K, np.zeros((3, 3)), b, u, h)[0]
    qi = nonlinear_ivp(M, C, K, b, u, h, story=2, kind="cubic", k_nl=0.0, gap=0.0)[0]
    scale = np.max(np.abs(qn))
    assert np.max(np.abs(qf - qn)) < 2e-3 * scale
    assert np.max(np.abs(qi - qn)) < 2e-3 * scale


def test_contact_spring_engages_beyond_the_gap_only():
    M, C, K = _system()
    b = np.array([1.0, 0.0, 0.0])
    h = 1 / 2000
    t = np.arange(0, 6, h)
    u = 50 * np.sin(2 * np.pi * 1.0 * t) * np.exp(-((t - 2) / 0.8) ** 2)
    q0 = nonlinear_ivp(M, C, K, b, u, h, story=1, kind="contact", k_nl=0.0, gap=0.0)[0]
    big_gap = 10 * np.max(np.abs(q0[0]))
    q1 = nonlinear_ivp(M, C, K, b, u, h, story=1, kind="contact", k_nl=5e4, gap=big_gap)[0]
    q2 = nonlinear_ivp(M, C, K, b, u, h, story=1, kind="contact", k_nl=5e4,
                          gap=0.3 * np.max(np.abs(q0[0])))[0]
    assert np.allclose(q1, q0, atol=1e-9)                  # never touches: linear
    assert np.max(np.abs(q2[0])) < 0.9 * np.max(np.abs(q0[0]))   # the stop limits the drift


def test_case_list_covers_every_family_at_five_sizes_and_has_60_cases():
    specs = case_specs(np.random.default_rng(0))
    assert len(specs) >= 60
    single = [s["effects"][0] for s in specs if len(s["effects"]) == 1 and not s.get("route")]
    for fam in FAMILIES:
        assert sorted(sz for f, sz in single if f == fam) == sorted(SIZES[fam])
    assert sum(len(s["effects"]) == 2 for s in specs) >= 5
    assert sum(not s["effects"] and not s.get("ordinary") for s in specs) >= 5   # null
    assert sum(bool(s.get("ordinary")) for s in specs) >= 5
    assert {s.get("route") for s in specs} >= {None, "frf_file"}
    assert {s["signal"] for s in specs} == {"chirp", "random"}


def test_null_damping_holds_no_detectable_damper():
    """Story dashpots read back from C (minus its 60 % Rayleigh part) never exceed the median of
    the other stories by a detectable damper, while a size-1 local_damper added on top does."""
    rng = np.random.default_rng(5)
    for t in range(60):
        n = int(rng.integers(3, 6))
        st = real_structure(rng, n, t % 2 == 0)
        M, K = st["M"], st["K"]
        w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
        a1 = 2 * st["zeta"] / (w[0] + w[-1])
        R = st["C"] - 0.6 * (a1 * w[0] * w[-1] * M + a1 * K)
        cs = np.array([-R[s, s - 1] for s in range(1, n)])      # stories 2..n
        cs = np.r_[R[0, 0] - cs[0], cs]                 # story 1 joins floor 1 to the ground
        unit = 2 * st["zeta"] * np.sqrt(st["k"] * st["m"])
        excess = [(cs[s] - np.median(np.delete(cs, s))) / unit[s] for s in range(n)]
        assert np.allclose(excess, st["dashpot_excess"], atol=1e-9)
        assert max(excess) < DASHPOT_CAP
        s = int(np.argmax(excess))                      # a size-1 damper on the most damped story
        c = with_effect(st, (M, st["C"], K, np.zeros((n, n))), "local_damper",
                        (s + 1, s), DASHPOT_CAP, rng)[1]
        added = (c - st["C"])[s, s]                     # the dashpot's own diagonal term
        assert np.isclose(added, DASHPOT_CAP * unit[s])
        cs[s] += added
        assert (cs[s] - np.median(np.delete(cs, s))) / unit[s] >= DASHPOT_CAP
