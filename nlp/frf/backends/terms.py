"""Added physics (:mod:`nlp.diagnosis.families`) as sparse terms of the FRF system.

A structural family changes the dynamic stiffness by fixed sparse patterns P_t times
scalar coefficients, on the model's DOFs plus the extra DOFs it appends (after them):

    Z = Z_model + sum_t c_t(theta) f_t(w) P_t,   f = 1 (K), -w^2 (M), j w (C), j (Kh)
    b = b_model + sum_{t in M} c_t(theta) b_t,   b_t = -P_t r (ground input, r = 0 on extra DOFs)

so dZ/dz is again a sum of fixed sparse matrices, and the adjoint sensitivities of
:mod:`nlp.frf.backends.sparse` carry the families unchanged: dH_c/dz = sum_t dc_t/dz
lambda_c^T (b_t - f_t P_t q). The c_t and their Jacobian come from one small CasADi
function of theta. Output-side families (sensor gain, delay, an extra mode) act on the
channels' outputs (:mod:`nlp.frf.backends.outputs`).

Locations come from ``ref["floors"]``: one weight vector a_f per floor (a DOF group),
a_f^T u the floor's mean displacement in the excitation direction (e_f on a shear frame).
"""

from dataclasses import dataclass
import math

import casadi as ca
import numpy as np
import scipy.sparse as sp

from nlp.frf.backends.outputs import OUTPUT, Outputs
from nlp.model.damping import RayleighDamping

__all__ = ["KINDS", "STRUCTURAL", "Terms", "supported", "family_terms", "floor_vector",
           "mass_vector",
           "terms_state", "with_terms", "backend_terms"]

KINDS = ("K", "M", "C", "H")
MU_MIN = 1e-12   # an appendage's smallest mass ratio on the sparse backend (see _appendage)
STRUCTURAL = ("added_mass", "secondary_oscillator", "local_damper", "hysteretic_damping",
              "nonadjacent_coupling", "base_flexibility")


def proportional(damping):
    """Whether C = a0 M + a1 K (Rayleigh): a flexible base then extends the law over its DOF,
    coupling to C through a1 K alone (:func:`_base`); a rank-m or dashpot damping term has no
    such form here."""
    return isinstance(damping, RayleighDamping)


def supported(enrichments, damping=None, channels=()):
    """Whether every family is carried by sparse terms (the others need the dense backend).
    A flexible base is, with proportional damping and no sensor on the base (a base sensor
    reads the appended DOF, which only the dense backend's outputs know)."""
    fams = [getattr(e, "family", None) for e in enrichments]
    if "base_flexibility" in fams and (not proportional(damping)
                                       or any(ch.dof < 0 for ch in channels)):
        return False
    return all(f in STRUCTURAL + OUTPUT for f in fams)


def floor_vector(ref, floor, n):
    """a_f (n,): the weights whose product with u is floor ``floor``'s displacement (1-based;
    0 is the ground, the zero vector)."""
    a = np.zeros(n)
    if floor == 0:
        return a
    floors = ref.get("floors")
    if floors is None:
        a[floor - 1] = 1.0
        return a
    a[:len(floors[floor - 1])] = floors[floor - 1]
    return a


def mass_vector(ref, floor, n):
    """b_f (n,): the weights of an added mass dm at floor ``floor`` on the diagonal of M,
    dm b_f: its nodes' translational DOFs on an FE model (``ref["masses"]``,
    nlp.diagnosis.locations.mass_vectors), else the floor's own weights a_f."""
    masses = ref.get("masses")
    if masses is None or floor == 0:
        return floor_vector(ref, floor, n)
    b = np.zeros(n)
    b[:len(masses[floor - 1])] = masses[floor - 1]
    return b


