"""Updating parameters: names, bounds, fixing, tying and scaling.

Every model parameter theta_i (alpha, beta, damping) either is fixed, or maps
to one decision variable z_j of the NLP; several parameters may share one
variable (a tie, e.g. one alpha for several stories). With a per-parameter
scale s_i the map is affine:

    theta = T z + c,    T_ij = s_i if parameter i uses variable j.
"""

from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["Parameter", "ParameterSet"]


@dataclass(frozen=True)
class Parameter:
    """One model parameter.

    Attributes
    ----------
    name : str
        ``k1``, ``m3``, ``L[2,1]``, ``a0``...
    group : str
        ``"stiffness"`` (alpha), ``"mass"`` (beta) or ``"damping"``.
    initial, lower, upper : float
        Start value and box bounds (Eqn 25e), in model units: relative change
        for alpha and beta, the damping model's own units otherwise.
    fixed : bool
        Held at ``initial`` (a weighed mass, for instance).
    tie : str or None
        Parameters with the same tie label share one variable.
    scale : float
        Typical magnitude, so decision variables are O(1).
    nominal : float
        Physical value at theta = 0 for alpha/beta (kg, N/m); None otherwise.
    unit : str or None
        Unit of the reported value ``nominal * (1 + theta)``: ``"kg"``, ``"N/m"``, or
        ``"x nominal"`` for a parameter that scales a matrix group; None: by group.
    """

    name: str
    group: str
    initial: float
    lower: float
    upper: float
    fixed: bool = False
    tie: str = None
    scale: float = 1.0
    nominal: float = None
    unit: str = None


@dataclass(frozen=True)
class ParameterSet:
    """Ordered parameters: alpha (stiffness), beta (mass), then damping."""

    params: tuple
    n_alpha: int
    n_beta: int
    _groups: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        groups = []
        label_of = {}
        for i, p in enumerate(self.params):
            if p.fixed:
                continue
            key = ("tie", p.tie) if p.tie else ("own", i)
            if key not in label_of:
                label_of[key] = len(groups)
                groups.append([])
            groups[label_of[key]].append(i)
        object.__setattr__(self, "_groups", tuple(tuple(g) for g in groups))

    # --- sizes and names -------------------------------------------------
    @property
    def n_theta(self):
        return len(self.params)

    @property
    def n_z(self):
        return len(self._groups)

    @property
    def names(self):
        return tuple(p.name for p in self.params)

    @property
    def z_names(self):
        """A name per decision variable (``k2+k3`` for a tie)."""
        return tuple("+".join(self.params[i].name for i in g) for g in self._groups)

    @property
    def groups(self):
        """Parameter indices behind each decision variable."""
        return self._groups

    @property
    def n_physics(self):
        """Parameters of added physics (group "physics"), kept last."""
        return sum(p.group == "physics" for p in self.params)

    def slices(self):
        """Index ranges of alpha, beta and damping inside theta."""
        a, b = self.n_alpha, self.n_alpha + self.n_beta
        return slice(0, a), slice(a, b), slice(b, self.n_theta - self.n_physics)

    def physics_slice(self):
        """Index range of the added-physics parameters inside theta."""
        return slice(self.n_theta - self.n_physics, self.n_theta)

    # --- the affine map theta = T z + c ---------------------------------
    @property
    def T(self):
        T = np.zeros((self.n_theta, self.n_z))
        for j, g in enumerate(self._groups):
            for i in g:
                T[i, j] = self.params[i].scale
        return T

    @property
    def c(self):
        return np.array([p.initial if p.fixed else 0.0 for p in self.params])

    def theta(self, z):
        """Model parameters from decision variables (numpy or CasADi)."""
        return self.T @ z + self.c

    def z_from_theta(self, theta):
        """Decision variables for theta (least squares over ties)."""
        theta = np.asarray(theta, dtype=float)
        z = np.empty(self.n_z)
        for j, g in enumerate(self._groups):
            z[j] = np.mean([theta[i] / self.params[i].scale for i in g])
        return z

    @property
    def z0(self):
        return self.z_from_theta([p.initial for p in self.params])

    @property
    def z_bounds(self):
        """Bounds on z: the tightest over each tie group."""
        lo = np.empty(self.n_z)
        hi = np.empty(self.n_z)
        for j, g in enumerate(self._groups):
            lo[j] = max(self.params[i].lower / self.params[i].scale for i in g)
            hi[j] = min(self.params[i].upper / self.params[i].scale for i in g)
        return lo, hi

    def with_initial(self, theta):
        """A copy whose initial values are theta (fixed ones unchanged)."""
        new = tuple(p if p.fixed else replace(p, initial=float(t))
                    for p, t in zip(self.params, theta))
        return replace(self, params=new)
