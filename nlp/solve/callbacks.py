"""The sparse and reduced backends' NLP: r and J evaluated numerically, handed to CasADi
as Python callbacks.

One numeric evaluation of r and J (:class:`nlp.frf.backends.sparse.SparseFRF`: sparse
factorisations, adjoint sensitivities) per point serves the objective, the gradient
J^T r and the Gauss-Newton Hessian J^T J of the same NLP as the dense backend's.
"""

import casadi as ca
import numpy as np

from nlp.solve.compiled import BuiltNLP, user_ipopt_keys

__all__ = ["PythonCallback", "total_mass_constraint", "build_callback_nlp"]


class PythonCallback(ca.Callback):
    """A CasADi function evaluated by Python (the numeric backends' r, J, f, gradient, Hessian)."""

    def __init__(self, name, fn, sp_in, sp_out, gradient=None):
        ca.Callback.__init__(self)
        self._fn, self._in, self._out = fn, sp_in, sp_out
        self.gradient = gradient  # a callback returning (f, df/dx) for a scalar f(x, p)
        self.construct(name, {})

    def get_n_in(self):
        return len(self._in)

    def get_n_out(self):
        return len(self._out)

    def get_sparsity_in(self, i):
        return self._in[i]

    def get_sparsity_out(self, i):
        return self._out[i]

    def has_jacobian(self):
        return self.gradient is not None

    def get_jacobian(self, name, inames, onames, opts):
        x, p = (ca.MX.sym(f"a{i}", self._in[i]) for i in range(2))
        out = ca.MX.sym("out", self._out[0])
        _, g = self.gradient(x, p)
        return ca.Function(name, [x, p, out], [g.T, ca.MX(1, self._in[1].size1())],
                           inames, onames, opts)

    def eval(self, args):
        outs = self._fn([np.asarray(a.full() if hasattr(a, "full") else a) for a in args])
        res = []
        for sp_o, v in zip(self._out, outs):
            v = np.atleast_2d(np.asarray(v, float))
            if v.shape != (sp_o.size1(), sp_o.size2()):
                v = v.reshape(sp_o.size1(), sp_o.size2())
            res.append(ca.DM(v) if sp_o.is_dense() else ca.project(ca.DM(v), sp_o))
        return res


def total_mass_constraint(model, params, x, total_mass):
    """g(x) = 1^T M 1 - m_total, linear in beta (Eqn 24); (0, 1) without an anchor."""
    if total_mass is None:
        return ca.MX(0, 1)
    _, sb, _ = params.slices()
    theta = ca.mtimes(ca.DM(params.T), x) + ca.DM(params.c)
    s0 = float(model.M0.sum())
    sr = ca.DM([float(A.sum()) for A in model.M_infl])
    return s0 + ca.dot(sr, theta[sb]) - total_mass if sr.numel() else ca.MX(s0 - total_mass)


def _callbacks(rj, n_z, n_p, ng, ipopt, r_only=None):
    """grad_f, objective and hess_lag as callbacks around rj(x, p) -> (r, J) and
    r_only(x, p) -> r (default: r of rj)."""
    def f_only(x, p):
        # r alone: IPOPT's line search tries several points per accepted one
        r = rj(x, p)[0] if r_only is None else r_only(x, p)
        return 0.5 * float(r @ r)

    def grad(x, p):
        r, J = rj(x, p)
        return 0.5 * float(r @ r), J.T @ r

    def hess(x, p, lam_f, lam_g):
        _, J = rj(x, p)
        H = float(np.ravel(lam_f)[0]) * (J.T @ J)
        return np.triu(H) if ipopt else H

    dense = ca.Sparsity.dense
    hsp = ca.Sparsity.upper(n_z) if ipopt else dense(n_z, n_z)
    grad_cb = PythonCallback("grad_f", lambda a: list(grad(*a)), [dense(n_z, 1), dense(n_p, 1)],
                             [dense(1, 1), dense(n_z, 1)])
    return [
        grad_cb,
        # CasADi asks once for df/dx, df/dp (the final multipliers): grad_f answers
        PythonCallback("objective", lambda a: [f_only(*a)], [dense(n_z, 1), dense(n_p, 1)],
                       [dense(1, 1)], gradient=grad_cb),
        PythonCallback("hess_lag", lambda a: [hess(*a)],
                       [dense(n_z, 1), dense(n_p, 1), dense(1, 1), dense(ng, 1)], [hsp]),
    ]


def _ipopt_numeric_options(opts, solver_config, named):
    """IPOPT on a numeric gradient: its own gradient callback and a looser acceptable stop."""
    opts["grad_f"] = named["grad_f"]
    # Round-off of the numeric gradient (~1e-8 of its starting norm, more at
    # thousands of DOFs) keeps the scaled dual infeasibility at 1e-7..3e-6 at the
    # optimum; IPOPT then backtracks ~37 times per iteration on a flat objective for
    # 10-15 iterations (measured at n = 256 and 2,000). Stop at a scaled error of 1e-5
    # (the first time) and let the watchdog take over after 3 shortened steps.
    user = user_ipopt_keys(solver_config)
    for key, value in (("ipopt.acceptable_iter", 1), ("ipopt.acceptable_tol", 1e-5),
                       ("ipopt.watchdog_shortened_iter_trigger", 3)):
        if key not in user:
            opts[key] = value


def build_callback_nlp(rj, model, params, n_p, total_mass, solver_config, r_only=None):
    """The numeric backends' NLP (:class:`nlp.solve.compiled.BuiltNLP`).

    rj : (x, p) -> (r, J) numeric; n_p : size of the data vector p; r_only : (x, p) -> r.
    """
    nz = params.n_z
    ipopt = solver_config.name == "ipopt"
    x = ca.MX.sym("x", nz)
    p = ca.MX.sym("p", n_p)
    g = total_mass_constraint(model, params, x, total_mass)
    ng = g.shape[0]
    callbacks = _callbacks(rj, nz, n_p, ng, ipopt, r_only)
    named = {cb.name(): cb for cb in callbacks}
    opts = solver_config.nlpsol_options()
    if ipopt:
        _ipopt_numeric_options(opts, solver_config, named)
    else:
        gx = ca.jacobian(g, x)
        jac_fg = ca.Function("jac_fg", [x, p], [*named["grad_f"](x, p), g, gx],
                             ["x", "p"], ["f", "grad", "g", "jac_g"])
        callbacks.append(jac_fg)
        opts["jac_fg"] = jac_fg
    opts["hess_lag"] = named["hess_lag"]
    opts["calc_lam_p"] = False  # d f / d p is never used; the callbacks have no derivatives
    obj_fn = named["objective"]
    solver = ca.nlpsol("updater", solver_config.name,
                       {"x": x, "p": p, "f": obj_fn(x, p), "g": g}, opts)
    # screen_def None: already stops at 1e-5 (above)
    # r and J straight from Python: a CasADi callback would copy J into a DM whose dense
    # sparsity alone holds n_r x n_z row indices (2.7 GB at 164k residuals x 2,049
    # parameters) and cost 6x the evaluation itself at n = 64 (measured)
    return BuiltNLP(obj_fn=obj_fn, resjac_fn=rj, solver=solver, ng=ng,
                    callbacks=callbacks)
