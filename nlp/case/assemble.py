"""Assemble a validated case file into model, parameters, data and the NLP."""

import os
from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np

from nlp.model.damping import (DashpotDamping, GeneralDamping, ModalDamping, ModalGeneralDamping,
                      RayleighDamping, band_modes, rayleigh_from_ratios)
from nlp.case.checks import (check_coherence, check_data_points, check_free_parameters,
                     check_frf_alive, check_model_matrices, check_points_inside,
                     check_record_alive, check_start_residuals, check_total_mass)
from nlp.case.load import Multiplier
from nlp.errors import InputError
from nlp.frf.freqsel import select_frequencies
from nlp.frf.backends import choose as choose_backend
from nlp.frf.backends import reduced
from nlp.frf.backends.sparse import SparseFRF
from nlp.frf.backends.system import LinearSystem
from nlp.solve.identify import SCALE_EXPLANATION, scale_null_space
from nlp.io.importers import dof_number, find_dof, ground_influence, load_model
from nlp.model.nominal import StructuralModel, shear_frame
from nlp.model.parameters import Parameter, ParameterSet
from nlp.frf.reference import BASE_DOF
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem
from nlp.frf.estimate import estimate_frf
from nlp.frf.kernel import estimator_kernel
from nlp.frf.noise import noise_model
from nlp.io.readers import read_frf, read_frf_coherence, read_time_histories

__all__ = ["Case", "assemble", "build_problem", "detection_noise"]


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


# Imported models up to this size run on the dense symbolic FRF; larger ones stay sparse.
DENSE_MAX = 400


def _load_model(cfg):
    m = cfg.model
    if m.type == "shear_frame":
        return shear_frame(m.masses, m.stiffnesses)
    model = load_model(m, cfg.path)
    if model.n > DENSE_MAX:
        return model
    model = model.dense()
    # symmetric M0, K0 and groups, M0 PD, K0 PSD: named by the model file
    src = m.file or m.script or (m.K.get("file") if isinstance(m.K, dict) else m.K) or cfg.path
    check_model_matrices(src, model.M0, model.K0, model.M_infl, model.K_infl)
    return model


def _groups_cover(model):
    """True when the influence matrices add up to M0 and K0 (a shear frame). Otherwise a
    part of the model that no parameter scales (an imported model's other elements
    or masses) anchors the M-C-K scale."""

    def gap(A0, parts):
        rest = A0 - sum(parts) if parts else A0
        return abs(rest).max() <= 1e-9 * abs(A0).max()  # abs() works on sparse and dense

    return gap(model.M0, list(model.M_infl)) and gap(model.K0, list(model.K_infl))


def _dof_index(cfg, model, key, floor, node, dof):
    """0-based row of a floor (shorthand) or of a node and DOF of an imported model."""
    n = model.n
    if node is None:
        if floor > n:
            raise InputError(cfg.path, f"{key}.floor", f"a floor (DOF) number from 1 to {n}", floor)
        if floor == 0 and (cfg.excitation.type != "ground" or model.dofs):
            raise InputError(cfg.path, f"{key}.floor", "a floor from 1 to n: a sensor on the base "
                             "(floor 0) needs ground excitation of a floor model", floor)
        return BASE_DOF if floor == 0 else floor - 1
    if not model.dofs:
        raise InputError(cfg.path, f"{key}.node", "a floor: this model has no node-to-DOF map "
                         "(model.dof_map, or an OpenSees script)", node)
    nodes = {nd for nd, _ in model.dofs}
    if node not in nodes:
        raise InputError(cfg.path, f"{key}.node", "a node tag of the model (with a free DOF)", node)
    ndf = max(d for _, d in model.dofs)
    num = dof_number(dof, 6 if ndf > 3 else ndf, model.ndm)
    i = None if num is None else find_dof(model.dofs, node, num)
    if i is None:
        free = [d for nd, d in model.dofs if nd == node]
        raise InputError(cfg.path, f"{key}.dof", f"a free DOF of node {node} (numbers {free})", dof)
    return i


def _ground_r(cfg, model):
    """Influence vector of the ground motion (None: all ones, the shear-frame case)."""
    ex = cfg.excitation
    if not model.dofs:
        if ex.direction is not None:
            raise InputError(cfg.path, "excitation.direction", "no direction: this model has no "
                             "node-to-DOF map, the ground moves every DOF", ex.direction)
        return None
    ndf = max(d for _, d in model.dofs)
    d = dof_number(ex.direction if ex.direction is not None else 1, 6 if ndf > 3 else ndf, model.ndm)
    if d is None or d > (3 if ndf >= 6 or model.ndm == 3 else 2):
        raise InputError(cfg.path, "excitation.direction", "a translation (ux, uy or uz)",
                         ex.direction)
    return ground_influence(model.dofs, d)


