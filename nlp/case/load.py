"""Loading a case file: YAML -> the typed case of :mod:`nlp.case.schema`, validated once.

Every user mistake raises one :class:`nlp.errors.InputError` naming the file,
the key and what is expected (docs/case_reference.md lists every key). The data
section is read by :mod:`nlp.case.load_data`, CLI overrides applied by
:mod:`nlp.case.overrides`.
"""

from dataclasses import replace
import os

import yaml

from nlp.case.load_data import data_section
from nlp.case.overrides import apply_overrides
from nlp.case.reader import Reader, YamlLoader, dof_spec, existing, location, scheduler_address
from nlp.case.schema import (DAMPING_MODELS, EXCITATIONS, EXECUTORS, FREQUENCY_METHODS,
                             FRF_BACKENDS, MODEL_TYPES, PREFITS, RESIDUALS, SOLVERS, CaseConfig,
                             DampingConfig, ExcitationConfig, FrequencyConfig, ModelConfig,
                             Multiplier, ObjectiveConfig, ParameterConfig, SearchSection,
                             SolverSection)
from nlp.errors import WHOLE_FILE, InputError

__all__ = ["load_case"]


def load_case(path, overrides=None):
    """Read and validate a case file; returns a :class:`nlp.case.schema.CaseConfig`.

    overrides : dict of CLI overrides: ``starts``, ``seed``, ``workers``, ``solver``,
        ``executor``, ``scheduler``.
    """
    path = os.path.abspath(path)
    raw = _read_yaml(path)
    rd = Reader(path)
    if not isinstance(raw, dict):
        raise rd.err(WHOLE_FILE, "a YAML mapping at the top level", type(raw).__name__)
    rd.check_keys(raw, "", {"name", "description", "model", "parameters", "damping",
                            "excitation", "data", "frequencies", "objective", "solver", "search",
                            "updates", "verification"})
    base = os.path.dirname(path)
    model = _model(rd, rd.mapping(raw, "model", required=True), base)
    n = len(model.masses) if model.type == "shear_frame" else None
    cfg = CaseConfig(
        path=path,
        name=str(raw.get("name") or os.path.basename(base)),
        description=str(raw.get("description", "")),
        model=model,
        parameters=_parameters(rd, rd.mapping(raw, "parameters")),
        damping=_damping(rd, rd.mapping(raw, "damping"), n),
        excitation=_excitation(rd, rd.mapping(raw, "excitation")),
        data=data_section(rd, rd.mapping(raw, "data", required=True), base),
        frequencies=_frequencies(rd, rd.mapping(raw, "frequencies")),
        objective=_objective(rd, rd.mapping(raw, "objective")),
        solver=_solver(rd, rd.mapping(raw, "solver")),
        search=_search(rd, rd.mapping(raw, "search")),
    )
    if not cfg.data.has_phase and cfg.objective.residual == "complex":
        raise rd.err("objective.residual", f"magnitude or log_magnitude (data.format "
                     f"{cfg.data.format} has no phase)", "complex")
    if not cfg.data.has_phase and cfg.objective.prefit == "complex":
        raise rd.err("objective.prefit", f"auto, none, magnitude or relative_magnitude (data.format "
                     f"{cfg.data.format} has no phase)", "complex")
    cfg = _updates_and_verification(rd, raw, cfg)
    return apply_overrides(cfg, overrides or {}, rd)


def _read_yaml(path):
    """The parsed YAML of a case file (an InputError for a missing, binary or invalid file)."""
    if not os.path.isfile(path):
        raise InputError(path, WHOLE_FILE, "an existing case YAML file")
    try:
        with open(path, "rb") as fh:
            text = fh.read()
        if b"\0" in text:
            raise InputError(path, WHOLE_FILE, "a YAML text file", "binary data")
        return yaml.load(text.decode("utf-8"), Loader=YamlLoader)
    except UnicodeDecodeError as exc:
        raise InputError(path, WHOLE_FILE, "a YAML text file in UTF-8",
                         f"undecodable byte at position {exc.start}") from None
    except yaml.YAMLError as exc:
        raise InputError(path, WHOLE_FILE, f"valid YAML ({str(exc).splitlines()[0]})") from None


