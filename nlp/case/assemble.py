"""Assemble a validated case into model, parameters, selected data and the NLP.

The pieces live by concept: the model and its DOFs (:mod:`nlp.case.model`), the
measured data (:mod:`nlp.case.records`), the frequency selection
(:mod:`nlp.case.selection`), damping and parameters (:mod:`nlp.case.parameters`).
"""

from dataclasses import dataclass, replace
import os
from types import SimpleNamespace

import numpy as np

from nlp.case.joint import common_grid, stack_tests
from nlp.case.checks import (check_data_points, check_free_parameters, check_frf_alive,
                             check_start_residuals, check_total_mass)
from nlp.case.model import case_model, dof_index, ground_vector, groups_cover
from nlp.case.parameters import case_damping, case_parameters
from nlp.case.records import read_data
from nlp.case.selection import model_frequencies, select_points
from nlp.errors import InputError
from nlp.frf.backends import DENSE_MAX, choose as choose_backend
from nlp.frf.backends import reduced
from nlp.frf.backends.sparse import SparseFRF
from nlp.frf.backends.system import LinearSystem
from nlp.frf.kernel import estimator_kernel
from nlp.frf.noise import noise_model, sigma_ln
from nlp.frf.reference import BASE_DOF
from nlp.model.nominal import StructuralModel
from nlp.model.parameters import ParameterSet
from nlp.output.progress import stage
from nlp.solve.identify import SCALE_EXPLANATION, scale_null_space
from nlp.solve.problem import (PREFIT_MAX_ITER, Channel, SolverConfig, Target, UpdatingProblem,
                               prefit_residual)

__all__ = ["Case", "assemble", "single_tests", "joint_case", "build_problem", "reduced_basis_at",
           "reduced_error"]


@dataclass(frozen=True)
class Case:
    """Everything a run needs, checked against each other."""

    config: object
    model: StructuralModel
    damping: object
    params: ParameterSet
    f: np.ndarray            # full measured grid [Hz]
    H: np.ndarray            # (n_ch, n_f) measured FRFs, SI
    channels: tuple          # problem.Channel
    selected: np.ndarray     # indices into f used in the objective
    target: Target
    coherence: np.ndarray = None   # (n_ch, n_f) when estimated from records
    records: object = None         # readers.TimeHistories when the data are records (the first)
    n_averages: int = 1            # Welch segments averaged in the estimate (all records)
    quality: object = None         # quality.QualityReport of the records (spikes, dropouts)
    has_phase: bool = True         # False for magnitude-only FRF files
    noise: object = None           # noise.NoiseModel of H (per channel and frequency)
    # model discrepancy a diagnosis adds to every fit (nlp.diagnosis.discrepancy): resonances
    # outside the model class, as modal terms; empty for updating
    discrepancy: tuple = ()
    # the model lacks as many resonances in its band as it has (a class of motion is
    # missing, not a subsystem): no change of its parameters is named (discrepancy.py)
    outside_class: bool = False
    # sensors whose gain a diagnosis named as beyond the case's calibration tolerance: freed
    # in every later fit (nlp.diagnosis.calibration)
    released_gains: tuple = ()
    # decision vector z at which a diagnosis on the reduced backend computes its basis
    # (nlp.diagnosis.reduction; None: the initial model)
    basis_centre: np.ndarray = None
    # the joints' distortion of a one-segment record, divided out of H by a
    # diagnosis (nlp.diagnosis.sweep; None: the data as measured)
    sweep_joints: dict = None
    measured: tuple = None   # (H, target, noise) as measured, where sweep_joints corrected them


def assemble(cfg, channels=None, data_file=None):
    """Model, damping, parameters and selected data for a validated case.

    channels : names of the channels to use (default all); data_file : read
    another test of the same structure instead of ``data.file`` (that test alone).
    A case with data.tests holds every test's channels (:mod:`nlp.case.joint`).
    """
    if cfg.data.tests and data_file is None:
        return joint_case(cfg, channels)
    return _one_test(cfg, channels, data_file)


def single_tests(cfg):
    """[(label, config, data file)] of each test of a case, each to be assembled alone:
    data.file first, then data.tests (with its shaker floor)."""
    plain = replace(cfg, data=replace(cfg.data, tests=()))
    out = [(os.path.splitext(os.path.basename(cfg.data.file))[0], plain, None)]
    for i, t in enumerate(cfg.data.tests):
        c = plain
        if t.force_floor is not None:
            if cfg.excitation.type != "force":
                raise InputError(cfg.path, f"data.tests[{i}].force_floor",
                                 "only with force excitation (excitation.type force)",
                                 t.force_floor)
            c = replace(plain, excitation=replace(cfg.excitation, floor=t.force_floor,
                                                  node=None, dof=None))
        out.append((t.label, c, t.file))
    return out