def _damping(cfg, model, f_max=None):
    d = cfg.damping
    M0, K0 = model.M0, model.K0
    if d.a0 is not None:
        a0, a1 = d.a0, d.a1
    elif d.model in ("modal_general", "dashpots") or model.n > 400:
        a0, a1 = _rayleigh_band(cfg, model, f_max)
    else:
        a0, a1 = rayleigh_from_ratios(M0, K0, d.zeta)
    if d.model == "modal_general":
        modes = d.modes or _band_mode_numbers(model, f_max)
        z0 = d.modal_zeta or (d.zeta,) * len(modes)
        if len(z0) != len(modes):
            raise InputError(cfg.path, "damping.modal_zeta", f"{len(modes)} ratios, one per mode "
                             f"in damping.modes {list(modes)}", list(z0))
        return ModalGeneralDamping.from_model(M0, K0, modes, z0, a0, a1)
    if d.model == "dashpots":
        return DashpotDamping(a0_ref=a0 if a0 > 0 else 1.0, a1_ref=a1 if a1 > 0 else 1e-3,
                              K_groups=tuple(model.K_infl), group_names=tuple(model.alpha_names))
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


def _band_mode_numbers(model, f_max):
    """1-based numbers of the nominal modes below 1.1 f_max (at least one)."""
    omega, _ = band_modes(model.M0, model.K0, min(model.n, 30))
    k = int(np.sum(omega / (2 * np.pi) <= 1.1 * f_max)) if f_max else omega.size
    return tuple(range(1, max(k, 1) + 1))


def _rayleigh_band(cfg, model, f_max):
    """Rayleigh (a0, a1) with ratio damping.zeta at the first and the last band mode."""
    modes = _band_mode_numbers(model, f_max)
    omega, _ = band_modes(model.M0, model.K0, max(modes[-1], 2))
    wi, wj = omega[0], omega[max(modes[-1], 2) - 1]
    z = cfg.damping.zeta
    return 2 * z * wi * wj / (wi + wj), 2 * z / (wi + wj)


_UNIT = {"stiffness": "N/m", "mass": "kg"}


def _shown(v):
    return {"multiplier": v.value} if isinstance(v, Multiplier) else v


def _relative(path, key, v, nominal, physical, group):
    """Relative change theta (Eqns 23-24) of a case value: a physical value (kg, N/m), or
    ``{multiplier: x}`` for any mass or stiffness. A model whose parameters scale matrix
    groups has no physical value to give, so a bare number there is refused: the old
    meaning (a multiplier) would otherwise change silently."""
    if isinstance(v, Multiplier):
        return tuple(x - 1 for x in v.value) if isinstance(v.value, tuple) else v.value - 1
    if not physical:
        raise InputError(path, key, f"{{multiplier: x}} (this {group} parameter scales a matrix "
                         f"group of the model and has no value in {_UNIT[group]})", v)
    return tuple(x / nominal - 1 for x in v) if isinstance(v, tuple) else v / nominal - 1


