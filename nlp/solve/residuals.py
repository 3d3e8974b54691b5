"""The residuals r_kc(z) of Eqn 25a at one frequency, as CasADi SX functions (dense backend).

Per channel c at the frequency w, with the measured H_x = yr + j yi, scale s and weight wt:

    log_magnitude   r = wt (ln|H_a| - ln|H_x|)
    magnitude       r = wt (|H_a| - |H_x|) / s,      s = rms_c |H_x|
    relative_magnitude  the same with s = |H_x|: ln|H_a / H_x| to first order, without
                    its singularity where the model's |H_a| passes through zero
    complex         r = wt [Re, Im] (H_a - H_x) / s,  s = |H_x|

H_a is the model's FRF of Eqns 2-5 (:func:`nlp.frf.backends.dense.frf_symbolic`) for
M, K, C at theta = T z + c, with the added physics of the enrichments. The measured data
of every frequency travel packed in one numeric vector p (:func:`pack_data`), so that
nothing symbolic is rebuilt when the data change.
"""

from dataclasses import dataclass

import casadi as ca
import numpy as np

from nlp.frf.backends.dense import frf_symbolic
from nlp.frf.reference import BASE_DOF
from nlp.frf.backends.terms import proportional

__all__ = ["RESIDUALS", "FrequencyFunctions", "pack_data", "data_arrays", "data_symbols", "system_sx",
           "load_vector", "frequency_functions"]

# The residual forms of the objective (Eqn 25): ln|H| (the default, far better conditioned
# than the paper's squared magnitudes), |H|, or the complex FRF
RESIDUALS = ("log_magnitude", "magnitude", "relative_magnitude", "complex")


@dataclass(frozen=True)
class FrequencyFunctions:
    """The SX functions of one frequency (inputs z, w, yr, yi, s, wt) and of z alone."""

    matrices: ca.Function      # z -> M, K, C of the model
    system: ca.Function        # z -> M, K, C with the DOFs added physics appends
    channel_frf: ca.Function   # (z, w) -> Re, Im of every channel's FRF
    res: ca.Function           # -> r
    resjac: ca.Function        # -> r, J^T
    fg: ca.Function            # -> 1/2 |r|^2, J^T r
    gn: ca.Function            # -> triu(J^T J)
    n_res: int                 # residuals per frequency


def pack_data(target, residual):
    """(p, n_used): the data vector [omega, Re H, Im H, s, wt] (matrices column-major)
    and the number of residuals that carry weight."""
    H = np.asarray(target.H, dtype=complex)
    wt = np.asarray(target.weight, dtype=float)
    used = wt > 0
    Hs = np.where(used, H, 1.0)  # unused points: harmless finite data
    mag = np.abs(Hs)
    if residual == "magnitude":
        rms = np.array([np.sqrt(np.mean(mag[c, used[c]] ** 2)) if used[c].any() else 1.0
                        for c in range(H.shape[0])])
        s = np.repeat(rms[:, None], H.shape[1], axis=1)
    elif residual in ("complex", "relative_magnitude"):
        s = mag
    else:
        s = np.ones_like(mag)
    n_used = int(used.sum()) * (2 if residual == "complex" else 1)
    p = np.concatenate([np.asarray(target.omega, float).ravel(),
                        *(a.ravel(order="F") for a in (Hs.real, Hs.imag, s, wt))])
    return p, n_used


def data_arrays(p, N, n_ch):
    """(w, yr, yi, s, wt) arrays from the packed data vector (:func:`pack_data`)."""
    p = np.asarray(p, float).ravel()
    blocks = [p[N + i * n_ch * N: N + (i + 1) * n_ch * N].reshape(n_ch, N, order="F")
              for i in range(4)]
    return (p[:N], *blocks)


def data_symbols(p, N, n_ch):
    """(w (1, N), yr, yi, s, wt (n_ch, N)) as MX from the symbolic data vector p."""
    W = ca.reshape(p[:N], 1, N)
    blocks = [ca.reshape(p[N + i * n_ch * N: N + (i + 1) * n_ch * N], n_ch, N) for i in range(4)]
    return W, *blocks