def _model(rd, d, base):
    """The model section; ``frf_backend`` applies to every model type."""
    backend = rd.choice(d, "frf_backend", "model.frf_backend", FRF_BACKENDS, ModelConfig.frf_backend)
    cutoff = rd.number(d, "reduced_cutoff", "model.reduced_cutoff", ModelConfig.reduced_cutoff,
                       positive=True)
    if cutoff <= 1.0:
        raise rd.err("model.reduced_cutoff", "a number > 1 (multiple of the band's top frequency)",
                     cutoff)
    return replace(_model_kind(rd, d, base), frf_backend=backend, reduced_cutoff=float(cutoff))


def _model_kind(rd, d, base):
    rd.check_keys(d, "model", {"type", "masses", "stiffnesses", "file", "script", "M", "K",
                               "dof_map", "constrained", "stiffness_groups", "mass_groups", "ndm",
                               "frf_backend", "reduced_cutoff"})
    kind = rd.choice(d, "type", "model.type", MODEL_TYPES, ModelConfig.type)
    if kind == "shear_frame":
        if "masses" not in d:
            raise rd.err("model.masses", "a list of floor masses in kg (required)")
        if "stiffnesses" not in d:
            raise rd.err("model.stiffnesses", "a list of story stiffnesses in N/m (required)")
        m = rd.numbers(d["masses"], "model.masses", positive=True)
        k = rd.numbers(d["stiffnesses"], "model.stiffnesses", positive=True)
        if len(k) != len(m):
            raise rd.err("model.stiffnesses", f"{len(m)} values, one per story like model.masses",
                         f"{len(k)} values")
        return ModelConfig(type=kind, masses=m, stiffnesses=k)
    if kind == "opensees":
        return _opensees_model(rd, d, base)
    if "file" in d:
        f = os.path.join(base, str(d["file"]))
        if not os.path.isfile(f):
            raise rd.err("model.file", "an existing file", d["file"])
        return ModelConfig(type=kind, file=f)
    if "M" not in d or "K" not in d:
        raise rd.err("model.K" if "M" in d else "model.M", "matrix files model.M and model.K "
                     "(.mtx, .npz, .mat), or model.file with M0, K0, M_infl, K_infl")
    out = {key: _matrix_spec(rd, d[key], f"model.{key}", base) for key in ("M", "K")}
    for section in ("stiffness_groups", "mass_groups"):
        groups = rd.mapping(d, f"model.{section}")
        out[section] = {str(k): _matrix_spec(rd, v, f"model.{section}.{k}", base)
                        for k, v in groups.items()}
    if not out["stiffness_groups"] and not out["mass_groups"]:
        raise rd.err("model.stiffness_groups", "at least one group matrix (an updating parameter)")
    if d.get("dof_map") is not None:
        out["dof_map"] = existing(rd, d["dof_map"], "model.dof_map", base)
    cons = d.get("constrained") or []
    if not isinstance(cons, list) or not all(isinstance(c, list) and len(c) == 2 for c in cons):
        raise rd.err("model.constrained", "a list of [node, dof] pairs", cons)
    out["constrained"] = tuple((c[0], c[1]) for c in cons)
    if d.get("ndm") is not None:
        out["ndm"] = rd.number(d, "ndm", "model.ndm", integer=True)
        if out["ndm"] not in (2, 3):
            raise rd.err("model.ndm", "2 or 3", out["ndm"])
    return ModelConfig(type=kind, **out)



def _matrix_spec(rd, v, key, base):
    """A matrix file: a path, or {file, key} for one array of an NPZ/MAT file."""
    if isinstance(v, dict):
        rd.check_keys(v, key, {"file", "key"})
        if "file" not in v:
            raise rd.err(f"{key}.file", "the matrix file's path")
        return {"file": existing(rd, v["file"], f"{key}.file", base),
                "key": None if v.get("key") is None else str(v["key"])}
    if not isinstance(v, str):
        raise rd.err(key, "a matrix file path (.mtx, .npz, .mat) or {file, key}", v)
    return existing(rd, v, key, base)


