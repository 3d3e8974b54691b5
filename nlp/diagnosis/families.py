"""Candidate missing physics: parametric enrichments of M, C, K, extra DOFs, outputs.

Each family is a small frozen dataclass with its parameters (names, start,
bounds, scale, and the "null" value at which it has no effect) and one of

* ``apply(sys, th)``: change the structural system ``sys`` = dict(M, K, C, Kh)
  of CasADi SX matrices, where the dynamic stiffness is
  Z = K - w^2 M + j (w C + Kh) (Kh: hysteretic part); extra DOFs are appended
  after the floors, so floor indices do not move;
* ``output(hr, hi, w, th)``: change one channel's FRF (sensor families).

The same CasADi FRF and NLP (:mod:`nlp.solve.problem`) then fit them. Floors are
numbered 1..n from the ground up in names and locations; 0 is the ground.
"""

from dataclasses import dataclass, field, replace
import math

import casadi as ca
import numpy as np

from nlp.frf.backends.terms import floor_vector, mass_vector
from nlp.model.parameters import Parameter

__all__ = ["FAMILIES", "FrameAction", "frame_action_dK", "condensed_dK", "AddedMass", "BaseFlexibility", "SecondaryOscillator", "LocalDamper",
           "HystereticDamping", "NonadjacentCoupling", "SensorGain", "SensorDelay", "ExtraMode"]


def _spring(A, i, j, v):
    """Add v (e_i - e_j)(e_i - e_j)^T; index None is the ground."""
    A = ca.SX(A)
    for a, sa in ((i, 1), (j, -1)):
        for b, sb in ((i, 1), (j, -1)):
            if a is not None and b is not None:
                A[a, b] = A[a, b] + sa * sb * v
    return A


def _rank_one(A, v, c):
    """A + c v v^T for a numeric v (a floor's weights, :func:`floor_vector`)."""
    return ca.SX(A) + c * ca.DM(np.outer(v, v))


def _floors(ref, n, *fl):
    return [floor_vector(ref, f, n) for f in fl]


def _augment(A, couple, diag):
    """Append one DOF: A -> [[A, couple], [couple^T, diag]]."""
    return ca.vertcat(ca.horzcat(A, couple), ca.horzcat(couple.T, diag))


@dataclass(frozen=True)
class AddedMass:
    """Unmodelled mass dm [kg] at a floor (equipment): on a shear frame its row; on an FE
    model shared by the level's nodes in every translational direction
    (nlp.frf.backends.terms.mass_vector)."""

    floor: int
    family = "added_mass"

    @property
    def names(self):
        return (f"dm{self.floor}",)

    def spec(self, ref):
        m = ref["m_ref"]
        return {"initial": [0.0], "lower": [-0.5 * m], "upper": [2.0 * m], "scale": [0.1 * m],
                "null": [0.0]}

    @property
    def location(self):
        return {"floor": self.floor}

    def apply(self, sys, th, ref):
        M = ca.SX(sys["M"])
        b = mass_vector(ref, self.floor, M.shape[0])
        return {**sys, "M": M + th[0] * ca.DM(np.diag(b))}  # dm spread over the floor's nodes


