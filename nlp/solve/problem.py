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
frequency and their Jacobian are an SX function of (z, w, data)
(:mod:`nlp.solve.residuals`), mapped over the frequency grid and compiled to C
(:mod:`nlp.solve.compiled`). IPOPT and sqpmethod receive the
gradient J^T r and the Gauss-Newton Hessian J^T J of the least-squares
objective. Everything that changes between solves (start point, data, bounds)
enters as numbers; nothing symbolic is rebuilt per start. Sparse and reduced:
one numeric evaluation of r and J (sparse factorisations, adjoint
sensitivities) per point, handed to the same NLP as CasADi callbacks
(:mod:`nlp.solve.callbacks`). When a solve stops: :mod:`nlp.solve.stopping`.
"""

from dataclasses import dataclass, field
import time

import casadi as ca
import numpy as np

from nlp.frf.backends import choose as choose_backend
from nlp.frf.backends.sparse import SparseFRF
from nlp.frf.backends.system import LinearSystem
from nlp.frf.backends.terms import backend_terms, with_terms
from nlp.solve.callbacks import build_callback_nlp
from nlp.solve.compiled import build_compiled_nlp
from nlp.solve.lm import LM_STATIONARY, PREFIT_HANDOVER, levenberg_marquardt, lm_chosen
from nlp.solve.polish import MAX_PARAMETERS, newton_polish
from nlp.solve.prefit import PREFIT_FAR, PREFIT_MAX_ITER, PREFITS, prefit_residual
from nlp.solve.residuals import RESIDUALS, data_arrays, frequency_functions, pack_data
from nlp.solve.stopping import POLISH_AT, STATIONARY, decrement_normal, gauss_newton_decrement

__all__ = ["SOLVERS", "PREFITS", "PREFIT_MAX_ITER", "prefit_residual", "Channel", "Target", "SolverConfig", "LocalResult",
           "UpdatingProblem"]

SOLVERS = ("ipopt", "sqpmethod")


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
    with a ``base_flexibility`` enrichment it is the base DOF's.

    Several tests fitted jointly (data.tests) stack their channels: ``force_dof`` is then
    the channel's own test's driven DOF (None: the target's), and ``sensor`` the physical
    sensor's name (None: ``name``), which the sensor families (gain, delay) attach to, so
    one sensor has one gain in every test."""

    name: str
    dof: int
    output: str = "receptance"
    sensor: str = None
    force_dof: int = None

    @property
    def sensor_name(self):
        return self.name if self.sensor is None else self.sensor