def _opensees_model(rd, d, base):
    if "script" not in d:
        raise rd.err("model.script", "the path of an OpenSeesPy model script (required)")
    script = existing(rd, d["script"], "model.script", base)
    out = {}
    for section in ("stiffness_groups", "mass_groups"):
        groups = rd.mapping(d, f"model.{section}")
        for k, v in groups.items():
            ok = isinstance(v, str) or (isinstance(v, list) and v and all(
                isinstance(x, int) and not isinstance(x, bool) for x in v)) or (
                isinstance(v, dict) and set(v) <= {"elements", "nodes"})
            if not ok:
                raise rd.err(f"model.{section}.{k}", "a group name of the script's `groups`, a "
                             "list of element tags, or {elements: [...], nodes: [...]}", v)
        out[section] = {str(k): v for k, v in groups.items()}
    if not out["stiffness_groups"] and not out["mass_groups"]:
        raise rd.err("model.stiffness_groups", "at least one element group (an updating parameter)")
    return ModelConfig(type="opensees", script=script, **out)


def _parameters(rd, d):
    rd.check_keys(d, "parameters", {"stiffness_bounds", "mass_bounds", "fixed", "initial",
                                    "bounds", "tie", "total_mass", "prior"})
    out = {}
    for key in ("stiffness_bounds", "mass_bounds"):
        if key in d:
            lo, hi = rd.interval(d[key], f"parameters.{key}")
            if lo <= -1:
                raise rd.err(f"parameters.{key}", "relative bounds with lower > -1 "
                             "(a mass or stiffness must stay positive)", list(d[key]))
            out[key] = (lo, hi)
    for key in ("fixed", "initial"):
        m = rd.mapping(d, f"parameters.{key}")
        out[key] = {str(k): _value_or_multiplier(rd, m, k, f"parameters.{key}.{k}") for k in m}
    bm = rd.mapping(d, "parameters.bounds")
    out["bounds"] = {str(k): _value_or_multiplier(rd, bm, k, f"parameters.bounds.{k}", pair=True)
                     for k in bm}
    tm = rd.mapping(d, "parameters.tie")
    ties = {}
    for label, names in tm.items():
        if not isinstance(names, list) or len(names) < 2 or not all(isinstance(x, str) for x in names):
            raise rd.err(f"parameters.tie.{label}", "a list of two or more parameter names", names)
        ties[str(label)] = tuple(names)
    out["ties"] = ties
    out["total_mass"] = rd.number(d, "total_mass", "parameters.total_mass", positive=True)
    pm = rd.mapping(d, "parameters.prior")
    out["prior"] = {str(k): rd.number(pm, k, f"parameters.prior.{k}", required=True, positive=True)
                    for k in pm}
    return ParameterConfig(**out)


def _value_or_multiplier(rd, m, k, path, pair=False):
    """A physical value (a number, or [lo, hi] for bounds) or ``{multiplier: ...}``."""
    v = m[k]
    if isinstance(v, dict):
        rd.check_keys(v, path, {"multiplier"})
        if "multiplier" not in v:
            raise rd.err(path, "{multiplier: value}", v)
        if pair:
            lo, hi = rd.interval(v["multiplier"], f"{path}.multiplier")
            if lo <= 0:
                raise rd.err(f"{path}.multiplier", "multipliers > 0", list(v["multiplier"]))
            return Multiplier((lo, hi))
        return Multiplier(rd.number(v, "multiplier", f"{path}.multiplier", positive=True))
    if pair:
        return rd.interval(v, path)
    return rd.number(m, k, path, required=True)