def system_sx(model, damping, params, enrichments, refs, z):
    """Base M, K, C (Eqns 23-24, the damping model) and the full system with added physics.

    Returns (M, K, C, system, sensor, base_dof): ``system`` the dict M, K, C, Kh (hysteretic
    stiffness) of the enriched model; ``sensor`` channel name -> [(family, its theta)] of
    the sensor-side families; ``base_dof`` the row of a flexible base, or None.
    """
    theta = ca.mtimes(ca.DM(params.T), z) + ca.DM(params.c)
    sa, sb, sd = params.slices()
    M, K = model.matrices(theta[sa], theta[sb])
    M, K = ca.SX(M), ca.SX(K)
    C = ca.SX(damping.matrix(theta[sd], M, K))
    n = model.n
    system = {"M": M, "K": K, "C": C, "Kh": ca.SX.zeros(n, n)}
    if proportional(damping):   # a flexible base extends the law over its DOF
        system["rayleigh"] = damping.structure(theta[sd])[:2]
    ref = {**refs, "K_parts": [(1 + theta[sa][r]) * ca.DM(Kr)
                               for r, Kr in enumerate(model.K_infl)]}
    th = theta[params.physics_slice()]
    k = 0
    sensor, base_dof = {}, None
    for e in enrichments:
        th_e = th[k:k + len(e.names)]
        k += len(e.names)
        if e.family == "base_flexibility":  # the DOF it appends is the base
            base_dof = system["M"].shape[0]
        if hasattr(e, "apply"):
            system = e.apply(system, th_e, ref)
        elif hasattr(e, "output_on"):   # one term on several channels (model discrepancy)
            for ch in e.channels:
                sensor.setdefault(ch, []).append((_OnChannel(e, ch), th_e))
        else:
            sensor.setdefault(e.channel, []).append((e, th_e))
    return M, K, C, system, sensor, base_dof


class _OnChannel:
    """A several-channel family's output on one channel (the sensor families' interface)."""

    def __init__(self, e, channel):
        self.e, self.channel = e, channel

    def output(self, hr, hi, w, th):
        return self.e.output_on(self.channel, hr, hi, w, th)


def load_vector(target, Ma, n, force_dof=None):
    """Right-hand side b: -M r for ground motion (Eqn 16, r the influence vector on the
    model's n DOFs, 1 on appended ones: an appendage or a base moves in the excitation's
    direction, carried rigidly by the ground), a unit force at ``force_dof`` (default the
    target's) otherwise."""
    if target.excitation == "ground":
        r = ca.DM.ones(Ma.shape[0]) if target.ground_r is None else \
            ca.vertcat(ca.DM(target.ground_r), ca.DM.ones(Ma.shape[0] - n))
        return -ca.mtimes(Ma, r)  # Eqn 16, with r for models with several DOFs per node
    b = ca.DM.zeros(Ma.shape[0])
    b[target.force_dof if force_dof is None else force_dof] = 1
    return b


def _channel_outputs(channels, Ma, Ca, Ka, kh, load, sensor, base_dof, wv):
    """Every channel's FRF (real, imaginary parts) at the frequency wv; load(force_dof) is
    the right-hand side of a channel's test."""
    cache, o_r, o_i = {}, [], []
    for ch in channels:
        key = (ch.output, ch.force_dof)
        if key not in cache:
            cache[key] = frf_symbolic(Ma, Ca, Ka, wv, load(ch.force_dof), ch.output, kh)
        if ch.dof == BASE_DOF and base_dof is None:  # rigid base: the ground's
            hr = ca.SX(1.0 if ch.output == "absolute_accelerance" else 0.0)
            hi = ca.SX(0.0)
        else:
            row = base_dof if ch.dof == BASE_DOF else ch.dof
            hr, hi = cache[key][0][row], cache[key][1][row]
        terms = sensor.get(ch.sensor_name, [])
        if ch.sensor_name != ch.name:   # a joint test's channel: its own terms too
            terms = terms + sensor.get(ch.name, [])
        for e, th_e in terms:
            hr, hi = e.output(hr, hi, wv, th_e)
        o_r.append(hr)
        o_i.append(hi)
    return o_r, o_i


