"""The data that the stages of one look at a case pass on (nlp.diagnosis.driver).

A look fits the points of its windows (Points), updates the case's own model on them
(Baseline), adds candidate physics round by round (Selection), checks the final model
beyond the windows (Checks) and states a verdict (Conclusion).
"""

from dataclasses import dataclass, field
from typing import Any, Optional


@dataclass
class Options:
    """The search's breadth: refits per round (top) and rounds (max_findings)."""
    top: int = 4
    max_findings: int = 3


@dataclass
class Points:
    """The fitted points (fit), the held-out shoulders (held), their noise levels, the
    target on the fitted points and the case's own model on it (base)."""
    widen: int
    fit: Any
    held: Any
    sig_fit: Any
    sig_held: Any
    target: Any
    base: Any
    hot: tuple = ()


@dataclass
class Seed:
    """The first look's optima and findings, which start a widened look after findings:
    its baseline is solved from them instead of searched, and each finding is refitted
    alone in its round before the other candidates are searched."""
    z_base: Any
    z_final: Any
    found: list


@dataclass
class Baseline:
    """The case's own model at its optimum: chi-square chi on nu degrees of freedom,
    held-out mean z^2, residual map, and the spread a right noise model gives (sd, n_eff)."""
    res: Any
    converged: bool
    chi: float
    nu: int
    n_fit: int
    held: float
    cells: list
    spread: tuple
    # the baseline with every gain inside the calibration tolerance, when gains beyond it
    # were freed after it (nlp.diagnosis.gains): the "before" of the report
    before: Any = None


@dataclass
class Selection:
    """What the rounds of candidate refits found, and the current model after them
    (state: dict of current enrichments, z, chi, held and problem)."""
    state: dict
    found: list = field(default_factory=list)
    alternatives: list = field(default_factory=list)
    absorbed: list = field(default_factory=list)
    tried: list = field(default_factory=list)
    indistinct: list = field(default_factory=list)
    unresolved: list = field(default_factory=list)   # better, but the data cannot resolve them
    phis: list = field(default_factory=list)
    unconfirmed: list = field(default_factory=list)
    consistency: list = field(default_factory=list)
    reciprocity: list = field(default_factory=list)   # gain ratios two tests fix (reciprocity)


@dataclass
class Checks:
    """The final model beyond its windows: effects inside the model class, phase and loss
    checks, the whole band; and the records of the other tests kept for the verdict."""
    inside: dict
    phase: Optional[dict]
    loss: Optional[dict]
    whole: Optional[dict]
    consistency: list
    unconfirmed: list
    tests_alone: list = field(default_factory=list)   # joint diagnoses (nlp.diagnosis.joint)


@dataclass
class Conclusion:
    """A look's result (diagnosis.json) and what its figures are drawn from."""
    result: dict
    case: Any
    base: Any
    z_base: Any
    improved: Any
    z_improved: Any
    cells_before: list
    cells_after: list
    family: Optional[str]
