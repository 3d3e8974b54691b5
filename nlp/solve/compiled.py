"""The dense backend's NLP: per-frequency SX functions mapped over the grid, compiled to C.

The residuals of one frequency and their Jacobian (:mod:`nlp.solve.residuals`) are mapped
over the frequency grid; the objective, gradient J^T r and Gauss-Newton Hessian J^T J of
the least-squares objective are generated as one C file (the per-frequency code once, the
maps as loops), compiled once and cached (:mod:`nlp.solve.codegen`).
"""

from dataclasses import dataclass

import casadi as ca
import numpy as np

from nlp.solve.codegen import compile_library
from nlp.solve.residuals import data_symbols
from nlp.solve.stopping import SCREEN_TOL, STATIONARY_EVERY, StopWhenStationary

__all__ = ["BuiltNLP", "user_ipopt_keys", "build_compiled_nlp"]


@dataclass
class BuiltNLP:
    """What a backend hands to :class:`nlp.solve.problem.UpdatingProblem`."""

    obj_fn: object            # (x, p) -> f
    resjac_fn: object         # (x, p) -> r, J
    solver: object            # the nlpsol
    ng: int                   # equality constraints
    compiled: bool = False    # C code (dense) or the CasADi virtual machine
    screen_def: tuple = None  # (nlp, options) of a screening solver, built on first use
    stop: object = None       # the stationarity callback, when IPOPT runs
    callbacks: list = None    # Python callbacks to keep alive (numeric backends)


class BufferedFunction:
    """A CasADi function of dense inputs evaluated into numpy arrays held by it (CasADi's
    buffer interface). A DM result reaches numpy through a Python list, about 100 ns per
    entry: a Jacobian of 240,000 entries took 26 ms to convert after 3 ms to evaluate, and
    the conversions were a fifth of a diagnosis (py-spy). Returns fresh arrays. One call at a
    time, as the solver objects it sits beside (one per worker process)."""

    def __init__(self, f):
        self.f = f
        self._buf, self._eval = f.buffer()
        self._args = [np.zeros(f.nnz_in(i)) for i in range(f.n_in())]
        self._res = [np.zeros(f.nnz_out(i)) for i in range(f.n_out())]
        for i, a in enumerate(self._args):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._res):
            self._buf.set_res(i, memoryview(r))
        # (shape, None) for a dense output, else (shape, (rows, cols) of its nonzeros)
        self._out = []
        for i in range(f.n_out()):
            sp = f.sparsity_out(i)
            self._out.append((sp.shape, None if sp.is_dense() else sp.get_triplet()))

    def __call__(self, *args):
        for a, v in zip(self._args, args):
            a[:] = np.asarray(v, float).ravel(order="F")
        self._eval()
        return [self._full(shape, rc, r) for (shape, rc), r in zip(self._out, self._res)]

    @staticmethod
    def _full(shape, rc, nz):
        if rc is None:
            return nz.reshape(shape, order="F").copy()
        out = np.zeros(shape)
        out[rc[0], rc[1]] = nz
        return out


def user_ipopt_keys(solver_config):
    """The IPOPT options the case sets, with their ``ipopt.`` prefix."""
    return {k if k.startswith("ipopt.") else "ipopt." + k for k in solver_config.options}


