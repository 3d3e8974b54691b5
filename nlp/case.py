"""Assemble a validated case file into model, parameters, data and the NLP."""

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import scipy.io

from .damping import GeneralDamping, ModalDamping, RayleighDamping, rayleigh_from_ratios
from .errors import InputError
from .freqsel import select_frequencies
from .identify import SCALE_EXPLANATION, scale_null_space
from .model import StructuralModel, shear_frame
from .parameters import Parameter, ParameterSet
from .problem import Channel, SolverConfig, Target, UpdatingProblem
from .estimate import estimate_frf
from .noise import noise_model
from .readers import read_frf, read_time_histories

__all__ = ["Case", "assemble", "build_problem"]


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
    records: object = None         # readers.TimeHistories when the data are records
    noise: object = None           # noise.NoiseModel of H (per channel and frequency)


def _load_model(cfg):
    m = cfg.model
    if m.type == "shear_frame":
        return shear_frame(m.masses, m.stiffnesses)
    try:
        raw = dict(np.load(m.file)) if m.file.endswith(".npz") else scipy.io.loadmat(m.file)
    except Exception as exc:  # unreadable file: a user mistake
        raise InputError(m.file, "<file>", f"a readable .npz or .mat file ({exc})") from None
    for key in ("M0", "K0", "M_infl", "K_infl"):
        if key not in raw:
            raise InputError(m.file, key, "an array named so (M0, K0: n x n; M_infl, K_infl: "
                             "r x n x n)")
    M0, K0 = np.asarray(raw["M0"], float), np.asarray(raw["K0"], float)
    n = M0.shape[0]
    Mi, Ki = np.asarray(raw["M_infl"], float), np.asarray(raw["K_infl"], float)
    for key, a, dims in (("M0", M0, 2), ("K0", K0, 2), ("M_infl", Mi, 3), ("K_infl", Ki, 3)):
        if a.ndim != dims or a.shape[-2:] != (n, n) or not np.all(np.isfinite(a)):
            raise InputError(m.file, key, f"finite array of shape {'(r, ' if dims == 3 else '('}{n}, {n})",
                             f"shape {a.shape}")
    if np.any(np.linalg.eigvalsh(M0) <= 0):
        raise InputError(m.file, "M0", "a symmetric positive definite mass matrix")

    def names(key, r, prefix):
        v = raw.get(key)
        return tuple(str(x).strip() for x in np.ravel(v)) if v is not None else \
            tuple(f"{prefix}{i + 1}" for i in range(r))

    return StructuralModel(M0=M0, K0=K0, M_infl=tuple(Mi), K_infl=tuple(Ki),
                           beta_names=names("beta_names", len(Mi), "beta"),
                           alpha_names=names("alpha_names", len(Ki), "alpha"),
                           beta_nominal=np.ones(len(Mi)), alpha_nominal=np.ones(len(Ki)),
                           dof_names=tuple(f"dof{i + 1}" for i in range(n)))


def _damping(cfg, model):
    d = cfg.damping
    M0, K0 = model.M0, model.K0
    if d.a0 is not None:
        a0, a1 = d.a0, d.a1
    else:
        a0, a1 = rayleigh_from_ratios(M0, K0, d.zeta)
    if d.model == "rayleigh":
        return RayleighDamping(a0_ref=a0 if a0 > 0 else 1.0, a1_ref=a1 if a1 > 0 else 1e-3)
    if d.model == "modal":
        z0 = np.asarray(d.modal_zeta) if d.modal_zeta else np.full(model.n, d.zeta)
        return ModalDamping(M0=M0, K0=K0, zeta0=z0)
    C0 = np.asarray(d.matrix) if d.matrix is not None else a0 * M0 + a1 * K0
    if not np.allclose(C0, C0.T) or np.any(np.linalg.eigvalsh(0.5 * (C0 + C0.T)) <= 0):
        raise InputError(cfg.path, "damping.matrix" if d.matrix is not None else "damping",
                         "a symmetric positive definite initial damping matrix")
    return GeneralDamping(C0=C0)


