"""Newton polish (nlp/polish.py) against closed-form and independent optima."""

import numpy as np
from scipy.optimize import least_squares

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.fitting import diagnosis_problem
from nlp.solve.polish import newton_polish
from nlp.solve.problem import UpdatingProblem
from support.cases import write_case


def test_projection_with_an_equality_and_an_active_bound():
    """min 0.5 |z - a|^2 on 1^T z = c with z_0 <= u < a_0: z_0 = u and the others are
    a_i + lam with lam fixing the sum (Lagrange: the same shift for every free z_i)."""
    a = np.array([2.0, 0.5, -1.0, 0.3])
    c, u = 1.0, 0.4
    lo, hi = np.full(4, -10.0), np.array([u, 10.0, 10.0, 10.0])
    lam = (c - u - a[1:].sum()) / 3
    expected = np.concatenate([[u], a[1:] + lam])

    def fg(z):
        return 0.5 * float((z - a) @ (z - a)), z - a

    z0 = np.array([0.0, 0.5, 0.25, 0.25])            # feasible: sums to c
    z, f, dec, ok, steps = newton_polish(fg, z0, lo, hi, G=np.ones((1, 4)))
    assert ok and dec < 1e-10
    np.testing.assert_allclose(z, expected, atol=1e-9)
    assert abs(z.sum() - c) < 1e-12


def test_large_residual_fit_reaches_the_independent_optimum():
    """y = b0 exp(b1 t) + large misfit: the polish from a rough start ends where scipy's
    trust-region least squares ends, and the gradient there (central differences of f,
    not the gradient given to the polish) vanishes."""
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2, 40)
    y = 1.5 * np.exp(-0.7 * t) + 0.4 * np.sin(9 * t) + 0.05 * rng.normal(size=t.size)

    def res(b):
        return b[0] * np.exp(b[1] * t) - y

    def fg(b):
        r = res(b)
        J = np.column_stack([np.exp(b[1] * t), b[0] * t * np.exp(b[1] * t)])
        return 0.5 * float(r @ r), J.T @ r

    ref = least_squares(res, [1.0, -0.3], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    lo, hi = np.array([-10.0, -10.0]), np.array([10.0, 10.0])
    # f is not a chi-square here (no noise normalisation): a tolerance to match, above the
    # smallest decrease the line search can see in f (machine epsilon x f, 4e-16 here)
    z, f, dec, ok, _ = newton_polish(fg, np.array([1.2, -0.4]), lo, hi, tol=1e-14)
    assert ok
    np.testing.assert_allclose(z, ref, rtol=1e-6)
    h = 1e-6
    g_fd = [(fg(z + h * e)[0] - fg(z - h * e)[0]) / (2 * h) for e in np.eye(2)]
    assert np.max(np.abs(g_fd)) < 1e-6


def test_a_saddle_is_not_called_a_minimum():
    """f = 0.5 (x^2 - y^2) from the saddle's neighbourhood: never reported stationary there,
    and the polish does not return a point worse than its start."""
    def fg(z):
        return 0.5 * float(z[0] ** 2 - z[1] ** 2), np.array([z[0], -z[1]])

    lo, hi = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    z0 = np.array([0.3, 1e-3])
    z, f, dec, ok, _ = newton_polish(fg, z0, lo, hi, max_steps=50)
    assert f <= fg(z0)[0]
    # it leaves along -y^2 to the bound y = +-1 and settles x = 0 there (a true minimum
    # on the box: the bound holds y)
    assert ok and abs(abs(z[1]) - 1.0) < 1e-12 and abs(z[0]) < 1e-8


def test_a_point_where_the_model_fails_is_left_as_it_is():
    """A gradient that turns non-finite next to the start (the FD Hessian reads it): the
    polish returns the start, not stationary, and raises nothing."""
    def fg(z):
        if z[0] > 0.5 + 1e-7:
            return np.inf, np.full(2, np.nan)
        return 0.5 * float(z @ z) - z[0], z - np.array([1.0, 0.0])

    z0 = np.array([0.5, 0.2])
    z, f, dec, ok, _ = newton_polish(fg, z0, np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    assert not ok and np.array_equal(z, z0)


def test_a_coupled_variable_on_its_bound_is_held_and_the_rest_solved():
    """f = 0.5 (z - a)^T A (z - a) with A coupling z_0 and z_1, z_0 on its upper bound u
    and a Newton step that would push it out: the minimum on the box holds z_0 = u and
    sets z_1 = a_1 - A_10 (u - a_0) / A_11 (closed form), with the KKT sign on z_0."""
    A = np.array([[2.0, 1.5], [1.5, 2.0]])
    a = np.array([1.0, -1.0])
    u = 0.5
    lo, hi = np.array([-5.0, -5.0]), np.array([u, 5.0])

    def fg(z):
        d = z - a
        return 0.5 * float(d @ A @ d), A @ d

    z, f, dec, ok, _ = newton_polish(fg, np.array([u, 0.0]), lo, hi)
    z1 = a[1] - A[1, 0] * (u - a[0]) / A[1, 1]
    assert ok
    np.testing.assert_allclose(z, [u, z1], atol=1e-9)
    assert fg(z)[1][0] < 0          # the gradient presses z_0 against its upper bound


def test_capped_refits_are_not_polished(tmp_path, monkeypatch):
    """A diagnosis refit capped below the case's iteration limit stops unconverged and
    is left so (it is continued when adopted); the same NLP without the cap is finished
    by Newton steps when IPOPT stops at its limit."""
    path, _ = write_case(str(tmp_path), noise=0.02, seed=1,
                         frequencies={"method": "half_power", "k": 2.0, "fmax": 7.0})
    case = assemble(load_case(path))
    calls = []
    real = UpdatingProblem._polish

    def counted(self, *a):
        calls.append(self.polish_unconverged)
        return real(self, *a)

    monkeypatch.setattr(UpdatingProblem, "_polish", counted)
    capped = diagnosis_problem(case, case.target, compile=False, max_iter=2)
    res = capped.solve(0.5 * capped.z0 + 0.5 * capped.bounds[1])
    assert not capped.polish_unconverged and calls == []
    assert res.status == "Maximum_Iterations_Exceeded" and not res.success
    capped.polish_unconverged = True     # the uncapped rule on the same stop
    capped.solve(0.5 * capped.z0 + 0.5 * capped.bounds[1])
    assert calls == [True]
    assert diagnosis_problem(case, case.target, compile=False).polish_unconverged