@dataclass(frozen=True)
class BaseFlexibility:
    """A base DOF between ground and structure: mass m_b, sway spring k_b, dashpot c_b.

    Every ground connection of the structure is re-routed through the base: the model's
    forces act on its motion relative to the base, u - r u_b, with r the base's rigid
    translation (``ref["r"]`` on an FE model: flexible supports; 1 on a shear frame's floors).
    Parameters: base mass [kg], base-to-first-floor stiffness ratio k_b/k_ref
    (log10) and base dashpot [N s/m].

    Damping: with Rayleigh damping (``sys["rayleigh"]`` = (a0, a1)) the base joins the model
    and the law covers it, C = a0 M + a1 K of the model with its base, as an FE program
    assembles it: the a1 K part moves with the base, the a0 M part stays on the motion
    relative to the ground, and the base has a0 m_b + a1 k_b; c_b is damping beyond the law
    (radiation into the soil), 0 by reference. With any other damping matrix, all of C
    moves with the base and c_b is the base's whole dashpot (reference c_ref).
    """

    family = "base_flexibility"

    names = ("m_base", "log10_kb", "c_base")

    @property
    def location(self):
        return {}

    @staticmethod
    def _c(ref):
        return 0.0 if ref.get("rayleigh") else ref["c_ref"]

    def spec(self, ref):
        m, lk, c = ref["m_ref"], math.log10(ref["k_ref"]), self._c(ref)
        return {"initial": [0.5 * m, lk + 1.0, c], "lower": [0.0, lk - 1.0, 0.0],
                "upper": [5.0 * m, lk + 4.0, 50.0 * ref["c_ref"]],
                "scale": [m, 1.0, ref["c_ref"]], "null": [0.0, lk + 6.0, 0.0]}

    def starts(self, ref):
        """Start points spread over the base stiffness (the fit has many local minima)."""
        m, lk, c = ref["m_ref"], math.log10(ref["k_ref"]), self._c(ref)
        return [[0.5 * m, lk + d, c] for d in (-0.3, 0.0, 0.5, 1.0, 1.5)]

    def apply(self, sys, th, ref):
        M, K, C, Kh = (ca.SX(sys[k]) for k in ("M", "K", "C", "Kh"))
        n = M.shape[0]
        one = ca.DM.ones(n) if ref.get("r") is None else ca.vertcat(
            ca.DM(np.asarray(ref["r"], float)), ca.DM.ones(n - len(ref["r"])))
        kb = 10 ** th[1]
        gK, gH = ca.mtimes(K, one), ca.mtimes(Kh, one)
        if sys.get("rayleigh") is not None:
            cM, cK = sys["rayleigh"]
            C = _augment(C, -cK * gK, cK * (ca.dot(one, gK) + kb) + cM * th[0] + th[2])
        else:
            gC = ca.mtimes(C, one)
            C = _augment(C, -gC, ca.dot(one, gC) + th[2])
        # r^T A r on the base's diagonal (the sum of A r when r is all ones: a shear frame)
        return {**sys, "M": _augment(M, ca.SX.zeros(n), th[0]),
                "K": _augment(K, -gK, ca.dot(one, gK) + kb), "C": C,
                "Kh": _augment(Kh, -gH, ca.dot(one, gH))}


ZETA_S_MIN = 0.001   # lower bound of an appendage's damping ratio in its fit


@dataclass(frozen=True)
class SecondaryOscillator:
    """An appendage at a floor: mass ratio mu (to m_ref), frequency f_s [Hz], damping zeta_s.

    resonances : frequencies [Hz] of resonances the current model lacks (extra modes
    of the whole band); refits also start there. Not part of the candidate's identity.
    """

    floor: int
    f0: float = 1.0
    resonances: tuple = field(default=(), repr=False, compare=False)
    family = "secondary_oscillator"

    @property
    def names(self):
        return (f"mu{self.floor}", f"f_s{self.floor}", f"zeta_s{self.floor}")

    @property
    def location(self):
        return {"floor": self.floor}

    def spec(self, ref):
        return {"initial": [0.02, self.f0, 0.02], "lower": [0.0, 0.5 * self.f0, ZETA_S_MIN],
                "upper": [0.5, 2.0 * self.f0, 0.3], "scale": [0.01, 0.1 * self.f0, 0.01],
                "null": [0.0, self.f0, 0.02]}

    def starts(self, ref):
        """A light, lightly damped appendage tuned to each unexplained resonance inside
        the frequency box: the scan's best frequency is a first-order guess, and a refit
        from there can stop in a broad, heavily damped minimum (a tenth below the true
        frequency with a damping ratio of 0.14; see docs/method/diagnosis.md)."""
        return [[0.01, f, 0.02] for f in sorted(set(self.resonances))
                if 0.5 * self.f0 < f < 2.0 * self.f0 and abs(f / self.f0 - 1.0) > 0.02]

    def apply(self, sys, th, ref):
        m_ref = ref["m_ref"]
        M, K, C, Kh = (ca.SX(sys[k]) for k in ("M", "K", "C", "Kh"))
        n = M.shape[0]
        a = floor_vector(ref, self.floor, n)   # it hangs from the floor's mean motion
        ms = th[0] * m_ref
        ws = 2 * math.pi * th[1]
        ks, cs = ms * ws**2, 2 * th[2] * ms * ws

        def attach(A, v):
            return _augment(_rank_one(A, a, v), -v * ca.DM(a), v)

        return {**sys, "M": _augment(M, ca.SX.zeros(n), ms), "K": attach(K, ks), "C": attach(C, cs),
                "Kh": _augment(Kh, ca.SX.zeros(n), 0)}