def _parameters(cfg, model, damping):
    pc = cfg.parameters
    path = cfg.path
    params = []
    for group, names, nominal, rel in (
            ("stiffness", model.alpha_names, model.alpha_nominal, pc.stiffness_bounds),
            ("mass", model.beta_names, model.beta_nominal, pc.mass_bounds)):
        for name, nom in zip(names, nominal):
            lo, hi = rel
            if name in pc.bounds:
                lo, hi = (v / nom - 1 for v in pc.bounds[name])
            init = pc.initial[name] / nom - 1 if name in pc.initial else 0.0
            fixed = name in pc.fixed
            if fixed:
                init = pc.fixed[name] / nom - 1
                if pc.fixed[name] <= 0:
                    raise InputError(path, f"parameters.fixed.{name}", "a positive value", pc.fixed[name])
            elif not lo <= init <= hi:
                raise InputError(path, f"parameters.initial.{name}",
                                 f"a value within the bounds [{nom * (1 + lo):g}, {nom * (1 + hi):g}]",
                                 nom * (1 + init))
            if lo <= -1:
                raise InputError(path, f"parameters.bounds.{name}", "a lower bound > 0", nom * (1 + lo))
            params.append(Parameter(name, group, init, lo, hi, fixed=fixed, nominal=float(nom)))
    d = cfg.damping
    if isinstance(damping, GeneralDamping):
        lo_d, hi_d = damping.default_bounds(d.diag_factor, d.offdiag)
    else:
        lo_d, hi_d = damping.default_bounds()
    scales = damping.initial() if isinstance(damping, ModalDamping) else np.ones(len(damping.names))
    for name, init, lo, hi, s in zip(damping.names, damping.initial(), lo_d, hi_d, scales):
        if name in pc.bounds:
            lo, hi = pc.bounds[name]
        fixed = name in pc.fixed
        init = pc.fixed.get(name, pc.initial.get(name, init))
        params.append(Parameter(name, "damping", float(init), float(lo), float(hi), fixed=fixed,
                                scale=float(s)))
    known = {p.name for p in params}
    for section, keys in (("fixed", pc.fixed), ("initial", pc.initial), ("bounds", pc.bounds)):
        for k in keys:
            if k not in known:
                raise InputError(path, f"parameters.{section}.{k}",
                                 f"a parameter name, one of {sorted(known)}", k)
    tie_of = {}
    for label, names in pc.ties.items():
        for nm in names:
            if nm not in known:
                raise InputError(path, f"parameters.tie.{label}", f"parameter names from {sorted(known)}", nm)
            if nm in pc.fixed:
                raise InputError(path, f"parameters.tie.{label}", "free parameters (not fixed)", nm)
            if nm in tie_of:
                raise InputError(path, f"parameters.tie.{label}", "each parameter in one tie only", nm)
            tie_of[nm] = label
    params = [Parameter(p.name, p.group, p.initial, p.lower, p.upper, p.fixed, tie_of.get(p.name),
                        p.scale, p.nominal) for p in params]
    return ParameterSet(tuple(params), n_alpha=len(model.alpha_names), n_beta=len(model.beta_names))


def _read_data(cfg, path=None):
    """(f, H, coherence, records) of the case's data file (or another test's)."""
    d = cfg.data
    path = path or d.file
    if d.type == "frf":
        fmt = d.format
        if fmt == "auto":
            fmt = "npz" if path.endswith(".npz") else "complex"
        f, H = read_frf(path, fmt=fmt if fmt != "npz" else "complex")
        return f, H * d.unit_factor, None, None
    inp = d.input
    spec = {"__input__": {"column": inp["column"], "quantity": inp["quantity"], "unit": inp["unit"]}}
    for c in d.channels:
        spec[c.name] = {"column": c.column, "quantity": c.quantity, "unit": c.unit}
    spec = {k: {kk: vv for kk, vv in v.items() if vv is not None} for k, v in spec.items()}
    rec = read_time_histories(path, spec)
    x = rec.data["__input__"]
    y = np.array([rec.data[c.name] for c in d.channels])
    nperseg = x.size if d.nperseg == "all" else d.nperseg
    noverlap = None if nperseg is None else int(d.overlap * nperseg)
    est = estimate_frf(x, y, rec.fs, estimator=d.estimator, nperseg=nperseg, noverlap=noverlap,
                       window=d.window, source=path)
    return est.f, est.H, est.coherence, rec


def _detection_form(f, H, channels, excitation):
    """Each channel as an accelerance, absolute for ground input (-w^2 H + 1 for a
    receptance): every mode peaks there, while the 1/w^2 fall of a receptance
    can hide a high mode of a base-excited frame."""
    jw = 2j * np.pi * f
    power = {"receptance": 0, "mobility": 1, "accelerance": 2, "absolute_accelerance": 2}
    out = np.empty_like(H)
    for c, ch in enumerate(channels):
        out[c] = H[c] * jw ** (2 - power[ch.output])
        if excitation == "ground" and ch.output != "absolute_accelerance":
            out[c] += 1.0
    return out


def _select(cfg, f, H, channels, excitation, coherence=None, sigma=None):
    fc = cfg.frequencies
    if fc.method == "all":
        mask = np.ones(f.size, bool)
        if fc.fmin is not None:
            mask &= f >= fc.fmin
        if fc.fmax is not None:
            mask &= f <= fc.fmax
        idx = np.nonzero(mask)[0]
    elif fc.method == "points":
        idx = np.unique([int(np.argmin(np.abs(f - p))) for p in fc.points])
    else:
        try:
            idx = _half_power(cfg, f, H, channels, excitation, coherence, sigma)
        except InputError as exc:  # freqsel names its argument; say which case key it is
            raise InputError(cfg.path, f"frequencies.{exc.key}", exc.expected, exc.got) from None
    return _nonempty(cfg, f, idx)