def _estimated_outputs(outputs, kernel, w, n_ch):
    """The FRF as the data's estimator sees it: the model's own, or with a kernel (h, a)
    its windowed average a H(w - h) + (1 - 2a) H(w) + a H(w + h)."""
    if kernel is None:
        return outputs(w)
    # the windowed average's expected value: the FRF smoothed by the window's kernel
    h, a = kernel
    taps = [(a, outputs(w - h)), (1 - 2 * a, outputs(w)), (a, outputs(w + h))]
    out_r = [sum(g * o[0][c] for g, o in taps) for c in range(n_ch)]
    out_i = [sum(g * o[1][c] for g, o in taps) for c in range(n_ch)]
    return out_r, out_i


def _residual_terms(residual, n_ch, out_r, out_i, yr, yi, s, wt):
    """The residuals of the residual form (module docstring) for every channel."""
    res = []
    for c in range(n_ch):
        hr, hi = out_r[c], out_i[c]
        if residual == "log_magnitude":
            res.append(wt[c] * 0.5 * (ca.log(hr**2 + hi**2) - ca.log(yr[c]**2 + yi[c]**2)))
        elif residual in ("magnitude", "relative_magnitude"):
            res.append(wt[c] * (ca.sqrt(hr**2 + hi**2) - ca.sqrt(yr[c]**2 + yi[c]**2)) / s[c])
        else:
            res += [wt[c] * (hr - yr[c]) / s[c], wt[c] * (hi - yi[c]) / s[c]]
    return ca.vertcat(*res)


def frequency_functions(model, damping, params, target, residual, enrichments=(), refs=None):
    """The per-frequency SX functions of the dense backend (:class:`FrequencyFunctions`)."""
    nz = params.n_z
    n_ch = len(target.channels)
    z = ca.SX.sym("z", nz)
    w = ca.SX.sym("w")
    yr, yi, s, wt = (ca.SX.sym(nm, n_ch) for nm in ("yr", "yi", "s", "wt"))
    M, K, C, system, sensor, base_dof = system_sx(model, damping, params, enrichments,
                                                  dict(refs or {}), z)
    matrices_fn = ca.Function("matrices", [z], [M, K, C], ["z"], ["M", "K", "C"])
    Ma, Ka, Ca, Kh = (system[k] for k in ("M", "K", "C", "Kh"))
    system_fn = ca.Function("system", [z], [Ma, Ka, Ca], ["z"], ["M", "K", "C"])
    loads = {}

    def load(force_dof):
        if force_dof not in loads:
            loads[force_dof] = load_vector(target, Ma, model.n, force_dof)
        return loads[force_dof]

    kh = Kh if enrichments else None

    def outputs(wv):
        return _channel_outputs(target.channels, Ma, Ca, Ka, kh, load, sensor, base_dof, wv)

    out_r, out_i = _estimated_outputs(outputs, target.kernel, w, n_ch)
    r = _residual_terms(residual, n_ch, out_r, out_i, yr, yi, s, wt)
    frf_fn = ca.Function("channel_frf", [z, w], [ca.vertcat(*out_r), ca.vertcat(*out_i)],
                         ["z", "w"], ["Hr", "Hi"])
    args = [z, w, yr, yi, s, wt]
    names = ["z", "w", "yr", "yi", "s", "wt"]
    res_fn = ca.Function("frf_res", args, [r], names, ["r"])
    JT = ca.jacobian(r, z).T
    resjac_fn = ca.Function("frf_resjac", args, [r, JT], names, ["r", "JT"])
    # per-frequency terms of f, J^T r and triu(J^T J), summed over frequencies by the map
    fg_fn = ca.Function("frf_fg", args, [0.5 * ca.sumsqr(r), ca.mtimes(JT, r)], names,
                        ["f", "g"])
    gn_fn = ca.Function("frf_gn", args, [ca.triu(ca.mtimes(JT, JT.T))], names, ["H"])
    return FrequencyFunctions(matrices_fn, system_fn, frf_fn, res_fn, resjac_fn, fg_fn, gn_fn,
                              r.shape[0])