def joint_case(cfg, channels=None):
    """The stacked case of every test of the structure (:func:`nlp.case.joint.stack_tests`)."""
    if choose_backend(cfg.model.frf_backend, case_model(cfg).n) != "dense":
        raise InputError(cfg.path, "data.tests", "a model for the dense backend (tests fitted "
                         "jointly are not carried by the sparse and reduced backends yet)")
    tests = single_tests(cfg)
    cases = [_one_test(c, None, path) for _, c, path in tests]
    grid = common_grid([c.f for c in cases])
    if grid is None:
        raise InputError(cfg.path, "data.tests", "FRF files on the frequency grid of data.file")
    return stack_tests(cfg, cases, [lab for lab, _, _ in tests], grid[1], grid[0], channels)


def _one_test(cfg, channels=None, data_file=None):
    """The case of one test (:func:`assemble`)."""
    model = case_model(cfg)
    f, H, coherence, records, n_avg, quality = read_data(cfg, data_file)
    ex = cfg.excitation
    force_dof = None
    if ex.type == "force":
        force_dof = dof_index(cfg, model, "excitation", ex.floor, ex.node, ex.dof)
    ground_r = ground_vector(cfg, model) if ex.type == "ground" else None
    used = [c for c in cfg.data.channels if channels is None or c.name in channels]
    channels, rows = _channels(cfg, model, H, channels, ground_r)
    gains = np.array([c.scale * c.sign for c in used])
    weights = np.array([c.weight for c in used])
    if cfg.data.type == "frf":
        check_frf_alive(cfg, H, rows)
    H = H[rows]
    if cfg.data.type == "frf":  # per-channel calibration of FRF files (time histories: readers)
        H = H * gains[:, None]
    if coherence is not None:
        coherence = coherence[rows]
    # the model sees the estimate's window where the FRF is a windowed average; the
    # numeric (sparse, reduced) backends do not carry it, so their cases keep the
    # noise model's resolution bias instead
    kernel = estimator_kernel(cfg, f, records, coherence, n_avg) \
        if choose_backend(cfg.model.frf_backend, model.n) == "dense" else None
    noise = noise_model(SimpleNamespace(config=cfg, f=f, H=H, coherence=coherence,
                                        records=records, channels=tuple(channels),
                                        n_averages=n_avg, kernel=kernel))
    fc = cfg.frequencies
    model_hz = model_frequencies(model, max(f[0], fc.fmin or 0.0), min(f[-1], fc.fmax or np.inf)) \
        if fc.method == "half_power" and not fc.bands and fc.n_peaks is None else None
    if model_hz is not None and model_hz.size <= DENSE_MAX:
        # few modes: kept as they were, since the diagnosis's decisions were measured on
        # that selection (a mode not found among few is one the data barely show)
        model_hz = None
    idx = select_points(cfg, f, H, channels, ex.type, coherence, noise.detect, model_hz,
                        source=data_file)
    # damping after the selection: modal-basis damping takes the band's modes
    damping = case_damping(cfg, model, float(f[idx].max()))
    params = case_parameters(cfg, model, damping)
    check_free_parameters(cfg.path, params)
    check_total_mass(cfg.path, model, params, cfg.parameters.total_mass)
    check_data_points(cfg, params, len(channels), idx.size, f)
    weights = weights[:, None] * np.ones(idx.size)
    target = Target(omega=2 * np.pi * f[idx], H=H[:, idx], weight=weights,
                    channels=tuple(channels), excitation=ex.type, force_dof=force_dof,
                    ground_r=ground_r, kernel=kernel)
    if groups_cover(model) and scale_null_space(params, damping, ex.type,
                                                cfg.parameters.total_mass):
        raise InputError(cfg.path, "parameters",
                         "a scale anchor (a fixed weighed mass or parameters.total_mass). "
                         + SCALE_EXPLANATION)
    return Case(config=cfg, model=model, damping=damping, params=params, f=f, H=H,
                channels=tuple(channels), selected=idx, target=target, coherence=coherence,
                records=records, n_averages=n_avg, quality=quality, has_phase=cfg.data.has_phase,
                noise=noise)


def _channels(cfg, model, H, names, ground_r):
    """(problem.Channel list, rows of H) of the channels named (default all), each checked
    against the model's DOFs, the data file and the excitation."""
    ex = cfg.excitation
    chans = []
    rows = []
    for i, c in enumerate(cfg.data.channels):
        if names is not None and c.name not in names:
            continue
        key = f"data.channels[{i}]"
        dof = dof_index(cfg, model, key, c.floor, c.node, c.dof)
        if cfg.data.type == "frf" and c.column >= H.shape[0]:
            raise InputError(cfg.path, f"{key}.column",
                             f"a column index below {H.shape[0]} (the data file has {H.shape[0]} FRFs)",
                             c.column)
        if c.output == "absolute_accelerance" and ex.type != "ground":
            raise InputError(cfg.path, f"{key}.output", "receptance, mobility or accelerance "
                             "(absolute_accelerance needs ground excitation)", c.output)
        if c.output == "absolute_accelerance" and ground_r is not None and dof != BASE_DOF \
                and ground_r[dof] != 1:
            raise InputError(cfg.path, f"{key}.output", "a relative output (receptance, mobility, "
                             "accelerance): absolute_accelerance needs a DOF along the ground "
                             "motion", c.output)
        chans.append(Channel(c.name, dof, c.output))
        rows.append(c.column if cfg.data.type == "frf" else i)
    return chans, rows


