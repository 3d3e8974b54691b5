"""The case's unknowns: its damping model and the ParameterSet (bounds, fixed values, ties)
built from the parameters and damping sections against the nominal model."""

from dataclasses import replace

import numpy as np

from nlp.case.model import DENSE_MATRICES_MAX
from nlp.case.schema import Multiplier
from nlp.errors import InputError
from nlp.model.damping import (DashpotDamping, GeneralDamping, ModalDamping, ModalGeneralDamping,
                               RayleighDamping, band_modes, rayleigh_from_ratios)
from nlp.model.parameters import Parameter, ParameterSet

__all__ = ["case_damping", "case_parameters", "dashpot_damping"]


def case_damping(cfg, model, f_max=None):
    """The damping model of the damping section, started from its ratios or matrix;
    f_max [Hz]: top of the band, whose modes modal-basis damping takes."""
    d = cfg.damping
    M0, K0 = model.M0, model.K0
    if d.a0 is not None:
        a0, a1 = d.a0, d.a1
    elif d.model in ("modal_general", "dashpots") or model.n > DENSE_MATRICES_MAX:
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


def case_parameters(cfg, model, damping):
    """The ParameterSet of masses, stiffnesses and damping with the case's bounds, fixed
    values, initial values and ties."""
    params = _structural(cfg, model) + _damping_parameters(cfg, damping)
    _check_names(cfg, {p.name for p in params})
    tie_of = _ties(cfg, {p.name for p in params})
    params = [replace(p, tie=tie_of.get(p.name)) for p in params]
    return ParameterSet(tuple(params), n_alpha=len(model.alpha_names), n_beta=len(model.beta_names))


def _structural(cfg, model):
    """Stiffness then mass parameters: relative changes theta of the nominal values."""
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
    return params


def _damping_parameters(cfg, damping):
    """The damping model's parameters, in its own units, with the case's settings."""
    pc = cfg.parameters
    d = cfg.damping
    if isinstance(damping, (GeneralDamping, ModalGeneralDamping)):
        lo_d, hi_d = damping.default_bounds(d.diag_factor, d.offdiag)
    else:
        lo_d, hi_d = damping.default_bounds()
    scales = damping.initial() if isinstance(damping, ModalDamping) else np.ones(len(damping.names))
    params = []
    for name, init, lo, hi, s in zip(damping.names, damping.initial(), lo_d, hi_d, scales):
        for section in ("fixed", "initial", "bounds"):
            if isinstance(getattr(pc, section).get(name), Multiplier):
                raise InputError(cfg.path, f"parameters.{section}.{name}", "a value in the damping "
                                 "model's own units (damping parameters have no nominal value "
                                 "to multiply)", "{multiplier: ...}")
        if name in pc.bounds:
            lo, hi = pc.bounds[name]
        fixed = name in pc.fixed
        init = pc.fixed.get(name, pc.initial.get(name, init))
        params.append(Parameter(name, "damping", float(init), float(lo), float(hi), fixed=fixed,
                                scale=float(s)))
    return params


def _check_names(cfg, known):
    """Every name in fixed, initial, bounds and prior is a parameter of the model."""
    pc = cfg.parameters
    prior_names = {k for k in pc.prior if k not in ("masses", "stiffnesses")}
    for section, keys in (("fixed", pc.fixed), ("initial", pc.initial), ("bounds", pc.bounds),
                          ("prior", prior_names)):
        for k in keys:
            if k not in known:
                raise InputError(cfg.path, f"parameters.{section}.{k}",
                                 f"a parameter name, one of {sorted(known)}", k)


def _ties(cfg, known):
    """name -> tie label of the tied parameters (each free, in one tie only)."""
    pc = cfg.parameters
    path = cfg.path
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
    return tie_of


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
    damping = case_damping(cfg, case.model, float(case.f[case.selected].max()))
    return damping, case_parameters(cfg, case.model, damping)