@dataclass(frozen=True)
class Terms:
    """The sparse terms of a set of families (module docstring).

    n_extra : extra DOFs appended after the model's n.
    kinds : (n_t,) index into KINDS of each term; P : its pattern (n + n_extra square, csc).
    b : (n_t, n + n_extra) csr, the load of each term per unit coefficient.
    coef : casadi Function theta -> (c (n_t,), dc/dtheta (n_t, n_theta)).
    outputs : the output-side families (:class:`nlp.frf.backends.outputs.Outputs`) or None.
    """

    n_extra: int
    kinds: np.ndarray
    P: tuple
    b: sp.csr_matrix
    coef: ca.Function
    outputs: Outputs

    def project(self, Psi):
        """The same terms on q = W eta, W = diag(Psi, I): the model's DOFs on the reduced
        basis Psi (n, m), the appended DOFs kept (the reduced backend)."""
        W = sp.block_diag([sp.csc_matrix(Psi), sp.identity(self.n_extra)], format="csc")
        P = tuple(sp.csc_matrix(W.T @ (A @ W)) for A in self.P)
        return Terms(n_extra=self.n_extra, kinds=self.kinds, P=P, b=sp.csr_matrix(self.b @ W),
                     coef=self.coef, outputs=self.outputs)

    def factors(self, w):
        """f_t(w) (n_t, N): the frequency factor of each term."""
        w = np.asarray(w, float)
        table = np.stack([np.ones_like(w), -(w ** 2), 1j * w, 1j * np.ones_like(w)])
        return table[self.kinds]


class _Builder:
    """Collects (kind, triplets, coefficient) of the terms as families are translated."""

    def __init__(self, n, r):
        self.n, self.extra, self.items = n, 0, []
        self.r = list(r)  # rigid-body influence of the ground motion on every DOF (Eqn 16)

    def add(self, kind, v, coef, w=None):
        """A term coef * v w^T (w = v: a rank-one spring, dashpot or mass)."""
        w = v if w is None else w
        self.items.append((KINDS.index(kind), np.outer(v, w), coef))

    def add_matrix(self, kind, A, coef):
        self.items.append((KINDS.index(kind), A, coef))

    def new_dof(self, r):
        """A DOF appended after the others; r its motion under a unit rigid ground motion."""
        self.extra += 1
        self.r.append(float(r))
        return self.n + self.extra - 1


def _added_mass(bld, e, th, ref, ctx):
    b = mass_vector(ref, e.floor, bld.n)
    bld.add_matrix("M", sp.diags(b), th[0])  # dm spread over the floor's nodes, total dm


def _appendage(bld, e, th, ref, ctx):
    """The oscillator's DOF x joined to the floor's mean displacement a_f^T u; a rigid ground
    motion carries it with the floor (r_x = a_f^T r). Its mass ratio is floored at MU_MIN:
    every entry of its DOF's row scales with its mass, so a massless appendage (a family at
    its null value) would leave Z singular, while one of MU_MIN has no measurable effect."""
    ms = (th[0] + MU_MIN) * ref["m_ref"]
    ws = 2 * math.pi * th[1]
    a = floor_vector(ref, e.floor, bld.n)
    x = bld.new_dof(a @ np.asarray(bld.r[:bld.n]))
    ex = np.zeros(x + 1)
    ex[x] = 1.0
    v = -ex
    v[:bld.n] += a
    bld.add("M", ex, ms)
    bld.add("K", v, ms * ws ** 2)
    bld.add("C", v, 2 * th[2] * ms * ws)


def _bordered(A, r, x):
    """The coupling of a base DOF x to the model's DOFs through A: [[0, -A r], [-r^T A, r^T A r]]
    on x + 1 DOFs, A acting on the motion relative to the base u - r u_b."""
    g = np.asarray(A @ r, float).ravel()
    i = np.flatnonzero(g)
    rows = np.concatenate([i, np.full(i.size, x), [x]])
    cols = np.concatenate([np.full(i.size, x), i, [x]])
    vals = np.concatenate([-g[i], -g[i], [r @ g]])
    return sp.csr_matrix((vals, (rows, cols)), shape=(x + 1, x + 1))