def _half_power(cfg, f, H, channels, excitation, coherence, sigma=None):
    """Half-power selection on the detection form; sigma: std of ln|H| (n_ch, n_f), so
    that a peak must stand out of the noise (carried over to the detection form)."""
    fc = cfg.frequencies
    det = _detection_form(f, H, channels, excitation)
    if sigma is not None:
        jw = 2j * np.pi * f
        power = {"receptance": 0, "mobility": 1, "accelerance": 2, "absolute_accelerance": 2}
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.array([np.abs(H[c] * jw ** (2 - power[ch.output])) / np.abs(det[c])
                              for c, ch in enumerate(channels)])
        sigma = sigma * np.nan_to_num(ratio, nan=1.0, posinf=1.0)
    return select_frequencies(f, det, k=fc.k,
                              coherence=coherence, min_coherence=fc.min_coherence,
                              bands=list(fc.bands) or None, n_peaks=fc.n_peaks,
                              min_points_per_peak=fc.min_points_per_peak, fmin=fc.fmin,
                              fmax=fc.fmax, sigma=sigma)


def _nonempty(cfg, f, idx):
    idx = np.asarray(idx, int)
    idx = idx[f[idx] > 0]
    if idx.size == 0:
        raise InputError(cfg.path, "frequencies", "settings that select at least one frequency "
                         f"point inside the data's range {f[0]:g}-{f[-1]:g} Hz")
    return idx


def assemble(cfg, channels=None, data_file=None):
    """Model, damping, parameters and selected data for a validated case.

    channels : names of the channels to use (default all); data_file : read
    another test of the same structure instead of ``data.file``.
    """
    model = _load_model(cfg)
    n = model.n
    damping = _damping(cfg, model)
    params = _parameters(cfg, model, damping)
    f, H, coherence, records = _read_data(cfg, data_file)
    ex = cfg.excitation
    if ex.type == "force" and ex.floor > n:
        raise InputError(cfg.path, "excitation.floor", f"a floor number from 1 to {n}", ex.floor)
    chans = []
    rows = []
    for i, c in enumerate(cfg.data.channels):
        if channels is not None and c.name not in channels:
            continue
        key = f"data.channels[{i}]"
        if c.floor > n:
            raise InputError(cfg.path, f"{key}.floor", f"a floor number from 1 to {n}", c.floor)
        if cfg.data.type == "frf" and c.column >= H.shape[0]:
            raise InputError(cfg.path, f"{key}.column",
                             f"a column index below {H.shape[0]} (the data file has {H.shape[0]} FRFs)",
                             c.column)
        if c.output == "absolute_accelerance" and ex.type != "ground":
            raise InputError(cfg.path, f"{key}.output", "receptance, mobility or accelerance "
                             "(absolute_accelerance needs ground excitation)", c.output)
        chans.append(Channel(c.name, c.floor - 1, c.output))
        rows.append(c.column if cfg.data.type == "frf" else i)
    channels, weights = chans, np.array([c.weight for c in cfg.data.channels
                                         if channels is None or c.name in channels])
    H = H[rows]
    if coherence is not None:
        coherence = coherence[rows]
    noise = noise_model(SimpleNamespace(config=cfg, f=f, H=H, coherence=coherence,
                                        records=records, channels=tuple(channels)))
    idx = _select(cfg, f, H, channels, ex.type, coherence, noise.sigma_ln)
    weights = weights[:, None] * np.ones(idx.size)
    target = Target(omega=2 * np.pi * f[idx], H=H[:, idx], weight=weights,
                    channels=tuple(channels), excitation=ex.type,
                    force_dof=None if ex.floor is None else ex.floor - 1)
    if scale_null_space(params, damping, ex.type, cfg.parameters.total_mass):
        raise InputError(cfg.path, "parameters",
                         "a scale anchor (a fixed weighed mass or parameters.total_mass). "
                         + SCALE_EXPLANATION)
    return Case(config=cfg, model=model, damping=damping, params=params, f=f, H=H,
                channels=tuple(channels), selected=idx, target=target, coherence=coherence,
                records=records, noise=noise)


def build_problem(case):
    """The compiled NLP for a case (built once; reuse it for every start)."""
    cfg = case.config
    solver = SolverConfig(cfg.solver.name, dict(cfg.solver.options), cfg.solver.compile)
    try:
        return UpdatingProblem(case.model, case.damping, case.params, case.target,
                               residual=cfg.objective.residual, solver=solver,
                               total_mass=cfg.parameters.total_mass)
    except RuntimeError as exc:  # CasADi rejects an option: a case-file mistake
        raise InputError(cfg.path, "solver.options", f"options that CasADi's {cfg.solver.name} "
                         f"accepts ({_casadi_reason(str(exc))})") from None


def _casadi_reason(text):
    """The useful line of a CasADi error, with its suggestions."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    head = next((ln.split(": ", 1)[-1] for ln in lines if "option" in ln.lower()), lines[-1] if lines else text)
    hints = [ln.split('"')[1] for ln in lines if ln.startswith('> "')]
    return head + (f"; did you mean {', '.join(hints)}?" if hints else "")
