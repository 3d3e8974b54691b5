"""Sensor delays from the FRF phase (nlp/diagnosis/phase.py), against hand-built FRFs."""

import numpy as np

from nlp.diagnosis.phase import delay_check, fit_delay, wrap


def _shear(m, k, c):
    n = len(m)
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    for s in range(n):
        for A, v in ((K, k[s]), (C, c[s])):
            A[s, s] += v
            if s > 0:
                A[s - 1, s - 1] += v
                A[s - 1, s] -= v
                A[s, s - 1] -= v
    return np.diag(m), C, K


def _accelerance(M, C, K, f, dof_in):
    """Floor accelerations per unit force at dof_in, by direct solves (no package code)."""
    out = []
    for w in 2 * np.pi * f:
        Z = K - w ** 2 * M + 1j * w * C
        out.append(-w ** 2 * np.linalg.solve(Z, np.eye(len(M))[:, dof_in]))
    return np.array(out).T


def _windows(f_modes, width=0.15, n=40):
    return np.sort(np.concatenate([np.linspace(fm * (1 - width), fm * (1 + width), n)
                                   for fm in f_modes]))


def _frame():
    M, C, K = _shear([5.0, 4.0, 3.0], [9000.0, 7000.0, 5000.0], [3.0, 2.0, 1.5])
    fn = np.sqrt(np.linalg.eigvalsh(np.linalg.solve(M, K))) / (2 * np.pi)
    return M, C, K, _windows(fn)


def test_fit_delay_recovers_a_wrapping_delay_with_its_standard_error():
    rng = np.random.default_rng(3)
    f = np.linspace(2.0, 30.0, 300)
    w = 2 * np.pi * f
    sigma = np.full(f.size, 0.05)
    tau = 0.030            # 30 ms: the phase wraps about once per 33 Hz
    est = [fit_delay(w, wrap(-w * tau + sigma * rng.standard_normal(f.size)), sigma)["tau"]
           for _ in range(200)]
    se_theory = 0.05 / np.sqrt(np.sum(w ** 2))          # weighted LS of d = -w tau
    assert abs(np.mean(est) - tau) < 3 * se_theory / np.sqrt(200) + 1e-9
    assert 0.8 < np.std(est) / se_theory < 1.2
    r = fit_delay(w, wrap(-w * tau + sigma * rng.standard_normal(f.size)), sigma)
    assert abs(r["tau"] - tau) < 4 * r["standard_error"]
    assert r["explained"] > 0.99 and r["delta_bic"] < -1000


def test_one_delayed_channel_is_found_and_model_phase_error_is_not():
    rng = np.random.default_rng(5)
    M, C, K, f = _frame()
    H_model = _accelerance(M, C, K, f, 2)
    # the "real" frame has 40 % more damping in story 2 (a magnitude fit's model error)
    M2, C2, K2 = _shear([5.0, 4.0, 3.0], [9000.0, 7000.0, 5000.0], [3.0, 2.8, 1.5])
    H_true = _accelerance(M2, C2, K2, f, 2)
    sigma = np.full(H_true.shape, 0.02)
    noise = np.exp(sigma * (rng.standard_normal(H_true.shape)
                            + 1j * rng.standard_normal(H_true.shape)))
    names = ["a1", "a2", "a3"]
    clean = delay_check(f, H_true * noise, H_model, sigma, names)
    assert clean["findings"] == []
    tau = 0.012
    H_meas = H_true * noise
    H_meas[1] *= np.exp(-2j * np.pi * f * tau)
    out = delay_check(f, H_meas, H_model, sigma, names)
    assert [fd["location"] for fd in out["findings"]] == [{"channel": "a2"}]
    fd = out["findings"][0]
    est, se = fd["parameters"]["delay_ms_a2"], fd["uncertainty"]["delay_ms_a2"]
    assert abs(est - 1e3 * tau) < 3 * se + 0.5
    assert "lags the model's by a time delay of 12" in fd["statement"]
    # a channel whose chain responds early (a negative delay) leads the model, by |tau|
    H_meas = H_true * noise
    H_meas[1] *= np.exp(2j * np.pi * f * tau)
    (fd,) = delay_check(f, H_meas, H_model, sigma, names)["findings"]
    assert fd["parameters"]["delay_ms_a2"] < 0
    assert "leads the model's by a time delay of 12" in fd["statement"]


