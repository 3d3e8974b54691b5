"""The case file: typed dataclasses, validated once at load.

Every user mistake raises one :class:`nlp.errors.InputError` naming the file,
the key and what is expected. See the README's case-file reference.
"""

from dataclasses import dataclass, field, replace
import math
import os
import re

import yaml

from nlp.errors import InputError
from nlp.solve.executors import EXECUTORS

__all__ = ["CaseConfig", "load_case", "ModelConfig", "ParameterConfig", "DampingConfig",
           "ExcitationConfig", "ChannelConfig", "DataConfig", "ScreenConfig", "Multiplier", "FrequencyConfig",
           "ObjectiveConfig", "SolverSection", "SearchSection"]

OUTPUTS = ("receptance", "mobility", "accelerance", "absolute_accelerance")
RESIDUALS = ("log_magnitude", "magnitude", "complex")
SOLVERS = ("ipopt", "sqpmethod")
FRF_BACKENDS = ("auto", "dense", "sparse", "reduced")   # nlp.frf.backends.BACKENDS


MODEL_TYPES = ("shear_frame", "matrices", "opensees")


@dataclass(frozen=True)
class ModelConfig:
    type: str = "shear_frame"      # "shear_frame" | "matrices" | "opensees"
    masses: tuple = ()             # shear_frame (required): floor masses [kg], ground up
    stiffnesses: tuple = ()        # shear_frame (required): story stiffnesses [N/m]
    file: str = None               # matrices: NPZ or MAT with M0, K0, M_infl, K_infl
    script: str = None             # opensees: the OpenSeesPy model script
    M: object = None               # matrices: path or {file, key} of M0 (.mtx, .npz, .mat)
    K: object = None               # matrices: same for K0
    dof_map: str = None            # matrices: (node, dof) of each row (CSV or array)
    constrained: tuple = ()        # matrices: (node, dof) rows to remove
    stiffness_groups: dict = field(default_factory=dict)   # name -> group / matrix spec
    mass_groups: dict = field(default_factory=dict)        # name -> group / matrix spec (masses)
    ndm: int = None                # spatial dimension, for DOF names of a 3-D truss
    frf_backend: str = "auto"      # auto | dense | sparse | reduced (nlp.frf.backends)
    reduced_cutoff: float = 2.0    # reduced backend: basis modes up to this multiple of the band's top frequency (> 1)


@dataclass(frozen=True)
class Multiplier:
    """A value stated as a multiple of the nominal one: ``{multiplier: x}`` (a number)
    or, for bounds, ``{multiplier: [lo, hi]}`` (a pair)."""

    value: object


@dataclass(frozen=True)
class ParameterConfig:
    stiffness_bounds: tuple = (-0.5, 1.0)   # [lo, hi] relative change of every stiffness [-]
    mass_bounds: tuple = (-0.5, 1.0)        # [lo, hi] relative change of every mass [-]
    # Values in physical units (kg, N/m; damping in its model's units) or Multiplier
    fixed: dict = field(default_factory=dict)     # name -> value [kg, N/m] or {multiplier: x}
    initial: dict = field(default_factory=dict)   # name -> start value [kg, N/m] or {multiplier: x}
    bounds: dict = field(default_factory=dict)    # name -> [lo, hi] [kg, N/m] or {multiplier: [lo, hi]}
    ties: dict = field(default_factory=dict)      # (key: tie) label -> list of names sharing one variable
    total_mass: float = None                      # known total mass, anchors the scale [kg]
    prior: dict = field(default_factory=dict)     # diagnose: {masses: s, stiffnesses: s, <name>: s}, relative 1-sigma of the nominal value [-]


@dataclass(frozen=True)
class DampingConfig:
    model: str = "general"                 # general | rayleigh | modal | modal_general | dashpots
    zeta: float = 0.02                     # initial Rayleigh ratio at modes 1 and n [-]
    a0: float = None                       # initial Rayleigh mass coefficient [1/s] (with a1)
    a1: float = None                       # initial Rayleigh stiffness coefficient [s] (with a0)
    matrix: tuple = None                   # initial C, list of rows [N s/m]
    modal_zeta: tuple = None               # modal: initial damping ratio of each mode [-]
    diag_factor: float = 30.0              # general: bounds of L[i,i] as a factor of the start [-]
    offdiag: float = 3.0                   # general: bound of |L[i,j]| relative to the diagonal [-]
    modes: tuple = None                    # modal_general: 1-based nominal modes (default: the band's)