@dataclass(frozen=True)
class LocalDamper:
    """A dashpot c [N s/m] between floors (i, j); j = 0 is the ground."""

    i: int
    j: int
    family = "local_damper"

    @property
    def names(self):
        return (f"c{self.j}{self.i}",)

    @property
    def location(self):
        return {"between": [self.j, self.i]}

    def spec(self, ref):
        c = ref["c_ref"]
        return {"initial": [0.0], "lower": [0.0], "upper": [50.0 * c], "scale": [c],
                "null": [0.0]}

    def apply(self, sys, th, ref):
        a, b = _floors(ref, sys["C"].shape[0], self.i, self.j)
        return {**sys, "C": _rank_one(sys["C"], a - b, th[0])}


@dataclass(frozen=True)
class HystereticDamping:
    """Frequency-independent loss: Kh = eta K (global) or eta K_story (one story)."""

    story: int = None
    family = "hysteretic_damping"

    @property
    def names(self):
        return ("eta",) if self.story is None else (f"eta{self.story}",)

    @property
    def location(self):
        return {} if self.story is None else {"between": [self.story - 1, self.story]}

    def spec(self, ref):
        return {"initial": [0.0], "lower": [0.0], "upper": [0.2], "scale": [0.01], "null": [0.0]}

    def apply(self, sys, th, ref):
        n = ref["K_parts"][0].shape[0]
        Ks = sys["K"][:n, :n] if self.story is None else ref["K_parts"][self.story - 1]
        Kh = ca.SX(sys["Kh"])
        Kh[:n, :n] = Kh[:n, :n] + th[0] * Ks
        return {**sys, "Kh": Kh}


@dataclass(frozen=True)
class NonadjacentCoupling:
    """A spring k [N/m] between non-adjacent floors i < j (non-shear behaviour)."""

    i: int
    j: int
    family = "nonadjacent_coupling"

    @property
    def names(self):
        return (f"k{self.i}{self.j}",)

    @property
    def location(self):
        return {"between": [self.i, self.j]}

    def spec(self, ref):
        # a brace over two stories can be as stiff as a story or more: an upper bound of half
        # a story held the largest benchmark couplings on it, refused for lying on their
        # bound however strong their evidence (see docs/method/diagnosis.md)
        k = ref["k_ref"]
        return {"initial": [0.0], "lower": [-0.5 * k], "upper": [2.0 * k], "scale": [0.05 * k],
                "null": [0.0]}

    def apply(self, sys, th, ref):
        a, b = _floors(ref, sys["K"].shape[0], self.i, self.j)
        return {**sys, "K": _rank_one(sys["K"], a - b, th[0])}


@dataclass(frozen=True)
class FrameAction:
    """Frame action: the beams of a moment frame bend, so its floors are not shear-coupled only.

    The shear model is read as a one-bay moment frame with the beam-column stiffness ratio
    rho (Blume 1968; Chopra, Dynamics of Structures, sec. 18.2: a floor's beams' EI_b/L over
    the storey's columns' EI_c/h). Its story stiffnesses k_i are the designer's D-values
    (Muto 1974): the columns' 12 EI/h^3 times a_i(rho), a = rho/(1 + rho) above the first
    storey and (0.5 + 2 rho)/(2 + 2 rho) in it, so the updated k_i keep their meaning. With
    the joint rotations condensed out, K becomes the frame's (:func:`frame_action_dK`):
    rho -> infinity (rigid beams, a_i = 1) is the shear frame, and a finite rho couples every
    floor as flexible beams do. One parameter, so it competes with a single non-adjacent
    coupling on equal terms. Parameter: rho_inv = 1 / rho [-].
    """

    family = "frame_action"

    @property
    def names(self):
        return ("rho_inv",)

    @property
    def location(self):
        return {}

    def spec(self, ref):
        # rho from 0.1 (columns 10x the beams) to the shear frame
        return {"initial": [0.0], "lower": [0.0], "upper": [10.0], "scale": [0.1], "null": [0.0]}

    def apply(self, sys, th, ref):
        dK = frame_action_dK(_story_stiffness(ref["K_parts"]), th[0])
        extra = sys["K"].shape[0] - dK.shape[0]   # DOFs other families appended: untouched
        return {**sys, "K": sys["K"] + (ca.diagcat(dK, ca.SX.zeros(extra, extra)) if extra else dK)}


