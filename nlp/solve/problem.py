"""The updating problem of Eqn 25 as a CasADi NLP, built once, solved many times.

    minimise   f(z) = 1/2 sum_k sum_c r_kc(z)^2                     (25a)
    subject to lbx <= z <= ubx                                        (25e)
               1^T M(z) 1 = m_total        (only with a total-mass anchor)

with theta = T z + c (:mod:`nlp.model.parameters`), M, K from Eqns 23-24, C from a
damping model that is SPD for every theta (25f), and the FRF of Eqns 2-5 at
each selected frequency. Residual forms (per channel c, frequency k, weight w):

    log_magnitude   r = w (ln|H_a| - ln|H_x|)
    magnitude       r = w (|H_a| - |H_x|) / rms_c|H_x|    (the paper's Eqn 25a)
    complex         r = w [Re, Im] (H_a - H_x) / |H_x|

The FRF backend (:mod:`nlp.frf.backends`) decides how r and J are computed.
Dense: how it is built (measured, see DEVELOPERS.md fact 3): the residuals of one
frequency and their Jacobian are an SX function of (z, w, data), mapped over
the frequency grid; the objective, gradient and Hessian functions are
generated as one C file (the per-frequency code once, the maps as loops),
compiled once and cached. IPOPT and sqpmethod receive the
gradient J^T r and the Gauss-Newton Hessian J^T J of the least-squares
objective. Everything that changes between solves (start point, data, bounds)
enters as numbers; nothing symbolic is rebuilt per start. Sparse and reduced:
one numeric evaluation of r and J (sparse factorisations, adjoint
sensitivities) per point, handed to the same NLP as CasADi callbacks.
"""

from dataclasses import dataclass, field
import time

import casadi as ca
import numpy as np

from nlp.case.schema import RESIDUALS, SOLVERS
from nlp.solve.codegen import compile_library
from nlp.frf.reference import BASE_DOF
from nlp.frf.backends import choose as choose_backend
from nlp.frf.backends.dense import frf_symbolic
from nlp.frf.backends.sparse import SparseFRF
from nlp.frf.backends.system import LinearSystem
from nlp.solve.polish import MAX_PARAMETERS, newton_polish

__all__ = ["Channel", "Target", "SolverConfig", "LocalResult",
           "UpdatingProblem"]


SCREEN_TOL = 1e-5  # IPOPT tol of screening solves (the default tol is 1e-8)
# A point is stationary when a Gauss-Newton step would lower the chi-square 2 f by less than
# this: every parameter step below ~1e-3 of its standard error. IPOPT's absolute tolerance on
# the gradient cannot be met where the misfit is large (a model missing physics: f ~ 4e4 left
# |grad f| at 5e-4 after 3,000 iterations with f settled to 12 digits), so such solves crawl
# to max_iter; they stop here instead, and count as converged.
STATIONARY = 1e-6
STATIONARY_EVERY = 10   # IPOPT iterations between two stationarity checks ...
STATIONARY_FROM = 50    # ... from this iteration on (a solve that converges sooner pays nothing)

_DEFAULT_OPTIONS = {
    "ipopt": {"ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.tol": 1e-8,
              "ipopt.acceptable_tol": 1e-6, "ipopt.mu_strategy": "adaptive",
              "ipopt.max_iter": 500, "print_time": False},
    "sqpmethod": {"qpsol": "qrqp", "qpsol_options": {"print_iter": False, "print_header": False,
                                                     "print_info": False, "error_on_fail": False},
                  "print_header": False, "print_iteration": False, "print_status": False,
                  "max_iter": 200, "max_iter_ls": 20, "tol_du": 1e-10, "tol_pr": 1e-10,
                  "min_step_size": 1e-14,
                  "print_time": False, "error_on_fail": False},
}


@dataclass(frozen=True)
class Channel:
    """A measured response: its name, 0-based DOF and output quantity.

    ``dof == BASE_DOF`` (-1): a sensor on the base (floor 0). For a rigid base
    its absolute acceleration is the ground input (absolute accelerance 1);
    with a ``base_flexibility`` enrichment it is the base DOF's."""

    name: str
    dof: int
    output: str = "receptance"