def _parameters(cfg, model, damping):
    pc = cfg.parameters
    path = cfg.path
    params = []
    physical = cfg.model.type == "shear_frame"  # nominal values in kg and N/m
    for group, names, nominal, rel in (
            ("stiffness", model.alpha_names, model.alpha_nominal, pc.stiffness_bounds),
            ("mass", model.beta_names, model.beta_nominal, pc.mass_bounds)):
        for name, nom in zip(names, nominal):
            def theta(section, v, name=name, nom=nom):
                return _relative(path, f"parameters.{section}.{name}", v, nom, physical, group)
            lo, hi = rel
            if name in pc.bounds:
                lo, hi = theta("bounds", pc.bounds[name])
            init = theta("initial", pc.initial[name]) if name in pc.initial else 0.0
            fixed = name in pc.fixed
            if fixed:
                init = theta("fixed", pc.fixed[name])
                if init <= -1:
                    raise InputError(path, f"parameters.fixed.{name}", "a positive value",
                                     _shown(pc.fixed[name]))
            elif not lo <= init <= hi:
                raise InputError(path, f"parameters.initial.{name}",
                                 f"a value within the bounds [{nom * (1 + lo):g}, {nom * (1 + hi):g}]",
                                 nom * (1 + init))
            if lo <= -1:
                raise InputError(path, f"parameters.bounds.{name}", "a lower bound > 0", nom * (1 + lo))
            params.append(Parameter(name, group, init, lo, hi, fixed=fixed, nominal=float(nom),
                                    unit=_UNIT[group] if physical else "x nominal"))
    d = cfg.damping
    if isinstance(damping, (GeneralDamping, ModalGeneralDamping)):
        lo_d, hi_d = damping.default_bounds(d.diag_factor, d.offdiag)
    else:
        lo_d, hi_d = damping.default_bounds()
    scales = damping.initial() if isinstance(damping, ModalDamping) else np.ones(len(damping.names))
    for name, init, lo, hi, s in zip(damping.names, damping.initial(), lo_d, hi_d, scales):
        for section in ("fixed", "initial", "bounds"):
            if isinstance(getattr(pc, section).get(name), Multiplier):
                raise InputError(path, f"parameters.{section}.{name}", "a value in the damping "
                                 "model's own units (damping parameters have no nominal value "
                                 "to multiply)", "{multiplier: ...}")
        if name in pc.bounds:
            lo, hi = pc.bounds[name]
        fixed = name in pc.fixed
        init = pc.fixed.get(name, pc.initial.get(name, init))
        params.append(Parameter(name, "damping", float(init), float(lo), float(hi), fixed=fixed,
                                scale=float(s)))
    known = {p.name for p in params}
    prior_names = {k for k in pc.prior if k not in ("masses", "stiffnesses")}
    for section, keys in (("fixed", pc.fixed), ("initial", pc.initial), ("bounds", pc.bounds),
                          ("prior", prior_names)):
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
    params = [replace(p, tie=tie_of.get(p.name)) for p in params]
    return ParameterSet(tuple(params), n_alpha=len(model.alpha_names), n_beta=len(model.beta_names))


def dashpot_damping(case):
    """The case's damping as a0 M plus one dashpot per stiffness group (a story of a shear
    frame), with its ParameterSet: (DashpotDamping, ParameterSet).

    Masses and stiffnesses keep the case's bounds, fixed values and ties; settings that
    name the case's own damping parameters are dropped. The damper test of ``diagnose``
    refits C in this family: n + 1 damping parameters instead of the n (n + 1) / 2 of a
    general C, so one story's dashpot is determined well enough to stand out.
    """
    cfg = case.config
    pc = cfg.parameters
    keep = set(case.model.alpha_names) | set(case.model.beta_names)
    pc = replace(pc, **{k: {n: v for n, v in getattr(pc, k).items() if n in keep}
                        for k in ("fixed", "initial", "bounds")},
                 ties={t: [n for n in ns if n in keep] for t, ns in pc.ties.items()
                       if any(n in keep for n in ns)},
                 prior={k: v for k, v in pc.prior.items() if k in keep or k in ("masses", "stiffnesses")})
    cfg = replace(cfg, damping=replace(cfg.damping, model="dashpots"), parameters=pc)
    damping = _damping(cfg, case.model, float(case.f[case.selected].max()))
    return damping, _parameters(cfg, case.model, damping)


def _record_spec(d):
    """Channel specs for readers.read_time_histories: the input, then each channel."""
    inp = d.input
    spec = {"__input__": {"column": inp["column"], "quantity": inp["quantity"], "unit": inp["unit"],
                          "from": inp.get("from"), "scale": inp.get("scale", 1.0),
                          "sign": inp.get("sign", 1)}}
    for c in d.channels:
        spec[c.name] = {"column": c.column, "quantity": c.quantity, "unit": c.unit,
                        "scale": c.scale, "sign": c.sign}
    return {k: {kk: vv for kk, vv in v.items() if vv is not None} for k, v in spec.items()}