def _story_stiffness(K_parts):
    """Story stiffnesses k_i of the shear chain sum(K_parts): k_{i+1} = -K[i, i+1], k_1 =
    K[0, 0] - k_2."""
    K = K_parts[0]
    for P in K_parts[1:]:
        K = K + P
    K = ca.SX(K)
    n = K.shape[0]
    k = [-K[i, i + 1] for i in range(n - 1)]
    return [K[0, 0] - (k[0] if k else 0)] + k


def condensed_dK(k, eta):
    """The frame's stiffness minus the shear chain of k, for columns whose rigid-beam story
    stiffnesses are k (list, SX or float) and beams of ratio rho = 1/eta:

        dK = -eta K_ut (eta K_tt + 12 D)^-1 K_tu

    with the rotations (times h) condensed out: K_ut, K_tt the column blocks (6 s_i; 4 s_i
    and 2 s_i, s_i = k_i / 12) and D = diag(s_j) for floor j's beams over the storey below
    (a symmetric bay's two joints turn alike, so its beams add 12 rho s_j)."""
    n = len(k)
    s = [ki / 12.0 for ki in k]
    Kut = ca.SX.zeros(n, n)
    Ktt = ca.SX.zeros(n, n)
    D = ca.SX.zeros(n, n)
    for i in range(n):                 # storey i + 1: floor i - 1 (ground at i = 0) to floor i
        a, b = i - 1, i                # its bottom and top floors (0-based; -1 the ground)
        Kut[b, b] += -6 * s[i]
        Ktt[b, b] += 4 * s[i]
        if a >= 0:
            Kut[a, a] += 6 * s[i]
            Kut[a, b] += 6 * s[i]
            Kut[b, a] += -6 * s[i]
            Ktt[a, a] += 4 * s[i]
            Ktt[a, b] += 2 * s[i]
            Ktt[b, a] += 2 * s[i]
        D[b, b] = s[i]
    return -eta * ca.mtimes(Kut, ca.solve(eta * Ktt + 12 * D, Kut.T))


def frame_action_dK(k, eta):
    """dK of :class:`FrameAction`: the frame whose D-value story stiffnesses are k, minus the
    shear chain of k. The columns' rigid-beam stiffnesses are k_i / a_i; 1/a - 1 is eta above
    the first storey and 1.5 eta / (0.5 eta + 2) in it."""
    n = len(k)
    extra = [k[0] * 1.5 * eta / (0.5 * eta + 2)] + [ki * eta for ki in k[1:]]
    chain = ca.SX.zeros(n, n)
    for i, e in enumerate(extra):
        chain = _spring(chain, i, i - 1 if i else None, e)
    return chain + condensed_dK([ki + e for ki, e in zip(k, extra)], eta)


@dataclass(frozen=True)
class SensorGain:
    """A calibration error on one channel: H -> (1 + g) H."""

    channel: str
    family = "sensor_gain"

    @property
    def names(self):
        return (f"gain_{self.channel}",)

    @property
    def location(self):
        return {"channel": self.channel}

    def spec(self, ref):
        return {"initial": [0.0], "lower": [-0.5], "upper": [1.0], "scale": [0.05], "null": [0.0]}

    def output(self, hr, hi, w, th):
        return (1 + th[0]) * hr, (1 + th[0]) * hi


@dataclass(frozen=True)
class SensorDelay:
    """A time delay tau [ms] on one channel: H -> H exp(-j w tau)."""

    channel: str
    family = "sensor_delay"

    @property
    def names(self):
        return (f"delay_ms_{self.channel}",)

    @property
    def location(self):
        return {"channel": self.channel}

    def spec(self, ref):
        return {"initial": [0.0], "lower": [-50.0], "upper": [50.0], "scale": [1.0], "null": [0.0]}

    def output(self, hr, hi, w, th):
        ph = -w * th[0] * 1e-3
        c, s = ca.cos(ph), ca.sin(ph)
        return hr * c - hi * s, hr * s + hi * c