def _base(bld, e, th, ref, ctx):
    """A base DOF u_b under every support, along the base's direction r (``ref["r"]``: the
    rigid translation, 1 on the DOFs along it; the ground's influence vector, or 1 on a shear
    frame's floors). The model's forces act on u - r u_b, so its K gains the border of
    :func:`_bordered` (K = K0 + sum alpha_i K_i, Eqn 23), and the base has mass m_b and a
    spring k_b to the ground; a rigid ground motion carries it (r_b = 1). The Rayleigh law
    C = cM M + cK K covers the model with its base: cK K gains the same border, cM M keeps
    acting on the motion relative to the ground, and the base has cM m_b + cK k_b plus the
    dashpot c_b beyond the law. The same physics as the dense
    :meth:`nlp.diagnosis.families.BaseFlexibility.apply`."""
    model, n = ctx["model"], bld.n
    if ctx.get("damping") is None or not proportional(ctx["damping"]):
        raise ValueError("a flexible base on the sparse backend needs Rayleigh damping")
    r = np.asarray(ref["r"] if ref.get("r") is not None else bld.r[:n], float)
    x = bld.new_dof(1.0)
    ex = np.zeros(x + 1)
    ex[x] = 1.0
    alpha = ctx["alpha"]
    cM, cK, _, _ = ctx["damping"].structure(ctx["theta_d"])
    for kind, A, c in list(bld.items):   # a hysteretic loss so far acts on u - r u_b too
        if KINDS[kind] == "H":
            bld.add_matrix("H", _bordered(sp.csr_matrix(A)[:n, :n], r, x), c)
    kb = 10 ** th[1]
    bld.add("M", ex, th[0])
    bld.add("K", ex, kb)
    bld.add("C", ex, cM * th[0] + cK * kb + th[2])
    for kind, scale in (("K", 1.0), ("C", cK)):
        bld.add_matrix(kind, _bordered(model.K0, r, x), scale)
        for i, Ai in enumerate(model.K_infl):
            bld.add_matrix(kind, _bordered(Ai, r, x), scale * alpha[i])


def _local_damper(bld, e, th, ref, ctx):
    v = floor_vector(ref, e.i, bld.n) - floor_vector(ref, e.j, bld.n)
    bld.add("C", v, th[0])


def _coupling(bld, e, th, ref, ctx):
    v = floor_vector(ref, e.i, bld.n) - floor_vector(ref, e.j, bld.n)
    bld.add("K", v, th[0])


def _hysteretic(bld, e, th, ref, ctx):
    """Kh = eta K_s (one stiffness group s) or eta K (the model's block of the stiffness so
    far: Eqn 23 and the K terms of the families before it)."""
    alpha, model = ctx["alpha"], ctx["model"]
    if e.story is not None:
        r = e.story - 1
        bld.add_matrix("H", model.K_infl[r], th[0] * (1 + alpha[r]))
        return
    bld.add_matrix("H", model.K0, th[0])
    for r, Kr in enumerate(model.K_infl):
        bld.add_matrix("H", Kr, th[0] * alpha[r])
    for kind, A, c in list(bld.items):
        if KINDS[kind] == "K":
            bld.add_matrix("H", sp.csr_matrix(A)[:bld.n, :bld.n], th[0] * c)


_TRANSLATE = {"added_mass": _added_mass, "secondary_oscillator": _appendage,
              "local_damper": _local_damper, "nonadjacent_coupling": _coupling,
              "hysteretic_damping": _hysteretic, "base_flexibility": _base}


def _pad(A, size):
    A = sp.coo_matrix(A)
    return sp.csc_matrix((A.data, (A.row, A.col)), shape=(size, size))


