"""scripts/make_planted_fe.py's flexible supports: the bordered model is the chain written
out by hand, and its rigid translation loads only the base spring."""

import importlib.util
import os

import numpy as np
import scipy.sparse as sp

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "make_planted_fe.py")


def _script():
    spec = importlib.util.spec_from_file_location("make_planted_fe", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_support_base_is_the_chain_with_a_base_dof():
    """Two storeys (k1 to the removed support, k2 between the floors): the base DOF under
    the support is the third DOF of the chain ground -kb- base -k1- floor 1 -k2- floor 2."""
    mod = _script()
    k1, k2, kb, m1, m2, mb = 3.0e6, 2.0e6, 9.0e6, 1.0e3, 8.0e2, 5.0e2
    K = sp.csc_matrix([[k1 + k2, -k2], [-k2, k2]])
    M = sp.csc_matrix(np.diag([m1, m2]))
    dofs = [(1, 1), (2, 1)]                        # node tags, both ux
    Mp, Kp, r = mod.plant_support(M, K, dofs, "ux", mb, kb)
    chain = np.array([[k1 + k2, -k2, -k1], [-k2, k2, 0.0], [-k1, 0.0, k1 + kb]])
    np.testing.assert_allclose(Kp.toarray(), chain, rtol=1e-14)
    np.testing.assert_allclose(Mp.toarray(), np.diag([m1, m2, mb]))
    # a rigid translation of everything stretches only the base spring
    np.testing.assert_allclose(Kp @ np.append(r, 1.0), [0.0, 0.0, kb], atol=1e-6 * kb)


def test_support_moves_only_the_named_direction():
    mod = _script()
    dofs = [(1, 1), (1, 2), (1, 4)]                # ux, uy, rx of one node
    K = sp.csc_matrix(np.diag([4.0, 5.0, 6.0]))
    _, _, r = mod.plant_support(sp.identity(3, format="csc"), K, dofs, "uy", 1.0, 1.0)
    np.testing.assert_array_equal(r, [0.0, 1.0, 0.0])
