"""The dense backend's residuals through CasADi's buffer interface equal the DM route."""

import casadi as ca
import numpy as np

from nlp.solve.compiled import BufferedFunction


def test_buffered_outputs_equal_the_dm_route_dense_and_sparse():
    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p", 2)
    dense = ca.vertcat(x * p[0], ca.sin(x) + p[1])          # (6, 1)
    J = ca.jacobian(dense, x)                                # (6, 3), structurally sparse
    full = ca.mtimes(ca.DM(np.arange(12.0).reshape(4, 3)), x) @ ca.DM.ones(1, 2)   # dense (4, 2)
    f = ca.Function("f", [x, p], [dense, J, full])
    assert not f.sparsity_out(1).is_dense() and f.sparsity_out(2).is_dense()
    bf = BufferedFunction(f)
    for xv, pv in (([0.3, -1.2, 2.0], [1.5, -0.4]), ([1.0, 2.0, 3.0], [0.0, 7.0])):
        got = bf(np.array(xv), np.array(pv))
        want = [np.asarray(o) for o in f(xv, pv)]
        for g, w in zip(got, want):
            assert g.shape == w.shape
            np.testing.assert_array_equal(g, w)
    first = bf(np.ones(3), np.ones(2))[0]
    bf(np.zeros(3), np.zeros(2))
    np.testing.assert_array_equal(first.ravel(), [1, 1, 1, np.sin(1) + 1, np.sin(1) + 1,
                                                  np.sin(1) + 1])   # not overwritten
