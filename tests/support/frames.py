"""Shear frames for the tests: the stiffness written independently of the package, the
paper's Table 1 initial values, parameter sets built by hand, and random systems."""

import numpy as np

from nlp.model.parameters import Parameter, ParameterSet
from nlp.testing.frames import shear_K  # noqa: F401  (re-exported for the tests)

TABLE1_INITIAL_M = np.full(4, 4.64)
TABLE1_INITIAL_K = np.array([1019.0, 1217.0, 1420.0, 2473.0])


def frame_parameter_set(m, k, damping):
    """ParameterSet of a shear frame: free story stiffness changes, fixed masses, and the
    damping model's own parameters (for tests that build an UpdatingProblem by hand)."""
    n = len(k)
    ps = [Parameter(f"k{i + 1}", "stiffness", 0.0, -0.5, 1.0, nominal=k[i]) for i in range(n)]
    ps += [Parameter(f"m{i + 1}", "mass", 0.0, -0.5, 1.0, fixed=True, nominal=m[i])
           for i in range(n)]
    lo, hi = damping.default_bounds()
    ps += [Parameter(nm, "damping", t, a, b) for nm, t, a, b in
           zip(damping.names, damping.initial(), lo, hi)]
    return ParameterSet(tuple(ps), n, n)


def random_system(n, rng):
    """Random SPD M, K and a non-proportional SPD C."""
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    B = rng.standard_normal((n, n))
    K = 100 * (B @ B.T + n * np.eye(n))
    D = rng.standard_normal((n, n))
    C = 0.5 * (D @ D.T) + 0.1 * np.eye(n)
    return M, C, K


def story_link(f, x, story, force):
    """Add a nonlinear story link to the load vector f (in place) and return it: ``force(d)``
    [N] acts across ``story`` (1-based) on its drift d = x_s - x_{s-1} (x_0 the ground)."""
    if story is not None:
        d = x[story - 1] - (x[story - 2] if story > 1 else 0.0)
        fn = force(d)
        f[story - 1] -= fn
        if story > 1:
            f[story - 2] += fn
    return f