@dataclass(frozen=True)
class Target:
    """Experimental FRFs at the frequencies used in the objective.

    omega : (N,) rad/s; H : (n_ch, N) complex; weight : (n_ch, N), 0 where a
    channel's point is not used; excitation ``"ground"`` or ``"force"`` with
    ``force_dof`` (0-based); ``ground_r`` (n,) the influence vector of the
    ground motion (1 on the DOFs it moves; None: every DOF, a shear frame);
    ``kernel`` (h [rad/s], a): the data are a windowed average, so the model is
    compared as the estimator sees it, a H(w - h) + (1 - 2a) H(w) + a H(w + h)
    (:func:`nlp.frf.noise.smoothing_taps`; dense backend only).
    """

    omega: np.ndarray
    H: np.ndarray
    weight: np.ndarray
    channels: tuple
    excitation: str = "ground"
    force_dof: int = None
    ground_r: np.ndarray = None
    kernel: tuple = None


@dataclass(frozen=True)
class SolverConfig:
    """Local NLP solver: CasADi plugin name and options passed through."""

    name: str = "ipopt"
    options: dict = field(default_factory=dict)
    compile: bool = True
    optimize: bool = True  # False: -O0 C, quicker to build, for a few solves (codegen)

    def nlpsol_options(self):
        opts = {k: (dict(v) if isinstance(v, dict) else v)
                for k, v in _DEFAULT_OPTIONS[self.name].items()}
        for key, value in self.options.items():
            if self.name == "ipopt" and not key.startswith("ipopt.") and key not in opts \
                    and key not in ("print_time", "expand"):
                key = "ipopt." + key
            if isinstance(value, dict) and isinstance(opts.get(key), dict):
                opts[key].update(value)
            else:
                opts[key] = value
        return opts


@dataclass(frozen=True)
class LocalResult:
    """One local solve: decision vector, objective and solver statistics."""

    z: np.ndarray
    f: float
    success: bool
    status: str
    iterations: int
    seconds: float
    z0: np.ndarray = None


