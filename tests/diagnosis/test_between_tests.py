"""The spread of the tests fitted alone around a joint finding (nlp.diagnosis.joint.between_tests),
against the closed forms of DerSimonian and Laird's moment estimate."""

import math

import numpy as np

from nlp.diagnosis.joint import WIDER, between_tests
from nlp.diagnosis.plain import paragraph


def _rec(test, value, se, joint=0.10, joint_se=0.001, reason=""):
    return {"test": test, "physics": "sensor_gain", "location": {"channel": "a1"},
            "joint": {"gain_a1": joint}, "joint_uncertainty": {"gain_a1": joint_se},
            "alone": {"gain_a1": value}, "alone_uncertainty": {"gain_a1": se},
            "agrees": not reason, "reason": reason}


def test_two_tests_that_disagree_give_the_sample_spread_less_the_noise():
    # equal errors s: Q = (y1 - y2)^2 / (2 s^2), tau^2 = (y1 - y2)^2 / 2 - s^2, and the common
    # value's error sqrt((s^2 + tau^2) / 2)
    y1, y2, s = 0.126, 0.095, 0.003
    (out,) = between_tests([_rec("t1", y1, s), _rec("t2", y2, s)])
    tau2 = (y1 - y2) ** 2 / 2 - s ** 2
    assert math.isclose(out["tau"], math.sqrt(tau2), rel_tol=1e-12)
    assert math.isclose(out["standard_error"], math.sqrt((s ** 2 + tau2) / 2), rel_tol=1e-12)
    assert out["wider"] and out["tests"] == ["t1", "t2"]


def test_tests_within_their_errors_add_no_spread():
    # |y1 - y2| < sqrt(2) s: Q < k - 1, so tau = 0 and the error is the fixed-effect one
    s1, s2 = 0.004, 0.002
    (out,) = between_tests([_rec("t1", 0.100, s1, joint_se=0.0018),
                            _rec("t2", 0.102, s2, joint_se=0.0018)])
    assert out["tau"] == 0.0
    assert math.isclose(out["standard_error"], 1 / math.sqrt(s1 ** -2 + s2 ** -2), rel_tol=1e-12)
    assert not out["wider"]


def test_three_unequal_tests_match_the_moment_estimate():
    y, s = np.array([0.05, 0.09, 0.13]), np.array([0.01, 0.02, 0.015])
    (out,) = between_tests([_rec(f"t{i}", y[i], s[i]) for i in range(3)])
    w = 1 / s ** 2
    mean = (w * y).sum() / w.sum()
    q = (w * (y - mean) ** 2).sum()
    tau2 = (q - 2) / (w.sum() - (w ** 2).sum() / w.sum())
    assert tau2 > 0
    assert math.isclose(out["tau"] ** 2, tau2, rel_tol=1e-12)
    assert math.isclose(out["standard_error"], ((1 / (s ** 2 + tau2)).sum()) ** -0.5, rel_tol=1e-12)


def test_a_test_that_cannot_see_the_finding_is_left_out():
    recs = [_rec("t1", 0.126, 0.003), _rec("t2", 0.0, 0.001, reason="this test cannot see it: x")]
    assert between_tests(recs) == []


def test_the_plain_words_give_the_wider_error_only_when_it_is_wider():
    recs = [_rec("t1", 0.126, 0.003), _rec("t2", 0.095, 0.003)]
    d = {"verdict": "partly_explained", "findings": [], "between_tests": between_tests(recs)}
    words = paragraph(d)
    se = d["between_tests"][0]["standard_error"]
    assert se >= WIDER * 0.001
    assert "known only to" in words and f"{100 * se:.2g} % points" in words
    d["between_tests"] = between_tests([_rec("t1", 0.100, 0.004), _rec("t2", 0.102, 0.002)])
    assert "known only to" not in paragraph(d)