def _damping(rd, d, n):
    rd.check_keys(d, "damping", {"model", "zeta", "a0", "a1", "matrix", "modal_zeta",
                                 "diag_factor", "offdiag", "modes"})
    model = rd.choice(d, "model", "damping.model", DAMPING_MODELS, DampingConfig.model)
    out = dict(model=model)
    out["zeta"] = rd.number(d, "zeta", "damping.zeta", DampingConfig.zeta, positive=True)
    out["a0"] = rd.number(d, "a0", "damping.a0")
    out["a1"] = rd.number(d, "a1", "damping.a1")
    if (out["a0"] is None) != (out["a1"] is None):
        raise rd.err("damping.a1" if out["a1"] is None else "damping.a0",
                     "both Rayleigh coefficients a0 [1/s] and a1 [s], or neither")
    for key in ("a0", "a1"):
        if out[key] is not None and out[key] < 0:
            raise rd.err(f"damping.{key}", "a number >= 0", out[key])
    if "matrix" in d:
        rows = d["matrix"]
        if not isinstance(rows, list) or not rows:
            raise rd.err("damping.matrix", "a square matrix as a list of rows", rows)
        mat = tuple(rd.numbers(r, f"damping.matrix[{i}]", length=len(rows)) for i, r in enumerate(rows))
        if n is not None and len(mat) != n:
            raise rd.err("damping.matrix", f"a {n}x{n} matrix (one row per floor)", f"{len(mat)} rows")
        out["matrix"] = mat
    if "modes" in d:
        modes = rd.numbers(d["modes"], "damping.modes", positive=True)
        if any(int(k) != k for k in modes) or (n is not None and max(modes) > n) \
                or len(set(modes)) != len(modes):
            raise rd.err("damping.modes", f"distinct mode numbers from 1 to {n}", d["modes"])
        out["modes"] = tuple(sorted(int(k) for k in modes))
    if "modal_zeta" in d:
        length = len(out["modes"]) if model == "modal_general" and "modes" in out else \
            (None if model == "modal_general" else n)
        out["modal_zeta"] = rd.numbers(d["modal_zeta"], "damping.modal_zeta", length=length,
                                       positive=True)
    out["diag_factor"] = rd.number(d, "diag_factor", "damping.diag_factor",
                                   DampingConfig.diag_factor, positive=True)
    out["offdiag"] = rd.number(d, "offdiag", "damping.offdiag", DampingConfig.offdiag,
                               positive=True)
    if out["diag_factor"] <= 1:
        raise rd.err("damping.diag_factor", "a number > 1", out["diag_factor"])
    return DampingConfig(**out)


def _excitation(rd, d):
    rd.check_keys(d, "excitation", {"type", "floor", "node", "dof", "direction"})
    kind = rd.choice(d, "type", "excitation.type", EXCITATIONS, ExcitationConfig.type)
    if kind == "ground":
        if "floor" in d or "node" in d:
            raise rd.err("excitation", "no floor or node for ground input (direction: ux, uy ...)")
        return ExcitationConfig(type=kind, direction=dof_spec(rd, d, "direction", "excitation"))
    floor, node, dof = location(rd, d, "excitation")
    return ExcitationConfig(type=kind, floor=floor, node=node, dof=dof)



def _updates_and_verification(rd, raw, cfg):
    names = [c.name for c in cfg.data.channels]
    ups = rd.mapping(raw, "updates")
    updates = {}
    for label, chans in ups.items():
        if not isinstance(chans, list) or not chans:
            raise rd.err(f"updates.{label}", "a list of channel names", chans)
        for c in chans:
            if c not in names:
                raise rd.err(f"updates.{label}", f"channel names from data.channels {names}", c)
        updates[str(label)] = tuple(chans)
    ver = rd.mapping(raw, "verification")
    rd.check_keys(ver, "verification", {"closeup_seconds"})
    close = rd.number(ver, "closeup_seconds", "verification.closeup_seconds",
                      CaseConfig.closeup_seconds, positive=True)
    if cfg.data.type == "time_histories":
        inp = cfg.data.input
        ex = ExcitationConfig("ground") if inp["quantity"] == "ground_acceleration" \
            else ExcitationConfig("force", inp["floor"])
        if "excitation" in raw and ex != cfg.excitation:
            raise rd.err("excitation", f"the excitation of data.input ({ex.type}) or no "
                         "excitation section", raw["excitation"])
        cfg = replace(cfg, excitation=ex)
    return replace(cfg, updates=updates, closeup_seconds=close)