class UpdatingProblem:
    """Eqn 25 for one model, damping model, parameter set and data set.

    Parameters
    ----------
    model : nlp.model.nominal.StructuralModel
    damping : a damping model from :mod:`nlp.model.damping`
    params : nlp.model.parameters.ParameterSet
    target : Target
    residual : {"log_magnitude", "magnitude", "complex"}
    solver : SolverConfig
    total_mass : float, optional
        Anchor 1^T M 1 = total_mass [kg] (an equality constraint).
    enrichments : sequence of :mod:`nlp.diagnosis.families` families
        Added physics; their parameters are the last ("physics") entries of
        ``params``, in the same order. refs : reference values they scale by.
    frf_backend : {"auto", "dense", "sparse", "reduced"}
        See :mod:`nlp.frf.backends`; ``reduced`` needs ``basis``.
    basis : (n, m) ndarray, optional
        The reduced backend's fixed basis Psi (:func:`nlp.frf.backends.reduced.basis`).
    """

    def __init__(self, model, damping, params, target, residual="log_magnitude",
                 solver=SolverConfig(), total_mass=None, enrichments=(), refs=None,
                 frf_backend="auto", basis=None):
        if residual not in RESIDUALS:
            raise ValueError(f"residual must be one of {RESIDUALS}, got {residual!r}")
        if solver.name not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver.name!r}")
        self.model, self.damping, self.params = model, damping, params
        self.target, self.residual, self.solver_config = target, residual, solver
        self.total_mass = total_mass
        self.enrichments, self.refs = tuple(enrichments), dict(refs or {})
        self.reduced_info = None
        self.backend = choose_backend(frf_backend, model.n, self.enrichments)
        if target.kernel is not None and self.backend != "dense":
            raise ValueError("Target.kernel (a windowed estimate) needs the dense FRF backend")
        self._p = self._pack_data(target)
        if self.backend == "dense":
            self._build_symbolic()
            self._build_nlp()
        else:
            if self.backend == "reduced" and basis is None:
                raise ValueError("the reduced backend needs a basis")
            self._build_numeric(basis if self.backend == "reduced" else None)

    # ------------------------------------------------------------------ build
    def _model_matrices(self, z):
        """Base M, K, C and the full system (with added physics) as SX."""
        theta = ca.mtimes(ca.DM(self.params.T), z) + ca.DM(self.params.c)
        sa, sb, sd = self.params.slices()
        M, K = self.model.matrices(theta[sa], theta[sb])
        M, K = ca.SX(M), ca.SX(K)
        C = ca.SX(self.damping.matrix(theta[sd], M, K))
        n = self.model.n
        system = {"M": M, "K": K, "C": C, "Kh": ca.SX.zeros(n, n)}
        ref = {**self.refs, "K_parts": [(1 + theta[sa][r]) * ca.DM(Kr)
                                        for r, Kr in enumerate(self.model.K_infl)]}
        th = theta[self.params.physics_slice()]
        k = 0
        self._sensor = {}
        self._base_dof = None
        for e in self.enrichments:
            th_e = th[k:k + len(e.names)]
            k += len(e.names)
            if e.family == "base_flexibility":  # the DOF it appends is the base
                self._base_dof = system["M"].shape[0]
            if hasattr(e, "apply"):
                system = e.apply(system, th_e, ref)
            else:
                self._sensor.setdefault(e.channel, []).append((e, th_e))
        return M, K, C, system

    def _build_symbolic(self):
        nz = self.params.n_z
        n_ch = len(self.target.channels)
        z = ca.SX.sym("z", nz)
        w = ca.SX.sym("w")
        yr, yi, s, wt = (ca.SX.sym(nm, n_ch) for nm in ("yr", "yi", "s", "wt"))
        M, K, C, system = self._model_matrices(z)
        self.matrices_fn = ca.Function("matrices", [z], [M, K, C], ["z"], ["M", "K", "C"])
        Ma, Ka, Ca, Kh = (system[k] for k in ("M", "K", "C", "Kh"))
        self.system_fn = ca.Function("system", [z], [Ma, Ka, Ca], ["z"], ["M", "K", "C"])
        if self.target.excitation == "ground":
            r = ca.DM.ones(Ma.shape[0]) if self.target.ground_r is None else \
                ca.vertcat(ca.DM(self.target.ground_r), ca.DM.zeros(Ma.shape[0] - self.model.n))
            b = -ca.mtimes(Ma, r)  # Eqn 16, with r for models with several DOFs per node
        else:
            b = ca.DM.zeros(Ma.shape[0])
            b[self.target.force_dof] = 1
        kh = Kh if self.enrichments else None

        def outputs(wv):
            """Every channel's FRF (real, imaginary parts) at the frequency wv."""
            cache, o_r, o_i = {}, [], []
            for ch in self.target.channels:
                if ch.output not in cache:
                    cache[ch.output] = frf_symbolic(Ma, Ca, Ka, wv, b, ch.output, kh)
                if ch.dof == BASE_DOF and self._base_dof is None:  # rigid base: the ground's
                    hr = ca.SX(1.0 if ch.output == "absolute_accelerance" else 0.0)
                    hi = ca.SX(0.0)
                else:
                    row = self._base_dof if ch.dof == BASE_DOF else ch.dof
                    hr, hi = cache[ch.output][0][row], cache[ch.output][1][row]
                for e, th_e in self._sensor.get(ch.name, ()):
                    hr, hi = e.output(hr, hi, wv, th_e)
                o_r.append(hr)
                o_i.append(hi)
            return o_r, o_i

        if self.target.kernel is None:
            out_r, out_i = outputs(w)
        else:
            # the windowed average's expected value: the FRF smoothed by the window's kernel
            h, a = self.target.kernel
            taps = [(a, outputs(w - h)), (1 - 2 * a, outputs(w)), (a, outputs(w + h))]
            out_r = [sum(g * o[0][c] for g, o in taps) for c in range(n_ch)]
            out_i = [sum(g * o[1][c] for g, o in taps) for c in range(n_ch)]
        res = []
        for c, ch in enumerate(self.target.channels):
            hr, hi = out_r[c], out_i[c]
            if self.residual == "log_magnitude":
                res.append(wt[c] * 0.5 * (ca.log(hr**2 + hi**2) - ca.log(yr[c]**2 + yi[c]**2)))
            elif self.residual == "magnitude":
                res.append(wt[c] * (ca.sqrt(hr**2 + hi**2) - ca.sqrt(yr[c]**2 + yi[c]**2)) / s[c])
            else:
                res += [wt[c] * (hr - yr[c]) / s[c], wt[c] * (hi - yi[c]) / s[c]]
        r = ca.vertcat(*res)
        self.frf_fn = ca.Function("channel_frf", [z, w], [ca.vertcat(*out_r), ca.vertcat(*out_i)],
                                  ["z", "w"], ["Hr", "Hi"])
        args = [z, w, yr, yi, s, wt]
        names = ["z", "w", "yr", "yi", "s", "wt"]
        res_fn = ca.Function("frf_res", args, [r], names, ["r"])
        JT = ca.jacobian(r, z).T
        resjac_fn = ca.Function("frf_resjac", args, [r, JT], names, ["r", "JT"])
        # per-frequency terms of f, J^T r and triu(J^T J), summed over frequencies by the map
        fg_fn = ca.Function("frf_fg", args, [0.5 * ca.sumsqr(r), ca.mtimes(JT, r)], names,
                            ["f", "g"])
        gn_fn = ca.Function("frf_gn", args, [ca.triu(ca.mtimes(JT, JT.T))], names, ["H"])
        self.n_res = r.shape[0]
        self._res_fn, self._resjac_fn = res_fn, resjac_fn
        self._fg_fn, self._gn_fn = fg_fn, gn_fn

    def _pack_data(self, target):
        H = np.asarray(target.H, dtype=complex)
        wt = np.asarray(target.weight, dtype=float)
        used = wt > 0
        Hs = np.where(used, H, 1.0)  # unused points: harmless finite data
        mag = np.abs(Hs)
        if self.residual == "magnitude":
            rms = np.array([np.sqrt(np.mean(mag[c, used[c]] ** 2)) if used[c].any() else 1.0
                            for c in range(H.shape[0])])
            s = np.repeat(rms[:, None], H.shape[1], axis=1)
        elif self.residual == "complex":
            s = mag
        else:
            s = np.ones_like(mag)
        self.n_used = int(used.sum()) * (2 if self.residual == "complex" else 1)
        return np.concatenate([np.asarray(target.omega, float).ravel(),
                               *(a.ravel(order="F") for a in (Hs.real, Hs.imag, s, wt))])

    def _unpack(self, p):
        N = self.target.omega.size
        n_ch = len(self.target.channels)
        W = ca.reshape(p[:N], 1, N)
        blocks = [ca.reshape(p[N + i * n_ch * N: N + (i + 1) * n_ch * N], n_ch, N) for i in range(4)]
        return W, *blocks

    def _build_nlp(self):
        N = self.target.omega.size
        nz = self.params.n_z
        x = ca.MX.sym("x", nz)
        p = ca.MX.sym("p", self._p.size)
        data = self._unpack(p)
        R = self._res_fn.map(N, "serial")(x, *data)
        R2, JT = self._resjac_fn.map(N, "serial")(x, *data)
        rv = ca.vec(R2)
        # f, gradient J^T r and Gauss-Newton Hessian J^T J, summed inside the maps
        fk, grad = self._fg_fn.map("fg_sum", "serial", N, [0], [0, 1])(x, *data)
        gn_triu = self._gn_fn.map("gn_sum", "serial", N, [0], [0])(x, *data)
        lam_f = ca.MX.sym("lam_f")
        M, _, _ = self.matrices_fn(x)
        g = ca.sum1(ca.sum2(M)) - self.total_mass if self.total_mass is not None else ca.MX(0, 1)
        lam_g = ca.MX.sym("lam_g", g.shape[0])
        obj = ca.Function("objective", [x, p], [0.5 * ca.sumsqr(R)], ["x", "p"], ["f"])
        fns = [obj, obj.jacobian(),
               ca.Function("residuals", [x, p], [rv, JT.T], ["x", "p"], ["r", "J"])]
        if self.solver_config.name == "ipopt":
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
        self.compiled = False
        if self.solver_config.compile:
            # One C file: the per-frequency SX code once, the maps as C loops.
            lib = compile_library(fns, stem=f"frfnlp_n{self.model.n}_N{N}",
                                  optimize=self.solver_config.optimize)
            if lib is not None:
                # "objective" finds its derivative "jac_objective" in the library
                fns = [ca.external(f.name(), lib) for f in fns if f.name() != "jac_objective"]
                self.compiled = True
        named = {f.name(): f for f in fns}
        self.obj_fn, self.resjac_fn = named["objective"], named["residuals"]
        opts = self.solver_config.nlpsol_options()
        for key in ("grad_f", "jac_fg", "hess_lag"):
            if key in named:
                opts[key] = named[key]
        nlp = {"x": x, "p": p, "f": self.obj_fn(x, p), "g": g}
        if self.solver_config.name == "ipopt":
            self._stop = _StopWhenStationary(self, nz, g.shape[0], self._p.size)
            opts["iteration_callback"] = self._stop
            opts["iteration_callback_step"] = STATIONARY_EVERY
        self._solver = ca.nlpsol("updater", self.solver_config.name, nlp, opts)
        self._screen_solver = None
        user = {k if k.startswith("ipopt.") else "ipopt." + k for k in self.solver_config.options}
        # a screening solver only when the tolerance is ours to choose
        self._screen_def = (nlp, {**opts, "ipopt.tol": SCREEN_TOL}) \
            if self.solver_config.name == "ipopt" and "ipopt.tol" not in user else None
        self.ng = g.shape[0]
        self._batch = {}

    def _data(self, p):
        """(w, yr, yi, s, wt) arrays from the packed data vector."""
        N = self.target.omega.size
        n_ch = len(self.target.channels)
        p = np.asarray(p, float).ravel()
        blocks = [p[N + i * n_ch * N: N + (i + 1) * n_ch * N].reshape(n_ch, N, order="F")
                  for i in range(4)]
        return (p[:N], *blocks)

    def _build_numeric(self, basis):
        """Sparse or reduced backend: r and J from SparseFRF, the NLP's functions as callbacks."""
        system = LinearSystem.from_model(self.model, self.damping, self.target)
        if basis is not None:
            system = system.project(basis)
        self.evaluator = ev = SparseFRF(system, self.damping, self.params, self.target,
                                        self.residual)
        nz, npar = self.params.n_z, self._p.size
        N = self.target.omega.size
        self.n_res = len(self.target.channels) * (2 if self.residual == "complex" else 1)
        n_r = self.n_res * N
        ipopt = self.solver_config.name == "ipopt"

        def rj(x, p):
            return ev.cached(x, p.tobytes(), self._data(p))

        def f_only(x, p):
            # with J too: IPOPT asks for the gradient at the point it accepts, and the
            # adjoint solves cost little next to the factorisations
            r, _ = rj(x, p)
            return 0.5 * float(r @ r)

        def grad(x, p):
            r, J = rj(x, p)
            return 0.5 * float(r @ r), J.T @ r

        def hess(x, p, lam_f, lam_g):
            _, J = rj(x, p)
            H = float(np.ravel(lam_f)[0]) * (J.T @ J)
            return np.triu(H) if ipopt else H

        dense = ca.Sparsity.dense
        hsp = ca.Sparsity.upper(nz) if ipopt else dense(nz, nz)
        x = ca.MX.sym("x", nz)
        p = ca.MX.sym("p", npar)
        sa, sb, sd = self.params.slices()
        theta = ca.mtimes(ca.DM(self.params.T), x) + ca.DM(self.params.c)
        if self.total_mass is not None:  # 1^T M 1 is linear in beta (Eqn 24)
            s0 = float(self.model.M0.sum())
            sr = ca.DM([float(A.sum()) for A in self.model.M_infl])
            g = s0 + ca.dot(sr, theta[sb]) - self.total_mass if sr.numel() else ca.MX(s0 - self.total_mass)
        else:
            g = ca.MX(0, 1)
        ng = g.shape[0]
        grad_cb = _Callback("grad_f", lambda a: list(grad(*a)), [dense(nz, 1), dense(npar, 1)],
                            [dense(1, 1), dense(nz, 1)])
        self._callbacks = [
            grad_cb,
            # CasADi asks once for df/dx, df/dp (the final multipliers): grad_f answers
            _Callback("objective", lambda a: [f_only(*a)], [dense(nz, 1), dense(npar, 1)],
                      [dense(1, 1)], gradient=grad_cb),
            _Callback("hess_lag", lambda a: [hess(*a)],
                      [dense(nz, 1), dense(npar, 1), dense(1, 1), dense(ng, 1)], [hsp]),
            _Callback("residuals", lambda a: list(rj(*a)), [dense(nz, 1), dense(npar, 1)],
                      [dense(n_r, 1), dense(n_r, nz)]),
        ]
        named = {cb.name(): cb for cb in self._callbacks}
        self.obj_fn, self.resjac_fn = named["objective"], named["residuals"]
        opts = self.solver_config.nlpsol_options()
        if ipopt:
            opts["grad_f"] = named["grad_f"]
            # Round-off of the numeric gradient (~1e-8 of its starting norm, more at
            # thousands of DOFs) keeps the scaled dual infeasibility at 1e-7..3e-6 at the
            # optimum; IPOPT then backtracks ~37 times per iteration on a flat objective for
            # 10-15 iterations (measured at n = 256 and 2,000). Stop at a scaled error of 1e-5
            # (the first time) and let the watchdog take over after 3 shortened steps.
            user = {k if k.startswith("ipopt.") else "ipopt." + k for k in self.solver_config.options}
            for key, value in (("ipopt.acceptable_iter", 1), ("ipopt.acceptable_tol", 1e-5),
                               ("ipopt.watchdog_shortened_iter_trigger", 3)):
                if key not in user:
                    opts[key] = value
        else:
            gx = ca.jacobian(g, x)
            jac_fg = ca.Function("jac_fg", [x, p], [*named["grad_f"](x, p), g, gx],
                                 ["x", "p"], ["f", "grad", "g", "jac_g"])
            self._callbacks.append(jac_fg)
            opts["jac_fg"] = jac_fg
        opts["hess_lag"] = named["hess_lag"]
        opts["calc_lam_p"] = False  # d f / d p is never used; the callbacks have no derivatives
        self.compiled = False
        self._solver = ca.nlpsol("updater", self.solver_config.name,
                                 {"x": x, "p": p, "f": self.obj_fn(x, p), "g": g}, opts)
        self._screen_solver = self._screen_def = None  # already stops at 1e-5 (above)
        self.ng = ng
        self._batch = {}
        self.matrices_fn = self.system_fn = None

    def describe(self):
        """One line: which FRF backend runs and how."""
        if self.backend == "dense":
            return "dense FRF backend, " + ("compiled C" if self.compiled else "CasADi virtual machine")
        ev = self.evaluator
        how = ("batched dense LU" if ev.batched else
               f"banded LU, half-bandwidth {ev.bandwidth}" if ev.banded else "SuperLU")
        how += f", {ev.n} + {ev.m} unknowns"
        text = f"{self.backend} FRF backend ({how}, adjoint sensitivities)"
        info = getattr(self, "reduced_info", None)
        if info:
            text += (f"; {info['vectors']} basis vectors, RMS ln|H| error {info['rms_log_error']:.2g}"
                     f" vs noise {info['noise']:.2g} at {info['points_checked']} of the case's"
                     f" frequencies")
        return text

    # ------------------------------------------------------------- numerics
    @property
    def z0(self):
        return self.params.z0

    @property
    def bounds(self):
        return self.params.z_bounds

    def objective(self, z):
        """f(z) = 1/2 ||r(z)||^2."""
        return float(self.obj_fn(np.asarray(z, float), self._p))

    def objective_batch(self, Z):
        """f at each column of Z (n_z, n_points), evaluated in one compiled loop."""
        Z = np.atleast_2d(np.asarray(Z, float))
        n = Z.shape[1]
        if self.backend != "dense":  # residuals only: no adjoint solves for trial points
            data = self._data(self._p)
            rs = (self.evaluator.residuals(Z[:, i], data, jacobian=False)[0] for i in range(n))
            return np.array([0.5 * float(r @ r) for r in rs])
        if n not in self._batch:
            self._batch[n] = self.obj_fn.map(n, "serial")
        return np.asarray(self._batch[n](Z, self._p)).ravel()

    def constraint_jacobian(self):
        """dg/dz (n_g, n_z) of the equality constraints: the total-mass anchor
        1^T M 1 = m_total, linear in beta (Eqn 24), or none (0, n_z)."""
        T = self.params.T
        if self.total_mass is None:
            return np.zeros((0, T.shape[1]))
        _, sb, _ = self.params.slices()
        sr = np.array([float(A.sum()) for A in self.model.M_infl])
        if sr.size == 0:
            return np.zeros((0, T.shape[1]))
        return (sr @ T[sb, :])[None, :]

    def residuals(self, z):
        """Residual vector r and Jacobian J = dr/dz at z."""
        r, J = self.resjac_fn(np.asarray(z, float), self._p)
        return np.asarray(r).ravel(), np.asarray(J)

    def matrices(self, z):
        """Numeric M, K, C at z (dense arrays)."""
        if self.matrices_fn is None:
            theta = self.theta(z)
            sa, sb, sd = self.params.slices()
            M, K = self.model.matrices(theta[sa], theta[sb])
            C = self.damping.matrix(theta[sd], M, K)
            return tuple(np.asarray(A.toarray() if hasattr(A, "toarray") else A, float)
                         for A in (M, K, C))
        M, K, C = self.matrices_fn(np.asarray(z, float))
        return np.asarray(M), np.asarray(K), np.asarray(C)

    def system_matrices(self, z):
        """Numeric M, K, C of the whole system at z, with the DOFs the added physics appends
        (an appendage's, a flexible base's) after the model's; the model's own M, K, C
        (:meth:`matrices`) when the FRF backend is numeric."""
        if self.system_fn is None:
            return self.matrices(z)
        return tuple(np.asarray(A) for A in self.system_fn(np.asarray(z, float)))

    def theta(self, z):
        return self.params.theta(np.asarray(z, float))

    def channel_frfs(self, z, omega):
        """The model's FRF of every channel (with added physics) at omega: (n_ch, N)."""
        if self.backend != "dense":
            return self.evaluator.frf(np.asarray(z, float), np.asarray(omega, float))
        key = ("frf", len(omega))
        if key not in self._batch:  # one map per grid size, built once
            self._batch[key] = self.frf_fn.map(len(omega))
        Hr, Hi = self._batch[key](np.asarray(z, float), np.asarray(omega, float)[None, :])
        return np.asarray(Hr) + 1j * np.asarray(Hi)

    @property
    def can_screen(self):
        """Does :meth:`solve` offer a screening tolerance (IPOPT, tol not set by the case)?"""
        return getattr(self, "_screen_def", None) is not None

    # Newton polish where IPOPT ends unconverged; off for solves capped on purpose below
    # the case's iteration limit (candidate refits that only bound their optimum)
    polish_unconverged = True

    def solve(self, z0=None, screen=False, bounds=None):
        """One local solve from z0 (default: the case's initial point).

        screen : stop at IPOPT's scaled error ``SCREEN_TOL`` (1e-5) instead of the
            case's tolerance (1e-8), when :attr:`can_screen`. The scatter search
            screens its starts this way and polishes the best ones with the full
            tolerance (:func:`nlp.solve.search.scatter_search`).
        bounds : optional (lower, upper) on z in place of :attr:`bounds`: equal ones hold a
            variable, so nested models share one compiled problem.
        """
        z0 = self.z0 if z0 is None else np.asarray(z0, float)
        lo, hi = self.bounds if bounds is None else bounds
        z0c = np.clip(z0, lo, hi)
        g0 = np.zeros(self.ng)
        solver = self._solver
        if screen and self.can_screen:
            if self._screen_solver is None:  # built once per process, on first use
                nlp, opts = self._screen_def
                self._screen_solver = ca.nlpsol("screen", self.solver_config.name, nlp, opts)
            solver = self._screen_solver
        if getattr(self, "_stop", None) is not None:
            self._stop.calls = 0
        t0 = time.perf_counter()
        sol = solver(x0=z0c, p=self._p, lbx=lo, ubx=hi, lbg=g0, ubg=g0)
        st = solver.stats()
        status = str(st.get("return_status", "unknown"))
        iters = int(st.get("iter_count", -1))
        z = np.asarray(sol["x"]).ravel()
        success = bool(st.get("success", False))
        f = float(sol["f"])
        if not success and status in ("User_Requested_Stop", "Maximum_Iterations_Exceeded",
                                      "Maximum_CpuTime_Exceeded", "Search_Direction_Becomes_Too_Small",
                                      "Solved_To_Acceptable_Level"):
            dec = self.gn_decrement(z)
            if dec < STATIONARY:
                success, status = True, f"Stationary (Gauss-Newton decrement {dec:.1e})"
            elif self.polish_unconverged and self.params.n_z <= MAX_PARAMETERS and np.isfinite(f):
                # J^T J misses the curvature of large residuals: finish with full Newton
                # steps from where IPOPT ended. Not earlier: on blind 824513/42's shared-
                # stiffness fit, stopping IPOPT once f fell by < 0.05 per 100 iterations and
                # polishing gave a minimum at f 471.8; IPOPT's creep to its limit, 411.9
                z, f, success, status = self._polish(z, f, lo, hi, status)
        seconds = time.perf_counter() - t0
        return LocalResult(z=z, f=f, success=success, status=status,
                           iterations=iters, seconds=seconds, z0=z0c)

    def _polish(self, z, f, lo, hi, status):
        """Newton steps on the full Hessian where the Gauss-Newton solver stopped short of a
        stationary point (:mod:`nlp.solve.polish`); the start is kept unless they reach one."""
        def fg(x):
            r, J = self.residuals(x)
            return 0.5 * float(r @ r), J.T @ r

        G = self.constraint_jacobian()
        try:
            zp, fp, dec, ok, steps = newton_polish(fg, z, lo, hi, G if G.size else None)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            return z, f, False, status
        if ok and fp <= f:
            return zp, fp, True, f"Stationary after {steps} Newton steps (decrement {dec:.1e})"
        return z, f, False, status

    def gn_decrement(self, z):
        """Chi-square decrease a Gauss-Newton step from z would give: g^T (J^T J)^+ g on the
        steps that keep the bounds active where the gradient presses on them and the
        total-mass anchor satisfied (g = J^T r; 2 f is the chi-square). Small means
        stationary, whatever the size of the misfit."""
        from nlp.solve.identify import tangent_basis
        z = np.asarray(z, float)
        r, J = self.residuals(z)
        g = J.T @ r
        if not np.all(np.isfinite(g)):
            return np.inf
        lo, hi = self.bounds
        near = 1e-7 * np.maximum(1.0, np.abs(z))
        free = ~(((z <= lo + near) & (g > 0)) | ((z >= hi - near) & (g < 0)))
        N = tangent_basis(self.constraint_jacobian()[:, free], int(free.sum()))
        JN, gN = J[:, free] @ N, N.T @ g[free]
        return float(gN @ np.linalg.pinv(JN.T @ JN) @ gN)


class _StopWhenStationary(ca.Callback):
    """IPOPT iteration callback: asks the solver to stop at a stationary point
    (:meth:`UpdatingProblem.gn_decrement` below :data:`STATIONARY`)."""

    def __init__(self, problem, nx, ng, np_):
        ca.Callback.__init__(self)
        self._problem, self._n = problem, {"x": nx, "lam_x": nx, "g": ng, "lam_g": ng,
                                           "f": 1, "lam_p": np_}
        self.calls = 0   # reset by UpdatingProblem.solve
        self.construct("stop_when_stationary", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "stop"

    def get_sparsity_in(self, i):
        n = self._n.get(ca.nlpsol_out(i), 0)
        return ca.Sparsity.dense(n, 1) if n else ca.Sparsity(0, 0)

    def eval(self, args):
        self.calls += 1
        if self.calls * STATIONARY_EVERY < STATIONARY_FROM:
            return [0]
        x = np.asarray(args[0], float).ravel()
        try:
            return [1 if self._problem.gn_decrement(x) < STATIONARY else 0]
        except Exception:  # an iterate where r cannot be evaluated: let IPOPT go on
            return [0]


class _Callback(ca.Callback):
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