@dataclass(frozen=True)
class ExcitationConfig:
    type: str = "ground"                   # ground | force
    floor: int = None                      # force: floor of the shaker, 1 = lowest
    node: int = None                       # force at a node ...
    dof: object = None                     # ... and DOF (number 1-6 or name ux..rz)
    direction: object = None               # ground: DOF of the table motion (default ux)


@dataclass(frozen=True)
class ChannelConfig:
    name: str                              # channel name (default ch1, ch2, ...)
    floor: int                             # (required unless node and dof) 1 = lowest floor, 0 = base sensor
    output: str                            # FRF file (required): receptance | mobility | accelerance | absolute_accelerance
    column: object                         # FRF file: 0-based FRF index (default: list order); records: column name (default: name)
    weight: float = 1.0                    # weight of the channel's residuals [-]
    quantity: str = None                   # time histories: acceleration | displacement | velocity
    unit: str = None                       # time histories: unit in the file (g, mm, m/s^2, ...)
    node: int = None                       # sensor at a node ...
    dof: object = None                     # ... and DOF (number 1-6 or name ux..rz)
    scale: float = 1.0                     # calibration: file value x scale = value in the unit
    sign: int = 1                          # 1, or -1 for a sensor mounted the other way


@dataclass(frozen=True)
class ScreenConfig:
    remove: bool = False                   # replace spikes/dropouts by interpolation (recorded)
    spike_threshold: float = 8.0           # robust standard deviations from the local cubic
    dropout_min_samples: int = 5           # identical samples in a row


@dataclass(frozen=True)
class DataConfig:
    file: str                              # (required unless records) data file, relative to the case
    format: str = "auto"                   # auto | npz | complex | magphase | db | magnitude | db_magnitude
    unit_factor: float = 1.0               # multiplies the file's FRF to SI [-]
    channels: tuple = ()                   # (required) list of channels (data.channels[] below)
    type: str = "frf"                      # frf | time_histories
    input: dict = None                     # time histories (required): {column, quantity, unit, floor, scale, sign, from: {column, mass, unit}}
    estimator: str = "H1"                  # H1 | H2 | Hv (total least squares)
    nperseg: object = None                 # Welch segment [samples] or "all" (default: largest power of 2 <= N/8)
    overlap: float = 0.5                   # Welch (or the FRF file's) segment overlap [-]
    window: str = "hann"                   # Welch window (scipy.signal name); boxcar when nperseg is all; FRF files: the analyzer's window, whose kernel the model carries (a file that states a single average: none), none if not windowed (simulated or measured bin by bin)
    validation_file: str = None            # another test of the same structure (held out)
    validation_force_floor: int = None     # its shaker floor, when it differs (force input)
    level_files: tuple = ()                # the same test at other excitation levels
    db_reference: float = 1.0              # |H| that 0 dB stands for, in the file's FRF unit
    records: tuple = ()                    # time histories: several records averaged (abs. paths)
    columns: tuple = None                  # names of a headerless text file's columns
    skip_rows: int = 0                     # leading lines of a text file to skip
    time_column: str = None                # time column [s] (default t or time)
    fs: float = None                       # sampling rate [Hz] when there is no time column
    screen: ScreenConfig = field(default_factory=ScreenConfig)  # spikes and dropouts

    @property
    def has_phase(self):
        """False for magnitude-only FRF files."""
        return self.format not in ("magnitude", "db_magnitude")


@dataclass(frozen=True)
class FrequencyConfig:
    method: str = "half_power"             # half_power | bands | points | all
    k: float = 1.0                         # half_power: window half-width in half-power bandwidths [-]
    bands: tuple = ()                      # bands: list of [f_lo, f_hi] [Hz]
    points: tuple = ()                     # points: list of frequencies [Hz]
    fmin: float = None                     # lowest frequency used [Hz]
    fmax: float = None                     # highest frequency used [Hz]
    n_peaks: int = None                    # half_power: number of peaks (default: all found)
    min_points_per_peak: int = 5           # half_power: widen a window to at least this many points
    min_coherence: float = None            # drop points below this coherence (records) [-]