def _frequencies(rd, d):
    rd.check_keys(d, "frequencies", {"method", "k", "bands", "points", "fmin", "fmax",
                                     "n_peaks", "min_points_per_peak", "min_coherence"})
    method = rd.choice(d, "method", "frequencies.method", FREQUENCY_METHODS,
                       FrequencyConfig.method)
    out = dict(method=method)
    out["k"] = rd.number(d, "k", "frequencies.k", FrequencyConfig.k, positive=True)
    out["fmin"] = rd.number(d, "fmin", "frequencies.fmin")
    out["fmax"] = rd.number(d, "fmax", "frequencies.fmax")
    if out["fmin"] is not None and out["fmax"] is not None and out["fmin"] >= out["fmax"]:
        raise rd.err("frequencies.fmax", f"a value above fmin = {out['fmin']}", out["fmax"])
    out["n_peaks"] = rd.number(d, "n_peaks", "frequencies.n_peaks", None, positive=True, integer=True)
    out["min_points_per_peak"] = rd.number(d, "min_points_per_peak",
                                           "frequencies.min_points_per_peak",
                                           FrequencyConfig.min_points_per_peak, positive=True,
                                           integer=True)
    out["min_coherence"] = rd.number(d, "min_coherence", "frequencies.min_coherence")
    if out["min_coherence"] is not None and not 0 <= out["min_coherence"] <= 1:
        raise rd.err("frequencies.min_coherence", "a value in [0, 1]", out["min_coherence"])
    if method == "bands":
        bands = d.get("bands")
        if not isinstance(bands, list) or not bands:
            raise rd.err("frequencies.bands", "a list of [f_lo, f_hi] bands in Hz", bands)
        out["bands"] = tuple(rd.interval(b, f"frequencies.bands[{i}]") for i, b in enumerate(bands))
    if method == "points":
        out["points"] = rd.numbers(d.get("points"), "frequencies.points", positive=True)
    return FrequencyConfig(**out)


def _objective(rd, d):
    rd.check_keys(d, "objective", {"residual", "prefit"})
    return ObjectiveConfig(residual=rd.choice(d, "residual", "objective.residual", RESIDUALS,
                                              ObjectiveConfig.residual),
                           prefit=rd.choice(d, "prefit", "objective.prefit", PREFITS,
                                            ObjectiveConfig.prefit))


def _solver(rd, d):
    rd.check_keys(d, "solver", {"name", "options", "compile"})
    name = rd.choice(d, "name", "solver.name", SOLVERS, SolverSection.name)
    opts = rd.mapping(d, "solver.options")
    comp = d.get("compile", SolverSection.compile)
    if not isinstance(comp, bool):
        raise rd.err("solver.compile", "true or false", comp)
    return SolverSection(name=name, options=dict(opts), compile=comp)


def _search(rd, d):
    rd.check_keys(d, "search", {"starts", "trial_factor", "seed", "workers", "executor",
                                "scheduler", "band_continuation"})
    bands = d.get("band_continuation") or ()
    if not isinstance(bands, (list, tuple)):
        raise rd.err("search.band_continuation", "a list of increasing frequencies in Hz", bands)
    bands = tuple(rd.numbers(bands, "search.band_continuation", positive=True)) if bands else ()
    if any(b >= a for a, b in zip(bands[1:], bands[:-1])):
        raise rd.err("search.band_continuation", "a list of increasing frequencies in Hz", list(bands))
    return SearchSection(
        band_continuation=bands,
        starts=rd.number(d, "starts", "search.starts", SearchSection.starts, positive=True, integer=True),
        trial_factor=rd.number(d, "trial_factor", "search.trial_factor", SearchSection.trial_factor,
                               positive=True,
                               integer=True),
        seed=rd.number(d, "seed", "search.seed", SearchSection.seed, integer=True),
        workers=rd.number(d, "workers", "search.workers", SearchSection.workers,
                          positive=True, integer=True),
        executor=rd.choice(d, "executor", "search.executor", EXECUTORS, SearchSection.executor),
        scheduler=scheduler_address(rd.err, d.get("scheduler"), "search.scheduler"),
    )