def build_problem(case, centre=None, check=True):
    """The compiled NLP for a case (built once; reuse it for every start).

    ``centre``: decision vector z at which the reduced backend computes its basis
    (default: the initial model; :mod:`nlp.workflow.recentre` moves it to the fit).
    ``check=False`` skips the reduced basis's comparison with the exact FRF (40 full
    factorisations): for intermediate bases whose fit only starts the next one, when
    the final basis is checked (:mod:`nlp.workflow.recentre`).
    """
    cfg = case.config
    solver = SolverConfig(cfg.solver.name, dict(cfg.solver.options), cfg.solver.compile)
    try:
        with stage("build NLP") as bar:
            backend = choose_backend(cfg.model.frf_backend, case.model.n)
            basis, info = reduced_basis_at(case, centre, check) if backend == "reduced" else (None, None)
            def on(residual, solver=solver):
                return UpdatingProblem(case.model, case.damping, case.params, case.target,
                                       residual=residual, solver=solver,
                                       total_mass=cfg.parameters.total_mass, frf_backend=backend,
                                       basis=basis)

            problem = on(cfg.objective.residual)
            problem.reduced_info = info
            pre = prefit_residual(cfg.objective.prefit, cfg.objective.residual, problem.backend,
                                  case.has_phase)
            if pre is not None:
                key = "ipopt.max_iter" if solver.name == "ipopt" else "max_iter"
                problem.prefit = on(pre, replace(solver, options={**solver.options,
                                                                  key: PREFIT_MAX_ITER}))
                problem.prefit.polish_unconverged = False  # only a start for the case's residual
            bar.update()
    except RuntimeError as exc:
        if "option" not in str(exc).lower():  # not the user's options: a real failure
            raise
        raise InputError(cfg.path, "solver.options", f"options that CasADi's {cfg.solver.name} "
                         f"accepts ({_casadi_reason(str(exc))})") from None
    check_start_residuals(case, problem)
    return problem


def reduced_basis_at(case, centre=None, check=True):
    """The reduced basis at z = ``centre`` (default z0), after checking its FRF against the exact one there.

    Refuses (InputError on ``model.frf_backend``) when the error exceeds the
    data noise (:func:`reduced_error`). Unchecked (``check=False``): the info says so.
    """
    tg = case.target
    full = LinearSystem.from_model(case.model, case.damping, tg)
    z = case.params.z0 if centre is None else np.asarray(centre, float)
    sa, sb, _ = case.params.slices()
    theta = case.params.theta(z)
    psi = reduced.basis(full.shifted(theta[sa], theta[sb]), float(tg.omega.max()),
                        cutoff=case.config.model.reduced_cutoff)
    if not check:
        return psi, {"vectors": psi.shape[1], "rms_log_error": None, "max_log_error": None,
                     "noise": None, "points_checked": 0}
    small = SparseFRF(full.project(psi), case.damping, case.params, tg, "log_magnitude")
    return psi, reduced_error(case, small, z, full)


def reduced_error(case, small, z, full=None):
    """The reduced FRF against the exact sparse FRF at z; refuses when it exceeds the noise.

    Error: RMS and maximum of |ln|H_red| - ln|H_exact|| over every k-th of the case's
    frequencies (at most 40: each exact point is a full factorisation, 0.1-0.3 s at
    2,100 DOFs), against the data noise (median over channels of the noise of ln|H|,
    :func:`nlp.frf.noise.sigma_ln`). ``small``: the reduced SparseFRF.
    Raises InputError on ``model.frf_backend`` when the RMS error exceeds the noise.
    """
    tg = case.target
    full = LinearSystem.from_model(case.model, case.damping, tg) if full is None else full
    k = -(-tg.omega.size // 40)
    w, weight = tg.omega[::k], tg.weight[:, ::k]
    exact = SparseFRF(full, case.damping, case.params, tg, "log_magnitude").frf(z, w)
    rms, worst = reduced.log_error(exact, small.frf(z, w), weight)
    noise = float(np.median(sigma_ln(case, case.selected)))
    m = small.n
    info = {"vectors": m, "rms_log_error": rms, "max_log_error": worst, "noise": noise,
            "points_checked": int(w.size)}
    if rms > noise:
        raise InputError(case.config.path, "model.frf_backend",
                         f"sparse (or dense): the reduced basis ({m} vectors) misses the "
                         f"exact FRF by {rms:.3g} (RMS of ln|H| on the case's frequencies), more "
                         f"than the data noise {noise:.3g}", "reduced")
    return info


def _casadi_reason(text):
    """The useful line of a CasADi error, with its suggestions."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    head = next((ln.split(": ", 1)[-1] for ln in lines if "option" in ln.lower()), lines[-1] if lines else text)
    hints = [ln.split('"')[1] for ln in lines if ln.startswith('> "')]
    return head + (f"; did you mean {', '.join(hints)}?" if hints else "")