@dataclass(frozen=True)
class ObjectiveConfig:
    residual: str = "log_magnitude"        # log_magnitude | magnitude | complex (needs phase)


@dataclass(frozen=True)
class SolverSection:
    name: str = "ipopt"                    # ipopt | sqpmethod
    options: dict = field(default_factory=dict)  # passed to CasADi's nlpsol
    compile: bool = True                   # compile the residual and Jacobian to C (cached)


@dataclass(frozen=True)
class SearchSection:
    starts: int = 20                       # local solves of the scatter search
    trial_factor: int = 10                 # trial points per start
    seed: int = 0                          # seed of the trial points
    workers: int = 1                       # worker processes
    executor: str = "local"      # where local solves run (nlp.solve.executors): local | dask | serial
    scheduler: str = None        # Dask scheduler address, e.g. tcp://10.0.0.5:8786
    band_continuation: tuple = ()  # upper frequencies [Hz] of sub-bands fitted in turn from the initial model; the result competes with the starts (nlp.solve.continuation)


@dataclass(frozen=True)
class CaseConfig:
    path: str                                     # (internal) absolute path of the case file
    name: str                                     # case name (default: the case folder's name)
    description: str                              # free text
    model: ModelConfig
    parameters: ParameterConfig
    damping: DampingConfig
    excitation: ExcitationConfig
    data: DataConfig
    frequencies: FrequencyConfig
    objective: ObjectiveConfig
    solver: SolverSection
    search: SearchSection
    updates: dict = field(default_factory=dict)   # name -> channel names, averaged (Table 1)
    closeup_seconds: float = 3.0                  # (key: verification.closeup_seconds) close-up length [s]