def _read_records(cfg, paths):
    """Records of the case (screened, and repaired when asked), the FRF estimate over
    all their segments, and the quality report."""
    from nlp.io.quality import screen_records

    d = cfg.data
    spec = _record_spec(d)
    xs, ys, reports, first = [], [], [], None
    for path in paths:
        try:
            rec = read_time_histories(path, spec, fs=d.fs, columns=d.columns,
                                      time_column=d.time_column, skip_rows=d.skip_rows)
        except InputError as exc:  # a unit or column named in the case file: say which key
            raise _case_key_error(cfg, exc) from None
        check_record_alive(path, d.input["column"], rec.data["__input__"],
                           f"data.input.column of {cfg.path}")
        for i, c in enumerate(d.channels):
            check_record_alive(path, c.column, rec.data[c.name],
                               f"data.channels[{i}] of {cfg.path}")
        if first is not None and abs(rec.fs - first.fs) > 1e-9 * first.fs:
            raise InputError(path, "fs", f"the sampling rate of the first record ({first.fs:g} Hz)",
                             rec.fs)
        sc = d.screen
        data, rep = screen_records(rec.data, rec.fs, remove=sc.remove,
                                   spike_threshold=sc.spike_threshold,
                                   dropout_min_samples=sc.dropout_min_samples, t0=float(rec.t[0]))
        if sc.remove:
            rec = type(rec)(t=rec.t, fs=rec.fs, data=data)
        first = first or rec
        reports.append((path, rep))
        xs.append(rec.data["__input__"])
        ys.append(np.array([rec.data[c.name] for c in d.channels]))
    n = min(x.size for x in xs)
    nperseg = n if d.nperseg == "all" else d.nperseg
    noverlap = None if nperseg is None else int(d.overlap * nperseg)
    if nperseg is None:  # the default segment, with the case's overlap (not scipy's half)
        from nlp.frf.estimate import default_nperseg
        nperseg = default_nperseg(n)
        noverlap = int(d.overlap * nperseg)
    try:
        est = estimate_frf(xs, ys, first.fs, estimator=d.estimator, nperseg=nperseg,
                           noverlap=noverlap, window=d.window, source=paths[0])
    except InputError as exc:  # segment settings come from the case file: name its key
        if exc.key not in ("nperseg", "noverlap"):
            raise
        raise InputError(cfg.path, "data.nperseg" if exc.key == "nperseg" else "data.overlap",
                         f"{exc.expected} (the records have {n} samples)", exc.got) from None
    check_coherence(cfg, est.f, est.coherence, [c.column for c in d.channels],
                    [f"data.channels[{i}]" for i in range(len(d.channels))], est.n_averages)
    return est, first, reports


def _read_data(cfg, path=None):
    """(f, H, coherence, records, n_averages, quality) of the case's data (or another test's)."""
    d = cfg.data
    if d.type == "frf":
        path = path or d.file
        fmt = d.format
        if fmt == "auto":
            fmt = "npz" if path.endswith(".npz") else "complex"
        f, H = read_frf(path, fmt=fmt if fmt != "npz" else "complex", db_reference=d.db_reference)
        coh, n_avg = read_frf_coherence(path, *H.shape)   # .npz may carry them (noise model)
        return f, H * d.unit_factor, coh, None, n_avg or 1, None
    paths = [path] if path else list(d.records or (d.file,))
    est, rec, reports = _read_records(cfg, paths)
    return est.f, est.H, est.coherence, rec, est.n_averages, _merge_quality(reports)


def _merge_quality(reports):
    """One report over all records (file named in each glitch's channel when several)."""
    from nlp.io.quality import QualityReport

    if len(reports) == 1:
        return reports[0][1]
    glitches = []
    for path, rep in reports:
        tag = os.path.basename(path)
        glitches += [type(g)(f"{tag}:{g.channel}", g.kind, g.start, g.stop, g.time_s)
                     for g in rep.glitches]
    return QualityReport(tuple(glitches), sum(r.n_samples for _, r in reports), reports[0][1].removed,
                         reports[0][1].settings)


def _case_key_error(cfg, exc):
    """A records-file error about a channel spec, renamed to the case file's key."""
    key = exc.key
    if key.startswith("channels."):
        _, name, *rest = key.split(".")
        field = rest[0] if rest else "column"
        if name == "__input__":
            return InputError(cfg.path, f"data.input.{field}", exc.expected, exc.got)
        for i, c in enumerate(cfg.data.channels):
            if c.name == name:
                return InputError(cfg.path, f"data.channels[{i}].{field}", exc.expected, exc.got)
    return exc


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
        check_points_inside(cfg, f)
        idx = np.unique([int(np.argmin(np.abs(f - p))) for p in fc.points])
    else:
        check_points_inside(cfg, f)
        try:
            idx = _half_power(cfg, f, H, channels, excitation, coherence, sigma)
        except InputError as exc:  # freqsel names its argument; say which case key it is
            raise _frequency_error(cfg, f, exc) from None
    return _nonempty(cfg, f, idx)