def family_terms(model, params, enrichments, refs, target, damping=None):
    """The :class:`Terms` of ``enrichments`` (their parameters the "physics" entries of
    ``params``, in order) on ``model`` for ``target``'s excitation and channels; ``damping``
    the model's (a flexible base couples to it)."""
    if not supported(enrichments, damping, target.channels):
        bad = sorted({e.family for e in enrichments} - set(STRUCTURAL + OUTPUT)) or \
            ["base_flexibility (needs Rayleigh damping and no base sensor)"]
        raise ValueError(f"families {bad} are not carried by the sparse FRF backends")
    n = model.n
    theta = ca.SX.sym("theta", params.T.shape[0])
    sa, sb, sd = params.slices()
    th = theta[params.physics_slice()]
    ctx = {"alpha": theta[sa], "beta": theta[sb], "theta_d": theta[sd], "damping": damping,
           "model": model}
    r = getattr(target, "ground_r", None)
    bld = _Builder(n, np.ones(n) if r is None else np.asarray(r, float))
    k = 0
    for e in enrichments:
        th_e = th[k:k + len(e.names)]
        if e.family in _TRANSLATE:
            # a family with parameters held (nlp.diagnosis.nuisance.Held): its own vector
            inner, th_i = (e.inner, e.full(th_e)) if hasattr(e, "full") else (e, th_e)
            _TRANSLATE[e.family](bld, inner, th_i, refs, ctx)
        k += len(e.names)
    size = n + bld.extra
    P = tuple(_pad(A, size) for _, A, _ in bld.items)
    kinds = np.array([kd for kd, _, _ in bld.items], int)
    c = ca.vertcat(*[ca.SX(cf) for _, _, cf in bld.items]) if bld.items else ca.SX(0, 1)
    coef = ca.Function("family_terms", [theta], [c, ca.jacobian(c, theta)])
    b = sp.csr_matrix((len(P), size))  # a force input: no term loads the structure
    if target.excitation == "ground" and P:
        r = np.asarray(bld.r)
        b = sp.csr_matrix(np.array([-(A @ r) if KINDS[kd] == "M" else np.zeros(size)
                                    for kd, A in zip(kinds, P)]))
    outputs = Outputs(enrichments, params, target.channels)
    return Terms(n_extra=bld.extra, kinds=kinds, P=P, b=b, coef=coef,
                 outputs=outputs if outputs.any else None)


def terms_state(st, terms, VT, T):
    """Add to the evaluation state ``st`` (theta, b) the terms at theta: their values per
    kind on the pattern tv (4, nnz; VT the patterns' values, one column per term), the
    Jacobian dcz = dc/dz (n_t, n_z) and the load."""
    c, dc = terms.coef(st.theta)
    c = np.asarray(c, float).ravel()
    st.dcz = np.asarray(dc, float).reshape(c.size, T.shape[0]) @ T
    st.tv = np.stack([VT @ np.where(terms.kinds == k, c, 0.0) for k in range(len(KINDS))])
    st.b = st.b + terms.b.T @ c


def with_terms(terms, theta, M, K, C):
    """Dense M, K, C of the whole system at theta: the model's (n, n) padded with the extra
    DOFs, plus the terms of each kind (the hysteretic ones are not among them)."""
    c = np.asarray(terms.coef(theta)[0], float).ravel()
    size = M.shape[0] + terms.n_extra
    out = [np.pad(np.asarray(A, float), (0, terms.n_extra)) for A in (M, K, C)]
    for kind, P, ct in zip(terms.kinds, terms.P, c):
        if KINDS[kind] != "H":
            out[("M", "K", "C").index(KINDS[kind])] += ct * P.toarray().reshape(size, size)
    return tuple(out)


def backend_terms(model, params, enrichments, refs, target, basis=None, damping=None):
    """(terms on the model's own DOFs, terms the backend runs: projected on ``basis`` when
    reduced); (None, None) without families."""
    if not enrichments:
        return None, None
    full = family_terms(model, params, enrichments, refs, target, damping)
    return full, (full if basis is None else full.project(basis))