class _Loader(yaml.SafeLoader):
    """SafeLoader that reads YAML 1.2 floats too: ``2.552e6`` and ``1e-3`` are numbers
    (YAML 1.1 wants a dot and a signed exponent, and would read them as text)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


class _Reader:
    """Typed access to a YAML mapping with errors that name file and key."""

    def __init__(self, file):
        self.file = file

    def err(self, key, expected, got=None):
        return InputError(self.file, key, expected, got)

    def mapping(self, d, key, required=False):
        if key is not None:
            if not isinstance(d, dict):
                raise self.err(key.rsplit(".", 1)[0], "a mapping", d)
        v = d if key is None else d.get(key.rsplit(".", 1)[-1])
        if v is None:
            if required:
                raise self.err(key, "a mapping (this section is required)")
            return {}
        if not isinstance(v, dict):
            raise self.err(key, "a mapping of keys to values", v)
        return v

    def check_keys(self, d, key, allowed):
        for k in d:
            if k not in allowed:
                raise self.err(f"{key}.{k}" if key else k,
                               f"one of the known keys {sorted(allowed)}", k)

    def number(self, d, key, path, default=None, positive=False, required=False, integer=False):
        if key not in d or d[key] is None:
            if required:
                raise self.err(path, "a number (required)")
            return default
        v = d[key]
        kind = "an integer" if integer else "a number"
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.err(path, f"{kind}{' > 0' if positive else ''}", v)
        if integer and int(v) != v:
            raise self.err(path, kind, v)
        if positive and v <= 0:
            raise self.err(path, f"{kind} > 0", v)
        return int(v) if integer else float(v)

    def choice(self, d, key, path, choices, default):
        v = d.get(key, default)
        if v not in choices:
            raise self.err(path, f"one of {list(choices)}", v)
        return v

    def numbers(self, v, path, length=None, positive=False):
        if not isinstance(v, (list, tuple)) or not v:
            raise self.err(path, "a non-empty list of numbers", v)
        out = []
        for i, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise self.err(f"{path}[{i}]", "a finite number", x)
            if positive and x <= 0:
                raise self.err(f"{path}[{i}]", "a number > 0", x)
            out.append(float(x))
        if length is not None and len(out) != length:
            raise self.err(path, f"a list of {length} numbers", f"{len(out)} numbers")
        return tuple(out)

    def interval(self, v, path):
        lo, hi = self.numbers(v, path, length=2)
        if not lo < hi:
            raise self.err(path, "[lower, upper] with lower < upper", list(v))
        return lo, hi


def load_case(path, overrides=None):
    """Read and validate a case file; returns a :class:`CaseConfig`.

    overrides : dict of CLI overrides: ``starts``, ``seed``, ``workers``, ``solver``,
        ``executor``, ``scheduler``.
    """
    path = os.path.abspath(path)
    if not os.path.isfile(path):
        raise InputError(path, "<file>", "an existing case YAML file")
    try:
        with open(path, "rb") as fh:
            text = fh.read()
        if b"\0" in text:
            raise InputError(path, "<file>", "a YAML text file", "binary data")
        raw = yaml.load(text.decode("utf-8"), Loader=_Loader)
    except UnicodeDecodeError as exc:
        raise InputError(path, "<file>", "a YAML text file in UTF-8",
                         f"undecodable byte at position {exc.start}") from None
    except yaml.YAMLError as exc:
        raise InputError(path, "<file>", f"valid YAML ({str(exc).splitlines()[0]})") from None
    rd = _Reader(path)
    if not isinstance(raw, dict):
        raise rd.err("<file>", "a YAML mapping at the top level", type(raw).__name__)
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
        data=_data(rd, rd.mapping(raw, "data", required=True), base),
        frequencies=_frequencies(rd, rd.mapping(raw, "frequencies")),
        objective=_objective(rd, rd.mapping(raw, "objective")),
        solver=_solver(rd, rd.mapping(raw, "solver")),
        search=_search(rd, rd.mapping(raw, "search")),
    )
    if not cfg.data.has_phase and cfg.objective.residual == "complex":
        raise rd.err("objective.residual", f"magnitude or log_magnitude (data.format "
                     f"{cfg.data.format} has no phase)", "complex")
    cfg = _updates_and_verification(rd, raw, cfg)
    return _apply_overrides(cfg, overrides or {}, rd)


def _model(rd, d, base):
    """The model section; ``frf_backend`` applies to every model type."""
    backend = rd.choice(d, "frf_backend", "model.frf_backend", FRF_BACKENDS, "auto")
    cutoff = rd.number(d, "reduced_cutoff", "model.reduced_cutoff", 2.0, positive=True)
    if cutoff <= 1.0:
        raise rd.err("model.reduced_cutoff", "a number > 1 (multiple of the band's top frequency)",
                     cutoff)
    return replace(_model_kind(rd, d, base), frf_backend=backend, reduced_cutoff=float(cutoff))


def _model_kind(rd, d, base):
    rd.check_keys(d, "model", {"type", "masses", "stiffnesses", "file", "script", "M", "K",
                               "dof_map", "constrained", "stiffness_groups", "mass_groups", "ndm",
                               "frf_backend", "reduced_cutoff"})
    kind = rd.choice(d, "type", "model.type", MODEL_TYPES, "shear_frame")
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
        out["dof_map"] = _existing(rd, d["dof_map"], "model.dof_map", base)
    cons = d.get("constrained") or []
    if not isinstance(cons, list) or not all(isinstance(c, list) and len(c) == 2 for c in cons):
        raise rd.err("model.constrained", "a list of [node, dof] pairs", cons)
    out["constrained"] = tuple((c[0], c[1]) for c in cons)
    if d.get("ndm") is not None:
        out["ndm"] = rd.number(d, "ndm", "model.ndm", integer=True)
        if out["ndm"] not in (2, 3):
            raise rd.err("model.ndm", "2 or 3", out["ndm"])
    return ModelConfig(type=kind, **out)


def _existing(rd, name, key, base):
    f = os.path.join(base, str(name))
    if not os.path.isfile(f):
        raise rd.err(key, "an existing file (relative to the case file)", name)
    return f


def _matrix_spec(rd, v, key, base):
    """A matrix file: a path, or {file, key} for one array of an NPZ/MAT file."""
    if isinstance(v, dict):
        rd.check_keys(v, key, {"file", "key"})
        if "file" not in v:
            raise rd.err(f"{key}.file", "the matrix file's path")
        return {"file": _existing(rd, v["file"], f"{key}.file", base),
                "key": None if v.get("key") is None else str(v["key"])}
    if not isinstance(v, str):
        raise rd.err(key, "a matrix file path (.mtx, .npz, .mat) or {file, key}", v)
    return _existing(rd, v, key, base)


def _opensees_model(rd, d, base):
    if "script" not in d:
        raise rd.err("model.script", "the path of an OpenSeesPy model script (required)")
    script = _existing(rd, d["script"], "model.script", base)
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
    model = rd.choice(d, "model", "damping.model",
                      ("general", "rayleigh", "modal", "modal_general", "dashpots"), "general")
    out = dict(model=model)
    out["zeta"] = rd.number(d, "zeta", "damping.zeta", 0.02, positive=True)
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
    out["diag_factor"] = rd.number(d, "diag_factor", "damping.diag_factor", 30.0, positive=True)
    out["offdiag"] = rd.number(d, "offdiag", "damping.offdiag", 3.0, positive=True)
    if out["diag_factor"] <= 1:
        raise rd.err("damping.diag_factor", "a number > 1", out["diag_factor"])
    return DampingConfig(**out)


def _excitation(rd, d):
    rd.check_keys(d, "excitation", {"type", "floor", "node", "dof", "direction"})
    kind = rd.choice(d, "type", "excitation.type", ("ground", "force"), "ground")
    if kind == "ground":
        if "floor" in d or "node" in d:
            raise rd.err("excitation", "no floor or node for ground input (direction: ux, uy ...)")
        return ExcitationConfig(type=kind, direction=_dof_spec(rd, d, "direction", "excitation"))
    floor, node, dof = _location(rd, d, "excitation")
    return ExcitationConfig(type=kind, floor=floor, node=node, dof=dof)


def _dof_spec(rd, d, key, path):
    """A DOF as given (number 1-6 or name ux..rz); checked against the model at assembly."""
    v = d.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, str)) or (isinstance(v, int) and not 1 <= v <= 6):
        raise rd.err(f"{path}.{key}", "a DOF number 1-6 or a name (ux, uy, uz, rx, ry, rz)", v)
    return v


def _location(rd, d, path, base=False):
    """(floor, node, dof): a floor (shear-frame shorthand, or a row of a matrix model)
    or a node and DOF of an imported model; base: floor 0 (the base) is allowed."""
    if "node" in d or "dof" in d:
        if "floor" in d:
            raise rd.err(f"{path}.floor", "either floor or node and dof, not both", d["floor"])
        node = rd.number(d, "node", f"{path}.node", required=True, integer=True)
        if d.get("dof") is None:
            raise rd.err(f"{path}.dof", "a DOF number 1-6 or a name (ux, uy, uz, rx, ry, rz)")
        return None, node, _dof_spec(rd, d, "dof", path)
    if "floor" not in d:
        raise rd.err(f"{path}.floor", "a floor number (required, 1-based), or node and dof")
    floor = rd.number(d, "floor", f"{path}.floor", required=True, integer=True)
    if floor < (0 if base else 1):
        raise rd.err(f"{path}.floor", "a floor number >= 1" + (" (0: a sensor on the base)" if base
                                                                else ""), floor)
    return floor, None, None


_QUANTITY_OUTPUT = {"displacement": "receptance", "velocity": "mobility"}


def _check_window(rd, d, records):
    """data.window: a scipy.signal window name; for FRF files also 'none' (not averaged)."""
    if "window" not in d:
        return
    w = d["window"]
    if not records and w == "none":
        return
    try:
        from scipy.signal import get_window
        get_window(w, 16)
    except (ValueError, TypeError):
        raise rd.err("data.window", "a scipy.signal window name such as hann or boxcar"
                     + ("" if records else ", or none for an FRF not estimated by windowed "
                        "averaging"), w) from None


def _data(rd, d, base):
    rd.check_keys(d, "data", {"type", "file", "format", "unit_factor", "channels", "input",
                              "estimator", "nperseg", "overlap", "window", "validation_file",
                              "validation_force_floor", "level_files", "db_reference", "records",
                              "columns", "skip_rows", "time_column", "fs", "screen"})
    kind = rd.choice(d, "type", "data.type", ("frf", "time_histories"), "frf")
    records = kind == "time_histories"
    rec_paths = _record_files(rd, d, base, records)
    if "file" not in d and not rec_paths:
        raise rd.err("data.file", "the path of the measured data file (required)")
    f = os.path.join(base, str(d["file"])) if "file" in d else rec_paths[0]
    if not os.path.isfile(f):
        raise rd.err("data.file", "an existing file (relative to the case file)", d["file"])
    if "file" in d and rec_paths:
        raise rd.err("data.records", "either data.file or data.records, not both", d["records"])
    val = None
    if d.get("validation_file") is not None:
        val = os.path.join(base, str(d["validation_file"]))
        if not os.path.isfile(val):
            raise rd.err("data.validation_file", "an existing file", d["validation_file"])
    fmt = rd.choice(d, "format", "data.format", ("auto", "npz", "complex", "magphase", "db",
                                                 "magnitude", "db_magnitude"), "auto")
    unit = rd.number(d, "unit_factor", "data.unit_factor", 1.0, positive=True)
    inp = None
    if records:
        inp = rd.mapping(d, "data.input", required=True)
        rd.check_keys(inp, "data.input", {"column", "quantity", "unit", "floor", "from", "scale",
                                          "sign"})
        q = rd.choice(inp, "quantity", "data.input.quantity", ("ground_acceleration", "force"), None)
        src = None
        if "from" in inp:
            src = _force_from(rd, inp, q)
        elif "column" not in inp:
            raise rd.err("data.input.column", "the name of the input record's column (or, for a "
                         "force, from: {column, mass, unit})")
        floor = None
        if q == "force":
            floor = rd.number(inp, "floor", "data.input.floor", required=True, positive=True,
                              integer=True)
        scale, sign = _scale_sign(rd, inp, "data.input")
        inp = {"column": None if src else str(inp["column"]), "quantity": q,
               "unit": inp.get("unit"), "floor": floor, "from": src, "scale": scale, "sign": sign}
    chans = d.get("channels")
    if not isinstance(chans, list) or not chans:
        raise rd.err("data.channels", "a list of channels, each {name, floor, output, column}", chans)
    out = []
    names = set()
    for i, c in enumerate(chans):
        key = f"data.channels[{i}]"
        if not isinstance(c, dict):
            raise rd.err(key, "a mapping {name, floor, output, column}", c)
        rd.check_keys(c, key, {"name", "floor", "output", "column", "weight", "quantity", "unit",
                               "node", "dof", "scale", "sign"})
        name = str(c.get("name", f"ch{i + 1}"))
        if name in names:
            raise rd.err(f"{key}.name", "a unique channel name", name)
        names.add(name)
        floor, node, dof = _location(rd, c, key, base=True)
        w = rd.number(c, "weight", f"{key}.weight", 1.0, positive=True)
        if records:
            if node is not None:
                raise rd.err(f"{key}.node", "a floor (time-history channels are floors of a "
                             "shear frame)", node)
            q = rd.choice(c, "quantity", f"{key}.quantity",
                          ("acceleration", "displacement", "velocity"), None)
            ground = inp["quantity"] == "ground_acceleration"
            output = _QUANTITY_OUTPUT.get(q, "absolute_accelerance" if ground else "accelerance")
            scale, sign = _scale_sign(rd, c, key)
            out.append(ChannelConfig(name=name, floor=floor, output=output,
                                     column=str(c.get("column", name)), weight=w, quantity=q,
                                     unit=c.get("unit"), node=node, dof=dof, scale=scale,
                                     sign=sign))
            continue
        output = rd.choice(c, "output", f"{key}.output", OUTPUTS, None)
        col = rd.number(c, "column", f"{key}.column", i, integer=True)
        if col < 0:
            raise rd.err(f"{key}.column", "a column index >= 0", col)
        scale, sign = _scale_sign(rd, c, key)
        out.append(ChannelConfig(name=name, floor=floor, output=output, column=col, weight=w,
                                 node=node, dof=dof, scale=scale, sign=sign))
    for i, c in enumerate(out):
        # the base moves only with the ground: a fixed-base model predicts the input
        # itself there, a flexible base (diagnose) the base DOF's absolute motion
        if c.floor == 0 and c.output != "absolute_accelerance":
            raise rd.err(f"data.channels[{i}].floor", "a floor >= 1; floor 0 (a sensor on the "
                         "base) is an absolute acceleration under ground excitation "
                         "(records: quantity acceleration with a ground_acceleration input; "
                         "FRF files: output absolute_accelerance)", 0)
    est = rd.choice(d, "estimator", "data.estimator", ("H1", "H2", "Hv"), "H1")
    nperseg = d.get("nperseg")
    if nperseg not in (None, "all"):
        nperseg = rd.number(d, "nperseg", "data.nperseg", positive=True, integer=True)
    overlap = rd.number(d, "overlap", "data.overlap", 0.5)
    if not 0 <= overlap < 1:
        raise rd.err("data.overlap", "a fraction in [0, 1)", overlap)
    vfloor = rd.number(d, "validation_force_floor", "data.validation_force_floor", None,
                       positive=True, integer=True)
    level_paths = _file_list(rd, d.get("level_files") or [], "data.level_files", base)
    dbref = rd.number(d, "db_reference", "data.db_reference", 1.0, positive=True)
    if "db_reference" in d and fmt not in ("db", "db_magnitude"):
        raise rd.err("data.db_reference", "only with format db or db_magnitude", fmt)
    layout = _text_layout(rd, d, records)
    _check_window(rd, d, records)
    return DataConfig(file=f, format=fmt, unit_factor=unit, channels=tuple(out), type=kind,
                      input=inp, estimator=est, nperseg=nperseg, overlap=overlap,
                      window=str(d.get("window", "boxcar" if nperseg == "all" else "hann")),
                      validation_file=val,
                      validation_force_floor=vfloor, level_files=tuple(level_paths),
                      db_reference=dbref, records=tuple(rec_paths), **layout)


def _record_files(rd, d, base, records):
    """Absolute paths of data.records (several records of one test, averaged)."""
    if "records" not in d:
        return []
    if not records:
        raise rd.err("data.records", "records only with type: time_histories", d["records"])
    if not d["records"]:
        raise rd.err("data.records", "a non-empty list of record files", d["records"])
    return _file_list(rd, d["records"], "data.records", base)


def _file_list(rd, v, key, base):
    """Absolute paths of a list of existing files named relative to the case file."""
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise rd.err(key, "a list of file names (relative to the case file)", v)
    out = []
    for i, x in enumerate(v):
        p = os.path.join(base, x)
        if not os.path.isfile(p):
            raise rd.err(f"{key}[{i}]", "an existing file (relative to the case file)", x)
        out.append(p)
    return out


def _scale_sign(rd, d, key):
    """Per-channel calibration: file value x scale x sign = value in the stated unit."""
    scale = rd.number(d, "scale", f"{key}.scale", 1.0, positive=True)
    sign = d.get("sign", 1)
    if isinstance(sign, bool) or sign not in (1, -1):
        raise rd.err(f"{key}.sign", "1 or -1", sign)
    return scale, int(sign)


def _force_from(rd, inp, quantity):
    """data.input.from: a force known as mass x acceleration."""
    if quantity != "force":
        raise rd.err("data.input.from", "only with quantity: force", quantity)
    src = rd.mapping(inp, "data.input.from")
    rd.check_keys(src, "data.input.from", {"column", "mass", "unit"})
    if "column" not in src:
        raise rd.err("data.input.from.column", "the column of the measured acceleration")
    if "column" in inp:
        raise rd.err("data.input.column", "either column or from, not both", inp["column"])
    mass = rd.number(src, "mass", "data.input.from.mass", required=True, positive=True)
    if inp.get("unit") not in (None, "N"):
        raise rd.err("data.input.unit", "no unit with from (the force is mass [kg] x "
                     "acceleration; give the acceleration's unit as from.unit)", inp["unit"])
    return {"column": str(src["column"]), "mass": mass, "unit": src.get("unit")}


def _text_layout(rd, d, records):
    """columns, skip_rows, time_column, fs and screen of the data section."""
    out = {}
    if not records:
        for key in ("columns", "skip_rows", "time_column", "fs", "screen"):
            if key in d:
                raise rd.err(f"data.{key}", "only with type: time_histories", d[key])
        return out
    cols = d.get("columns")
    if cols is not None:
        if not isinstance(cols, list) or not cols or not all(isinstance(x, str) for x in cols) \
                or len(set(cols)) != len(cols):
            raise rd.err("data.columns", "a list of unique column names, in file order", cols)
        out["columns"] = tuple(cols)
    out["skip_rows"] = rd.number(d, "skip_rows", "data.skip_rows", 0, integer=True)
    if out["skip_rows"] < 0:
        raise rd.err("data.skip_rows", "an integer >= 0", out["skip_rows"])
    if d.get("time_column") is not None:
        out["time_column"] = str(d["time_column"])
    out["fs"] = rd.number(d, "fs", "data.fs", None, positive=True)
    sc = rd.mapping(d, "data.screen")
    rd.check_keys(sc, "data.screen", {"remove", "spike_threshold", "dropout_min_samples"})
    remove = sc.get("remove", False)
    if not isinstance(remove, bool):
        raise rd.err("data.screen.remove", "true or false", remove)
    out["screen"] = ScreenConfig(
        remove=remove,
        spike_threshold=rd.number(sc, "spike_threshold", "data.screen.spike_threshold", 8.0,
                                  positive=True),
        dropout_min_samples=rd.number(sc, "dropout_min_samples", "data.screen.dropout_min_samples",
                                      5, positive=True, integer=True))
    return out


def _updates_and_verification(rd, raw, cfg):
    from dataclasses import replace
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
    close = rd.number(ver, "closeup_seconds", "verification.closeup_seconds", 3.0, positive=True)
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
    method = rd.choice(d, "method", "frequencies.method", ("half_power", "bands", "points", "all"),
                       "half_power")
    out = dict(method=method)
    out["k"] = rd.number(d, "k", "frequencies.k", 1.0, positive=True)
    out["fmin"] = rd.number(d, "fmin", "frequencies.fmin")
    out["fmax"] = rd.number(d, "fmax", "frequencies.fmax")
    if out["fmin"] is not None and out["fmax"] is not None and out["fmin"] >= out["fmax"]:
        raise rd.err("frequencies.fmax", f"a value above fmin = {out['fmin']}", out["fmax"])
    out["n_peaks"] = rd.number(d, "n_peaks", "frequencies.n_peaks", None, positive=True, integer=True)
    out["min_points_per_peak"] = rd.number(d, "min_points_per_peak",
                                           "frequencies.min_points_per_peak", 5, positive=True,
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
    rd.check_keys(d, "objective", {"residual"})
    return ObjectiveConfig(residual=rd.choice(d, "residual", "objective.residual", RESIDUALS,
                                              "log_magnitude"))


def _solver(rd, d):
    rd.check_keys(d, "solver", {"name", "options", "compile"})
    name = rd.choice(d, "name", "solver.name", SOLVERS, "ipopt")
    opts = rd.mapping(d, "solver.options")
    comp = d.get("compile", True)
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
        starts=rd.number(d, "starts", "search.starts", 20, positive=True, integer=True),
        trial_factor=rd.number(d, "trial_factor", "search.trial_factor", 10, positive=True,
                               integer=True),
        seed=rd.number(d, "seed", "search.seed", 0, integer=True),
        workers=rd.number(d, "workers", "search.workers", 1, positive=True, integer=True),
        executor=rd.choice(d, "executor", "search.executor", EXECUTORS, "local"),
        scheduler=_scheduler(rd.err, d.get("scheduler"), "search.scheduler"),
    )


def _scheduler(err, v, key):
    """A Dask scheduler address (protocol://host:port) or None."""
    if v is None:
        return None
    if not isinstance(v, str) or "://" not in v:
        raise err(key, "a Dask scheduler address such as tcp://host:8786", v)
    return v


def _apply_overrides(cfg, ov, rd):
    from dataclasses import replace
    search, solver = cfg.search, cfg.solver
    for key in ("starts", "seed", "workers"):
        if ov.get(key) is not None:
            v = ov[key]
            if key != "seed" and v < 1:
                raise InputError("<arguments>", f"--{key}", "an integer >= 1", v)
            search = replace(search, **{key: int(v)})
    if ov.get("executor") is not None:
        search = replace(search, executor=ov["executor"])
    if ov.get("scheduler") is not None:
        search = replace(search, scheduler=_scheduler(
            lambda k, e, g: InputError("<arguments>", k, e, g), ov["scheduler"], "--scheduler"))
    if search.scheduler is not None and search.executor != "dask":
        raise InputError("<arguments>" if ov.get("scheduler") else rd.file, "--scheduler"
                         if ov.get("scheduler") else "search.scheduler",
                         "executor 'dask' with a scheduler (--executor dask)", search.executor)
    if ov.get("solver") is not None:
        if ov["solver"] not in SOLVERS:
            raise InputError("<arguments>", "--solver", f"one of {list(SOLVERS)}", ov["solver"])
        if ov["solver"] != solver.name:
            solver = replace(solver, name=ov["solver"], options={})
    return replace(cfg, search=search, solver=solver)