@dataclass(frozen=True)
class Target:
    """Experimental FRFs at the frequencies used in the objective.

    omega : (N,) rad/s; H : (n_ch, N) complex; weight : (n_ch, N), 0 where a
    channel's point is not used; excitation ``"ground"`` or ``"force"`` with
    ``force_dof`` (0-based); ``ground_r`` (n,) the influence vector of the
    ground motion (1 on the DOFs it moves; None: every DOF, a shear frame);
    ``kernel`` (h [rad/s], a): the data are a windowed average, so the model is
    compared as the estimator sees it, a H(w - h) + (1 - 2a) H(w) + a H(w + h)
    (:func:`nlp.frf.kernel.smoothing_taps`; dense backend only).
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
    prefit_iterations: int = 0  # of the prefit solve (another residual) that started this one


class UpdatingProblem:
    """Eqn 25 for one model, damping model, parameter set and data set.

    Parameters
    ----------
    model : nlp.model.nominal.StructuralModel
    damping : a damping model from :mod:`nlp.model.damping`
    params : nlp.model.parameters.ParameterSet
    target : Target
    residual : {"log_magnitude", "magnitude", "relative_magnitude", "complex"}
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
        self.backend = choose_backend(frf_backend, model.n, self.enrichments, damping, target.channels)
        if target.kernel is not None and self.backend != "dense":
            raise ValueError("Target.kernel (a windowed estimate) needs the dense FRF backend")
        self._p, self.n_used = pack_data(target, residual)
        if self.backend == "dense":
            built = self._build_dense()
        else:
            if self.backend == "reduced" and basis is None:
                raise ValueError("the reduced backend needs a basis")
            built = self._build_numeric(basis if self.backend == "reduced" else None)
        self.obj_fn, self.resjac_fn = built.obj_fn, built.resjac_fn
        self._solver, self._screen_def, self._stop = built.solver, built.screen_def, built.stop
        self._callbacks = built.callbacks
        self._screen_solver = None  # built on first use (solve(screen=True))
        self.compiled, self.ng = built.compiled, built.ng
        self._batch = {}
        self.prefit = None  # an UpdatingProblem on another residual, solved first (prefit_residual)

    # ------------------------------------------------------------------ build
    def _build_dense(self):
        """Symbolic r and J per frequency (:mod:`nlp.solve.residuals`), compiled maps."""
        ff = frequency_functions(self.model, self.damping, self.params, self.target,
                                 self.residual, self.enrichments, self.refs)
        self.matrices_fn, self.system_fn, self.frf_fn = ff.matrices, ff.system, ff.channel_frf
        self.n_res = ff.n_res
        return build_compiled_nlp(ff, self.target, self.params.n_z, self._p.size, self.model.n,
                                  self.total_mass, self.solver_config,
                                  lambda z: self.gn_decrement(z))

    def _build_numeric(self, basis):
        """Sparse or reduced backend: r and J from SparseFRF, the NLP's functions as callbacks."""
        system = LinearSystem.from_model(self.model, self.damping, self.target)
        self.family_terms, terms = backend_terms(self.model, self.params, self.enrichments,
                                                 self.refs, self.target, basis, self.damping)
        if basis is not None:
            system = system.project(basis)
        self.evaluator = ev = SparseFRF(system, self.damping, self.params, self.target,
                                        self.residual, terms)
        self.matrices_fn = self.system_fn = None
        self.n_res = len(self.target.channels) * (2 if self.residual == "complex" else 1)

        def rj(x, p):
            return ev.cached(x, p.tobytes(), self._data(p))

        def r_only(x, p):
            return ev.cached_value(x, p.tobytes(), self._data(p))

        return build_callback_nlp(rj, self.model, self.params, self._p.size, self.total_mass,
                                  self.solver_config, r_only)

    def _data(self, p):
        """(w, yr, yi, s, wt) arrays from the packed data vector."""
        return data_arrays(p, self.target.omega.size, len(self.target.channels))

    @property
    def data_vector(self):
        """The packed data vector p of every solve (:func:`nlp.solve.residuals.pack_data`)."""
        return self._p

    def describe(self):
        """One line: which FRF backend runs and how."""
        if self.backend == "dense":
            return "dense FRF backend, " + ("compiled C" if self.compiled else "CasADi virtual machine")
        ev = self.evaluator
        how = ("dense: modal sums, else one LU per frequency" if ev.batched else f"banded LU, "
               f"half-bandwidth {ev.bandwidth}" if ev.banded else "SuperLU") + f", {ev.n} + {ev.m} unknowns"
        text = f"{self.backend} FRF backend ({how}, adjoint sensitivities)"
        info = getattr(self, "reduced_info", None)
        if info:
            text += f"; {info['vectors']} basis vectors, " + (
                "not checked against the exact FRF here" if info["rms_log_error"] is None else
                f"RMS ln|H| error {info['rms_log_error']:.2g} vs noise {info['noise']:.2g} at "
                f"{info['points_checked']} of the case's frequencies")
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
        (:meth:`matrices`, with the families' terms) when the FRF backend is numeric."""
        if self.system_fn is None:
            M, K, C = self.matrices(z)
            terms = getattr(self, "family_terms", None)
            return (M, K, C) if terms is None else with_terms(terms, self.theta(z), M, K, C)
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
        return self._screen_def is not None

    # Levenberg-Marquardt (nlp.solve.lm) on the numeric backends; None: the default,
    # above lm.LM_FROM free variables only (why: lm.lm_chosen)
    lm_prefit = None  # True: prefits by LM, handed over near their minimum
    lm_local = None   # True: every local solve by LM
    # Newton polish where IPOPT ends unconverged; off for refits capped on purpose
    polish_unconverged = True
    early_polish = False   # True (diagnosis fits, f half a chi-square): stop at POLISH_AT to polish

    def solve(self, z0=None, screen=False, bounds=None, prefit=True):
        """One local solve from z0 (default: the case's initial point).

        screen : stop at IPOPT's scaled error ``SCREEN_TOL`` (1e-5) instead of the
            case's tolerance (1e-8), when :attr:`can_screen`. The scatter search
            screens its starts this way and polishes the best ones with the full
            tolerance (:func:`nlp.solve.search.scatter_search`).
        bounds : optional (lower, upper) on z in place of :attr:`bounds` (equal ones hold a
            variable: nested models share one compiled problem).
        prefit : solve :attr:`prefit` first when there is one (False: a re-solve).
        """
        z0 = self.z0 if z0 is None else np.asarray(z0, float)
        lo, hi = self.bounds if bounds is None else bounds
        z0c = np.clip(z0, lo, hi)
        t0 = time.perf_counter()
        pre = self._prefit(z0c, bounds) if prefit else None
        if pre is not None and pre.status in PREFIT_FAR:
            # a prefit still moving after PREFIT_MAX_ITER iterations started in a far basin:
            # the start ends here, not after the case's whole iteration budget on ln|H|
            return LocalResult(z=pre.z, f=self.objective(pre.z), success=False,
                               status=f"prefit ({self.prefit.residual}): {pre.status}",
                               iterations=0, seconds=time.perf_counter() - t0, z0=z0c,
                               prefit_iterations=pre.iterations)
        z_start = z0c if pre is None else pre.z
        z, f, success, status, iters = self._local(z_start, lo, hi, screen, early=True)
        if self._stop is not None and self._stop.early:
            # Newton steps only from a convex point (docs/method/updating.md)
            z, f, success, status = self._polish(z, f, lo, hi, status, convex_start=True)
            if not success:
                z, f, success, status, more = self._local(z, lo, hi, screen)
                iters += more
        if not success and status in ("User_Requested_Stop", "Maximum_Iterations_Exceeded",
                                      "Maximum_CpuTime_Exceeded", "Search_Direction_Becomes_Too_Small",
                                      "Solved_To_Acceptable_Level"):
            dec = self.gn_decrement(z)
            if dec < STATIONARY:
                success, status = True, f"Stationary (Gauss-Newton decrement {dec:.1e})"
            elif self.polish_unconverged and self.params.n_z <= MAX_PARAMETERS and np.isfinite(f):
                # J^T J misses the curvature of large residuals: Newton steps finish it
                z, f, success, status = self._polish(z, f, lo, hi, status)
        seconds = time.perf_counter() - t0
        return LocalResult(z=z, f=f, success=success, status=status, iterations=iters,
                           seconds=seconds, z0=z0c,
                           prefit_iterations=0 if pre is None else pre.iterations)

    @property
    def uses_lm(self):
        """Are local solves Levenberg-Marquardt (:mod:`nlp.solve.lm`)? On the numeric
        backends with IPOPT chosen: IPOPT's undamped Gauss-Newton steps along the nearly
        null directions of J^T J of many-parameter fits (the top storeys of a tall frame:
        eigenvalue 2e-11 against 1e5) ran to steps of 0.004 and to its iteration limit."""
        return self.backend != "dense" and self.solver_config.name == "ipopt" and \
            lm_chosen(self.lm_local, self.params.n_z)

    def _local(self, z_start, lo, hi, screen, early=False):
        """(z, f, success, status, iterations) from z_start; early: may stop at POLISH_AT."""
        if self.uses_lm:
            res = self.solve_lm(z_start, (lo, hi))
            return res.z, res.f, res.success, res.status, res.iterations
        g0 = np.zeros(self.ng)
        solver = self._solver
        if screen and self.can_screen:
            if self._screen_solver is None:  # built once per process, on first use
                nlp, opts = self._screen_def
                self._screen_solver = ca.nlpsol("screen", self.solver_config.name, nlp, opts)
            solver = self._screen_solver
        if self._stop is not None:
            self._stop.calls, self._stop.early = 0, False
            self._stop.polish_at = POLISH_AT if (early and self.early_polish and self.polish_unconverged
                                                 and self.params.n_z <= MAX_PARAMETERS) else None
        sol = solver(x0=z_start, p=self._p, lbx=lo, ubx=hi, lbg=g0, ubg=g0)
        st = solver.stats()
        return (np.asarray(sol["x"]).ravel(), float(sol["f"]), bool(st.get("success", False)),
                str(st.get("return_status", "unknown")), int(st.get("iter_count", -1)))

    def _prefit(self, z0, bounds):
        """The prefit solve from z0 (:func:`prefit_residual`), or None: none set, or it
        failed (the case's residual then starts from z0 itself)."""
        if self.prefit is None:
            return None
        try:
            if lm_chosen(self.lm_prefit, self.params.n_z) and self.prefit.backend != "dense":
                pre = self.prefit.solve_lm(z0, bounds=bounds, tol=PREFIT_HANDOVER, handover=True)
            else:
                pre = self.prefit.solve(z0, screen=True, bounds=bounds)
        except (RuntimeError, np.linalg.LinAlgError, FloatingPointError):
            return None
        return pre if np.all(np.isfinite(pre.z)) and np.isfinite(pre.f) else None

    def normal_equations(self, z):
        """(f, J^T r, J^T J) at z; the numeric backends sum them per chunk of frequencies
        without holding J (:meth:`nlp.frf.backends.sparse.SparseFRF.normal_equations`)."""
        z = np.asarray(z, float)
        if self.backend == "dense":
            r, J = self.residuals(z)
            return 0.5 * float(r @ r), J.T @ r, J.T @ J
        r, g, A = self.evaluator.normal_equations(z, self._data(self._p))
        return 0.5 * float(r @ r), g, A

    def solve_lm(self, z0=None, bounds=None, tol=LM_STATIONARY, handover=False):
        """One Levenberg-Marquardt solve from z0 (:mod:`nlp.solve.lm`), as a LocalResult;
        its iteration limit is the solver's ``max_iter``, its stop ``tol`` (in s^2);
        ``handover``: a prefit, stopped near its minimum on the determined directions."""
        z0 = self.z0 if z0 is None else np.asarray(z0, float)
        lo, hi = self.bounds if bounds is None else bounds
        opts = self.solver_config.nlpsol_options()
        max_iter = int(opts.get("ipopt.max_iter", opts.get("max_iter", 500)))
        G, h = self.constraint_jacobian(), None
        if G.shape[0]:  # the total-mass anchor, G z = h (linear, Eqn 24)
            _, sb, _ = self.params.slices()
            sr = np.array([float(A.sum()) for A in self.model.M_infl])
            h = G @ z0 - (float(self.model.M0.sum()) + sr @ self.theta(z0)[sb] - self.total_mass)
        t0 = time.perf_counter()
        res = levenberg_marquardt(self.normal_equations, self.objective, z0, lo, hi,
                                  self.n_used - self.params.n_z, max_iter=max_iter,
                                  G=G if G.shape[0] else None, h=h, tol=tol,
                                  undetermined=not handover)
        return LocalResult(z=res.z, f=res.f, success=res.success, status=res.status,
                           iterations=res.iterations, seconds=time.perf_counter() - t0,
                           z0=np.clip(z0, lo, hi))

    def _polish(self, z, f, lo, hi, status, convex_start=False):
        """Newton steps on the full Hessian where the Gauss-Newton solver stopped short of a
        stationary point (:mod:`nlp.solve.polish`); the start is kept unless they reach one."""
        def fg(x):
            r, J = self.residuals(x)
            return 0.5 * float(r @ r), J.T @ r

        G = self.constraint_jacobian()
        try:
            zp, fp, dec, ok, steps = newton_polish(fg, z, lo, hi, G if G.size else None,
                                                   convex_start=convex_start)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            return z, f, False, status
        if ok and fp <= f:
            return zp, fp, True, f"Stationary after {steps} Newton steps (decrement {dec:.1e})"
        return z, f, False, status

    def gn_decrement(self, z):
        """Chi-square decrease a Gauss-Newton step from z would give: g^T (J^T J)^+ g on the
        steps that keep the bounds active where the gradient presses on them and the
        total-mass anchor satisfied (g = J^T r; 2 f is the chi-square). Small means
        stationary, whatever the size of the misfit
        (:func:`nlp.solve.stopping.gauss_newton_decrement`; on the numeric backends from
        the normal equations, :func:`nlp.solve.stopping.decrement_normal`)."""
        z = np.asarray(z, float)
        lo, hi = self.bounds
        if self.backend != "dense":
            _, g, A = self.normal_equations(z)
            return decrement_normal(z, g, A, lo, hi, self.constraint_jacobian())
        r, J = self.residuals(z)
        return gauss_newton_decrement(z, r, J, lo, hi, self.constraint_jacobian())