_FREQ_KEYS = {"k", "bands", "points", "fmin", "fmax", "n_peaks", "min_points_per_peak",
              "min_coherence"}


def _frequency_error(cfg, f, exc):
    """A freqsel error named by a key that exists in the case file."""
    if exc.key in _FREQ_KEYS:
        return InputError(cfg.path, f"frequencies.{exc.key}", exc.expected, exc.got)
    if exc.key == "prominence_db":  # no resonance peak: the data, not a setting, is the cause
        return InputError(cfg.path, "frequencies.method", "a method the data allow: half_power "
                          f"needs a resonance peak, and {cfg.data.file} shows none in "
                          f"{f[0]:g}-{f[-1]:g} Hz (check its record length and input, or use "
                          "bands or all)", cfg.frequencies.method)
    return InputError(cfg.path, "frequencies.method", f"{exc.expected} (from {exc.key})", exc.got)


def _half_power(cfg, f, H, channels, excitation, coherence, sigma=None):
    """Half-power selection on the detection form; sigma: std of ln|H| (n_ch, n_f), so
    that a peak must stand out of the noise (carried over to the detection form)."""
    fc = cfg.frequencies
    # a base sensor sees the modes only through a flexible base: peaks are looked for
    # on the structure's channels
    rows = [c for c, ch in enumerate(channels) if ch.dof != BASE_DOF] or list(range(len(channels)))
    channels, H = [channels[c] for c in rows], H[rows]
    coherence = None if coherence is None else coherence[rows]
    sigma = None if sigma is None else sigma[rows]
    det = _detection_form(f, H, channels, excitation)
    sigma = detection_noise(f, H, det, channels, sigma)
    return select_frequencies(f, det, k=fc.k,
                              coherence=coherence, min_coherence=fc.min_coherence,
                              bands=list(fc.bands) or None, n_peaks=fc.n_peaks,
                              min_points_per_peak=fc.min_points_per_peak, fmin=fc.fmin,
                              fmax=fc.fmax, sigma=sigma)


def selectable(cfg, f, channels, coherence):
    """(n_f,) mask of the points the half-power selection may keep: f inside
    fmin-fmax, and coherence >= min_coherence on every structure channel (the
    rules `_half_power` applies). Windows added around other frequencies (the
    diagnosis's hot spots) keep to it, so no point the case rules out is fitted."""
    fc = cfg.frequencies
    ok = (f >= (-np.inf if fc.fmin is None else fc.fmin)) & \
         (f <= (np.inf if fc.fmax is None else fc.fmax))
    if fc.min_coherence is not None and coherence is not None:
        rows = [c for c, ch in enumerate(channels) if ch.dof != BASE_DOF] \
            or list(range(len(channels)))
        ok &= np.min(np.asarray(coherence)[rows], axis=0) >= fc.min_coherence
    return ok


def detection_noise(f, H, det, channels, sigma):
    """Std of ln|det| from the std of ln|H| (n_ch, n_f): the jw powers leave it
    unchanged, the +1 of a relative channel under ground input scales it by
    |jw^p H| / |det|. None stays None."""
    if sigma is None:
        return None
    jw = 2j * np.pi * f
    power = {"receptance": 0, "mobility": 1, "accelerance": 2, "absolute_accelerance": 2}
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.array([np.abs(H[c] * jw ** (2 - power[ch.output])) / np.abs(det[c])
                          for c, ch in enumerate(channels)])
    return sigma * np.nan_to_num(ratio, nan=1.0, posinf=1.0)


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
    f, H, coherence, records, n_avg, quality = _read_data(cfg, data_file)
    ex = cfg.excitation
    force_dof = None
    if ex.type == "force":
        force_dof = _dof_index(cfg, model, "excitation", ex.floor, ex.node, ex.dof)
    ground_r = _ground_r(cfg, model) if ex.type == "ground" else None
    chans = []
    rows = []
    for i, c in enumerate(cfg.data.channels):
        if channels is not None and c.name not in channels:
            continue
        key = f"data.channels[{i}]"
        dof = _dof_index(cfg, model, key, c.floor, c.node, c.dof)
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
    gains = np.array([c.scale * c.sign for c in cfg.data.channels
                      if channels is None or c.name in channels])
    channels, weights = chans, np.array([c.weight for c in cfg.data.channels
                                         if channels is None or c.name in channels])
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
    idx = _select(cfg, f, H, channels, ex.type, coherence, noise.detect)
    # damping after the selection: modal-basis damping takes the band's modes
    damping = _damping(cfg, model, float(f[idx].max()))
    params = _parameters(cfg, model, damping)
    check_free_parameters(cfg.path, params)
    check_total_mass(cfg.path, model, params, cfg.parameters.total_mass)
    check_data_points(cfg, params, len(channels), idx.size, f)
    weights = weights[:, None] * np.ones(idx.size)
    target = Target(omega=2 * np.pi * f[idx], H=H[:, idx], weight=weights,
                    channels=tuple(channels), excitation=ex.type, force_dof=force_dof,
                    ground_r=ground_r, kernel=kernel)
    if _groups_cover(model) and scale_null_space(params, damping, ex.type,
                                                 cfg.parameters.total_mass):
        raise InputError(cfg.path, "parameters",
                         "a scale anchor (a fixed weighed mass or parameters.total_mass). "
                         + SCALE_EXPLANATION)
    return Case(config=cfg, model=model, damping=damping, params=params, f=f, H=H,
                channels=tuple(channels), selected=idx, target=target, coherence=coherence,
                records=records, n_averages=n_avg, quality=quality, has_phase=cfg.data.has_phase,
                noise=noise)


