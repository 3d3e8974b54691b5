"""Newton polish (nlp/polish.py) against closed-form and independent optima."""

import numpy as np
from scipy.optimize import least_squares

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.fitting import diagnosis_problem, fit_target, noise_sigma
from nlp.solve.polish import newton_polish
import nlp.solve.problem as P
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

    def counted(self, *a, **k):
        calls.append(self.polish_unconverged)
        return real(self, *a, **k)

    monkeypatch.setattr(UpdatingProblem, "_polish", counted)
    capped = diagnosis_problem(case, case.target, compile=False, max_iter=2)
    res = capped.solve(0.5 * capped.z0 + 0.5 * capped.bounds[1])
    assert not capped.polish_unconverged and calls == []
    assert res.status == "Maximum_Iterations_Exceeded" and not res.success
    capped.polish_unconverged = True     # the uncapped rule on the same stop
    capped.solve(0.5 * capped.z0 + 0.5 * capped.bounds[1])
    assert calls == [True]
    assert diagnosis_problem(case, case.target, compile=False).polish_unconverged


def test_a_convex_start_is_required_when_asked():
    """f = (x^2 - 1)^2 / 4: f'' = 3 x^2 - 1 is negative at x = 0.2 (no Newton step is taken
    from there when a convex start is required) and positive at x = 1.3 (Newton reaches the
    minimum x = 1, to the polish's tolerance: a chi-square decrement f'' dx^2 of 1e-4, so
    |dx| < 0.01)."""
    def fg(z):
        x = z[0]
        return 0.25 * (x * x - 1) ** 2, np.array([x * (x * x - 1)])

    lo, hi = np.array([-5.0]), np.array([5.0])
    z, f, dec, ok, steps = newton_polish(fg, np.array([0.2]), lo, hi, convex_start=True)
    assert not ok and steps == 0 and z[0] == 0.2
    z, f, dec, ok, steps = newton_polish(fg, np.array([1.3]), lo, hi, convex_start=True)
    assert ok and abs(z[0] - 1.0) < 0.01 and steps >= 1


def _early(tmp_path, monkeypatch, polish_at):
    path, _ = write_case(str(tmp_path), noise=0.02, seed=1,
                         frequencies={"method": "half_power", "k": 2.0, "fmax": 7.0})
    case = assemble(load_case(path))
    monkeypatch.setattr(P, "POLISH_AT", polish_at)
    fit = np.arange(case.f.size)
    pr = diagnosis_problem(case, fit_target(case, fit, noise_sigma(case, fit)), compile=False)
    return pr, pr.solve(0.5 * pr.z0 + 0.5 * pr.bounds[1])


def test_a_solve_stopped_early_and_polished_reaches_the_uninterrupted_optimum(tmp_path, monkeypatch):
    """IPOPT stopped at iteration 10 and finished by Newton steps ends at the optimum of
    the same solve left to IPOPT (no early stop), on a fit in noise units (f half a
    chi-square): f within 1e-4, the polish's stationarity test (a Newton step would lower
    the chi-square by less than 1e-4), and z within 1e-3."""
    pr, early = _early(tmp_path, monkeypatch, 10)
    assert early.success and "Newton steps" in early.status and early.iterations <= 11
    monkeypatch.setattr(P, "POLISH_AT", 10 ** 9)
    full = pr.solve(0.5 * pr.z0 + 0.5 * pr.bounds[1])
    assert full.success and "Newton" not in full.status and full.iterations > early.iterations
    assert abs(early.f - full.f) <= 1e-4
    np.testing.assert_allclose(early.z, full.z, atol=1e-3)


def test_a_solve_whose_early_polish_fails_goes_on_with_ipopt(tmp_path, monkeypatch):
    """Where the Newton steps from the early stop do not reach a minimum (forced here),
    IPOPT resumes from that point and converges by its own test."""
    monkeypatch.setattr(UpdatingProblem, "_polish",
                        lambda self, z, f, lo, hi, status, convex_start=False: (z, f, False, status))
    pr, res = _early(tmp_path, monkeypatch, 10)
    assert res.success and "Newton" not in res.status and res.iterations > 10