def _functions(ff, x, p, N, n_ch, total_mass, solver_name):
    """(functions to compile, g): objective, its Jacobian, residuals, and the gradient and
    Gauss-Newton Hessian in the form the solver takes; g the total-mass constraint."""
    data = data_symbols(p, N, n_ch)
    R = ff.res.map(N, "serial")(x, *data)
    R2, JT = ff.resjac.map(N, "serial")(x, *data)
    rv = ca.vec(R2)
    # f, gradient J^T r and Gauss-Newton Hessian J^T J, summed inside the maps
    fk, grad = ff.fg.map("fg_sum", "serial", N, [0], [0, 1])(x, *data)
    gn_triu = ff.gn.map("gn_sum", "serial", N, [0], [0])(x, *data)
    lam_f = ca.MX.sym("lam_f")
    M, _, _ = ff.matrices(x)
    g = ca.sum1(ca.sum2(M)) - total_mass if total_mass is not None else ca.MX(0, 1)
    lam_g = ca.MX.sym("lam_g", g.shape[0])
    obj = ca.Function("objective", [x, p], [0.5 * ca.sumsqr(R)], ["x", "p"], ["f"])
    fns = [obj, obj.jacobian(),
           ca.Function("residuals", [x, p], [rv, JT.T], ["x", "p"], ["r", "J"])]
    if solver_name == "ipopt":
        fns += [ca.Function("grad_f", [x, p], [fk, grad],
                            ["x", "p"], ["f", "grad"]),
                ca.Function("hess_lag", [x, p, lam_f, lam_g], [lam_f * gn_triu],
                            ["x", "p", "lam_f", "lam_g"], ["hess"])]
    else:
        gn = gn_triu + gn_triu.T - ca.diag(ca.diag(gn_triu))
        fns += [ca.Function("jac_fg", [x, p], [fk, grad, g, ca.jacobian(g, x)],
                            ["x", "p"], ["f", "grad", "g", "jac_g"]),
                ca.Function("hess_lag", [x, p, lam_f, lam_g], [lam_f * gn],
                            ["x", "p", "lam_f", "lam_g"], ["hess"])]
    return fns, g


def _compile(fns, stem, optimize):
    """(functions, compiled): the library's functions when a C compiler built it."""
    # One C file: the per-frequency SX code once, the maps as C loops.
    lib = compile_library(fns, stem=stem, optimize=optimize)
    if lib is None:
        return fns, False
    # "objective" finds its derivative "jac_objective" in the library
    return [ca.external(f.name(), lib) for f in fns if f.name() != "jac_objective"], True


def build_compiled_nlp(ff, target, n_z, n_p, n_dof, total_mass, solver_config, decrement):
    """The dense backend's NLP (:class:`BuiltNLP`).

    ff : :class:`nlp.solve.residuals.FrequencyFunctions`; n_z, n_p : sizes of z and of the
    data vector; n_dof : the model's DOFs (names the library); decrement : z -> the
    Gauss-Newton decrement, for the stationarity callback.
    """
    N = target.omega.size
    x = ca.MX.sym("x", n_z)
    p = ca.MX.sym("p", n_p)
    fns, g = _functions(ff, x, p, N, len(target.channels), total_mass, solver_config.name)
    compiled = False
    if solver_config.compile:
        fns, compiled = _compile(fns, f"frfnlp_n{n_dof}_N{N}", solver_config.optimize)
    named = {f.name(): f for f in fns}
    obj_fn = named["objective"]
    opts = solver_config.nlpsol_options()
    for key in ("grad_f", "jac_fg", "hess_lag"):
        if key in named:
            opts[key] = named[key]
    nlp = {"x": x, "p": p, "f": obj_fn(x, p), "g": g}
    stop = None
    if solver_config.name == "ipopt":
        stop = StopWhenStationary(decrement, n_z, g.shape[0], n_p)
        opts["iteration_callback"] = stop
        opts["iteration_callback_step"] = STATIONARY_EVERY
    solver = ca.nlpsol("updater", solver_config.name, nlp, opts)
    # a screening solver only when the tolerance is ours to choose
    screen_def = (nlp, {**opts, "ipopt.tol": SCREEN_TOL}) \
        if solver_config.name == "ipopt" and "ipopt.tol" not in user_ipopt_keys(solver_config) \
        else None
    return BuiltNLP(obj_fn=obj_fn, resjac_fn=BufferedFunction(named["residuals"]), solver=solver,
                    ng=g.shape[0], compiled=compiled, screen_def=screen_def, stop=stop)