def test_a_late_input_is_one_finding_on_the_input():
    rng = np.random.default_rng(8)
    M, C, K, f = _frame()
    H = _accelerance(M, C, K, f, 2)
    sigma = np.full(H.shape, 0.02)
    tau_in = 0.008
    # H = Y / U with U late by tau_in: every output leads by tau_in
    H_meas = H * np.exp(2j * np.pi * f * tau_in) * np.exp(
        sigma * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))
    out = delay_check(f, H_meas, H, sigma, ["a1", "a2", "a3"])
    assert len(out["findings"]) == 1
    fd = out["findings"][0]
    assert fd["location"] == {"channel": "input"}
    assert abs(fd["parameters"]["delay_ms_input"] - 1e3 * tau_in) < 3 * fd["uncertainty"][
        "delay_ms_input"] + 0.1


def _two_tests(tau_1, tau_2, seed=11):
    """Two tests of the model-error frame (force at floors 3 and 1), sensors a1-a3 in
    both; sensor a2 late by tau_1 in the first test and tau_2 in the second."""
    rng = np.random.default_rng(seed)
    M, C, K, f = _frame()
    M2, C2, K2 = _shear([5.0, 4.0, 3.0], [9000.0, 7000.0, 5000.0], [3.0, 2.8, 1.5])
    H_model = np.vstack([_accelerance(M, C, K, f, d) for d in (2, 0)])
    H_true = np.vstack([_accelerance(M2, C2, K2, f, d) for d in (2, 0)])
    sigma = np.full(H_true.shape, 0.02)
    H_meas = H_true * np.exp(sigma * (rng.standard_normal(H_true.shape)
                                      + 1j * rng.standard_normal(H_true.shape)))
    H_meas[1] *= np.exp(-2j * np.pi * f * tau_1)
    H_meas[4] *= np.exp(-2j * np.pi * f * tau_2)
    names = ["a1", "a2", "a3", "a1@t2", "a2@t2", "a3@t2"]
    return f, H_meas, H_model, sigma, names, ["a1", "a2", "a3"] * 2


def test_a_sensor_in_two_tests_gets_one_delay():
    f, H_meas, H_model, sigma, names, sensors = _two_tests(0.012, 0.012)
    out = delay_check(f, H_meas, H_model, sigma, names, sensors)
    (fd,) = out["findings"]
    assert fd["location"] == {"channel": "a2"}
    est, se = fd["parameters"]["delay_ms_a2"], fd["uncertainty"]["delay_ms_a2"]
    assert abs(est - 12.0) < 3 * se + 0.5
    apart = fd["evidence"]["per_channel"]
    assert [p["channel"] for p in apart] == ["a2", "a2@t2"]
    # one delay from both tests' points is more precise than either test's alone
    assert se < min(p["standard_error_ms"] for p in apart)
    assert "One delay for the sensor in every test" in fd["statement"]
    # fitted per channel (no sensors given), the same data give two findings
    assert len(delay_check(f, H_meas, H_model, sigma, names)["findings"]) == 2


def test_a_delay_in_one_test_only_is_reported_as_test_specific():
    f, H_meas, H_model, sigma, names, sensors = _two_tests(0.012, 0.0)
    (fd,) = delay_check(f, H_meas, H_model, sigma, names, sensors)["findings"]
    assert fd["location"] == {"channel": "a2"}
    assert abs(fd["parameters"]["delay_ms_a2"] - 12.0) < 3 * fd["uncertainty"]["delay_ms_a2"] + 0.5
    assert "Test-specific" in fd["statement"]
    assert [p["channel"] for p in fd["evidence"]["test_specific"]] == ["a2", "a2@t2"]


def test_a_sensor_whose_tests_differ_beyond_their_noise_gets_their_spread_as_its_error():
    # 12.0 and 12.6 ms: the same delay within a magnitude fit's phase error (0.6 ms x 2 pi x
    # 20 Hz = 0.08 rad < MIN_PHASE) but many noise errors apart, so the one delay is known
    # only to about half their difference (two tests: tau^2 = d^2 / 2 - s^2)
    f, H_meas, H_model, sigma, names, sensors = _two_tests(0.012, 0.0126)
    (fd,) = delay_check(f, H_meas, H_model, sigma, names, sensors)["findings"]
    apart = fd["evidence"]["per_channel"]
    d = apart[1]["delay_ms"] - apart[0]["delay_ms"]
    assert abs(d) > 5 * max(p["standard_error_ms"] for p in apart)
    se = fd["uncertainty"]["delay_ms_a2"]
    assert 0.25 * abs(d) < se < 0.75 * abs(d)
    assert abs(fd["parameters"]["delay_ms_a2"] - 12.3) < 2 * se