def build_problem(case, centre=None):
    """The compiled NLP for a case (built once; reuse it for every start).

    ``centre``: decision vector z at which the reduced backend computes its basis
    (default: the initial model; :mod:`nlp.workflow.recentre` moves it to the fit).
    """
    cfg = case.config
    solver = SolverConfig(cfg.solver.name, dict(cfg.solver.options), cfg.solver.compile)
    try:
        backend = choose_backend(cfg.model.frf_backend, case.model.n)
        basis, info = _reduced_basis(case, centre) if backend == "reduced" else (None, None)
        problem = UpdatingProblem(case.model, case.damping, case.params, case.target,
                                  residual=cfg.objective.residual, solver=solver,
                                  total_mass=cfg.parameters.total_mass, frf_backend=backend,
                                  basis=basis)
        problem.reduced_info = info
    except RuntimeError as exc:
        if "option" not in str(exc).lower():  # not the user's options: a real failure
            raise
        raise InputError(cfg.path, "solver.options", f"options that CasADi's {cfg.solver.name} "
                         f"accepts ({_casadi_reason(str(exc))})") from None
    check_start_residuals(case, problem)
    return problem


def _reduced_basis(case, centre=None):
    """The reduced basis at z = ``centre`` (default z0), after checking its FRF against the exact one there.

    Refuses (InputError on ``model.frf_backend``) when the error exceeds the
    data noise (:func:`reduced_error`).
    """
    tg = case.target
    full = LinearSystem.from_model(case.model, case.damping, tg)
    z = case.params.z0 if centre is None else np.asarray(centre, float)
    sa, sb, _ = case.params.slices()
    theta = case.params.theta(z)
    psi = reduced.basis(full.shifted(theta[sa], theta[sb]), float(tg.omega.max()),
                        cutoff=case.config.model.reduced_cutoff)
    small = SparseFRF(full.project(psi), case.damping, case.params, tg, "log_magnitude")
    return psi, reduced_error(case, small, z, full)


def reduced_error(case, small, z, full=None):
    """The reduced FRF against the exact sparse FRF at z; refuses when it exceeds the noise.

    Error: RMS and maximum of |ln|H_red| - ln|H_exact|| over every k-th of the case's
    frequencies (at most 40: each exact point is a full factorisation, 0.1-0.3 s at
    2,100 DOFs), against the data noise (median over channels of the noise of ln|H|,
    :func:`nlp.diagnosis.driver.noise_sigma`). ``small``: the reduced SparseFRF.
    Raises InputError on ``model.frf_backend`` when the RMS error exceeds the noise.
    """
    from nlp.diagnosis.driver import noise_sigma  # diagnose builds on this module

    tg = case.target
    full = LinearSystem.from_model(case.model, case.damping, tg) if full is None else full
    k = -(-tg.omega.size // 40)
    w, weight = tg.omega[::k], tg.weight[:, ::k]
    exact = SparseFRF(full, case.damping, case.params, tg, "log_magnitude").frf(z, w)
    rms, worst = reduced.log_error(exact, small.frf(z, w), weight)
    noise = float(np.median(noise_sigma(case, case.selected)))
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
