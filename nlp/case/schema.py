"""The case file's schema: every option, its choices and its default, in typed dataclasses.

One home per option: the reader (:mod:`nlp.case.load`) validates YAML against these
tuples and fills these dataclasses; docs/case_reference.md is generated from the
comment beside each field (:mod:`nlp.case.reference`).
"""

from dataclasses import dataclass, field

from nlp.frf.backends import BACKENDS as FRF_BACKENDS
from nlp.frf.estimate import ESTIMATORS
from nlp.frf.forms import OUTPUTS
from nlp.frf.reference import EXCITATIONS
from nlp.io.quality import DROPOUT_MIN_SAMPLES, SPIKE_THRESHOLD
from nlp.io.readers import FRF_FORMATS, MAGNITUDE_ONLY
from nlp.solve.executors import EXECUTORS
from nlp.solve.problem import PREFITS, SOLVERS
from nlp.solve.residuals import RESIDUALS
from nlp.solve.search import SearchSettings

__all__ = ["CaseConfig", "ModelConfig", "ParameterConfig", "DampingConfig", "ExcitationConfig",
           "ChannelConfig", "DataConfig", "ScreenConfig", "Multiplier", "FrequencyConfig",
           "ObjectiveConfig", "SolverSection", "SearchSection", "OUTPUTS", "RESIDUALS", "PREFITS", "SOLVERS",
           "FRF_BACKENDS", "MODEL_TYPES", "DAMPING_MODELS", "EXCITATIONS", "DATA_TYPES",
           "DATA_FORMATS", "DB_FORMATS", "MAGNITUDE_ONLY", "ESTIMATORS", "INPUT_QUANTITIES",
           "CHANNEL_QUANTITIES", "FREQUENCY_METHODS", "EXECUTORS"]

MODEL_TYPES = ("shear_frame", "matrices", "opensees")
DAMPING_MODELS = ("general", "rayleigh", "modal", "modal_general", "dashpots")
DATA_TYPES = ("frf", "time_histories")
DATA_FORMATS = ("auto", "npz") + FRF_FORMATS
DB_FORMATS = ("db", "db_magnitude")            # formats that data.db_reference applies to
INPUT_QUANTITIES = ("ground_acceleration", "force")
CHANNEL_QUANTITIES = ("acceleration", "displacement", "velocity")
FREQUENCY_METHODS = ("half_power", "bands", "points", "all")



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
    spike_threshold: float = SPIKE_THRESHOLD   # robust standard deviations from the local cubic
    dropout_min_samples: int = DROPOUT_MIN_SAMPLES  # identical samples in a row


@dataclass(frozen=True)
class OtherTest:
    """Another test of the same structure fitted jointly with data.file (data.tests[])."""
    file: str                              # (required) FRF file, same layout and sensors as data.file
    force_floor: int = None                # its shaker floor (force input; default: excitation.floor)
    label: str = None                      # name in reports and channel names (default: file stem)


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
    tests: tuple = ()                      # other tests of the structure fitted jointly: list of {file, force_floor, label} (same sensors and grid)
    db_reference: float = 1.0              # |H| that 0 dB stands for, in the file's FRF unit
    records: tuple = ()                    # time histories: several records averaged (abs. paths)
    columns: tuple = None                  # names of a headerless text file's columns
    skip_rows: int = 0                     # leading lines of a text file to skip
    time_column: str = None                # time column [s] (default t or time)
    fs: float = None                       # sampling rate [Hz] when there is no time column
    screen: ScreenConfig = field(default_factory=ScreenConfig)  # spikes and dropouts
    calibration: float = None              # every transducer's sensitivity known within +- this fraction (its certificate): diagnose fits each channel's gain inside it and names only a gain beyond it

    @property
    def has_phase(self):
        """False for magnitude-only FRF files."""
        return self.format not in MAGNITUDE_ONLY


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
    residual: str = "log_magnitude"        # log_magnitude | magnitude | relative_magnitude | complex (needs phase)
    prefit: str = "auto"                   # auto | none | magnitude | relative_magnitude | complex: a first solve of every start on this residual (nlp.solve.problem.prefit_residual); auto: complex (relative_magnitude without phase) for log_magnitude fits on the sparse or reduced backend


@dataclass(frozen=True)
class SolverSection:
    name: str = "ipopt"                    # ipopt | sqpmethod
    options: dict = field(default_factory=dict)  # passed to CasADi's nlpsol
    compile: bool = True                   # compile the residual and Jacobian to C (cached)


@dataclass(frozen=True)
class SearchSection(SearchSettings):
    """The shared search settings (:class:`nlp.solve.search.SearchSettings`) and continuation."""

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