@dataclass(frozen=True)
class ExtraMode:
    """Model discrepancy: a resonance the model class cannot have (an out-of-plane,
    torsional or local mode of a planar model), as one modal term on every channel.

    Channel c's FRF gains a_c L_c (j w / w_x)^p w_x^2 / (w_x^2 - w^2 + 2 j zeta_x w_x w),
    the mode's term in the channel's own output (p = 0 receptance, 1 mobility,
    2 accelerance; nlp.frf.forms.POWER), with L_c = |H_x| of the channel near f0, so a_c
    is dimensionless: the term peaks at a_c L_c / (2 zeta_x). A real residue is a
    lightly damped, nearly classical mode (Ewins, Modal Testing, 2000, ch. 2.6).
    Parameters: f_x [Hz], zeta_x, a_x per channel.

    channels, powers, levels : names, output powers and L_c of the channels, in order.
    """

    f0: float
    channels: tuple
    powers: tuple = field(default=(), compare=False)
    levels: tuple = field(default=(), compare=False)
    family = "model_discrepancy"

    @property
    def tag(self):
        # to the mHz: at 0.1 Hz two terms 0.02 Hz apart (one mode read on two channels, or
        # two close modes) shared their parameter names
        return f"x{round(1000 * self.f0)}"

    @property
    def names(self):
        return (f"f_{self.tag}", f"zeta_{self.tag}") + tuple(
            f"a_{self.tag}_{c}" for c in self.channels)

    @property
    def location(self):
        return {"frequency_hz": round(float(self.f0), 2)}

    def spec(self, ref, a0=0.0):
        n = len(self.channels)
        return {"initial": [self.f0, 0.01] + [a0] * n,
                "lower": [0.97 * self.f0, 5e-4] + [-1.0] * n,
                "upper": [1.03 * self.f0, 0.1] + [1.0] * n,
                "scale": [0.01 * self.f0, 0.005] + [0.01] * n, "null": [self.f0, 0.01] + [0.0] * n}

    def output_on(self, channel, hr, hi, w, th):
        """Channel's FRF (real, imaginary parts) with the mode's term added."""
        c = self.channels.index(channel)
        wx = 2 * math.pi * th[0]
        dr, di = wx ** 2 - w ** 2, 2 * th[1] * wx * w
        g = th[2 + c] * self.levels[c] * wx ** 2 / (dr ** 2 + di ** 2)
        tr, ti = g * dr, -g * di                    # g w_x^2 / D, D = dr + j di
        p = self.powers[c]
        if p == 1:                                  # times j w / w_x
            tr, ti = -ti * w / wx, tr * w / wx
        elif p == 2:                                # times -(w / w_x)^2
            tr, ti = -tr * (w / wx) ** 2, -ti * (w / wx) ** 2
        return hr + tr, hi + ti


FAMILIES = ("added_mass", "base_flexibility", "secondary_oscillator", "local_damper",
            "hysteretic_damping", "nonadjacent_coupling", "frame_action", "sensor_gain",
            "sensor_delay", "nonlinearity")


def extend_parameters(params, enrichments, ref, values=None):
    """A ParameterSet with the enrichments' parameters appended (group "physics").

    values : optional start values, one list per enrichment (default: the
    family's initial guess).
    """
    extra = []
    for k, e in enumerate(enrichments):
        sp = e.spec(ref)
        init = sp["initial"] if values is None else values[k]
        for name, v, lo, hi, sc in zip(e.names, init, sp["lower"], sp["upper"], sp["scale"]):
            extra.append(Parameter(name, "physics", float(v), float(lo), float(hi), scale=float(sc)))
    base = tuple(p for p in params.params if p.group != "physics")
    return replace(params, params=base + tuple(extra))


def references(model, damping_C0):
    """Reference magnitudes the families scale by: mean floor mass, story stiffness, damping."""
    return {"m_ref": float(np.mean(np.diag(model.M0))),
            "k_ref": float(np.mean(model.alpha_nominal)) if np.all(model.alpha_nominal != 1.0)
            else float(np.mean(np.diag(model.K0))),
            "c_ref": float(np.mean(np.diag(damping_C0)))}
