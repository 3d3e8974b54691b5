"""Output-side families (sensor gain and delay, every channel's
calibration, an extra modal term) on the numeric backends.

Each channel's FRF passes through its families in the order given (:mod:`nlp.diagnosis.families`:
a gain or a delay multiplies it, a modal term adds to it), so the channel's output is

    H_c = F_c(w, theta) H0_c + A_c(w, theta),   H0_c the model's own (Eqns 2-5)
    dH_c/dz = F_c dH0_c/dz + (dH_c/dtheta) T

with F_c = dH_c/dH0_c. The families' own CasADi expressions give H_c, F_c and dH_c/dtheta,
one small function per channel evaluated over the frequencies, exactly as the dense backend
(:mod:`nlp.solve.residuals`) composes them.
"""

import casadi as ca
import numpy as np

__all__ = ["OUTPUT", "Outputs"]

OUTPUT = ("sensor_gain", "sensor_delay", "model_discrepancy", "calibration")


def _on_channel(e, channel):
    """A several-channel family's output on one channel (the sensor families' signature)."""
    return lambda hr, hi, w, th: e.output_on(channel, hr, hi, w, th)


class Outputs:
    """The output families of ``enrichments`` (parameters the "physics" entries of ``params``,
    in order) on ``channels``; ``any`` says whether one acts at all."""

    def __init__(self, enrichments, params, channels):
        self.n_theta = n_theta = params.T.shape[0]
        theta = ca.SX.sym("theta", n_theta)
        th = theta[params.physics_slice()]
        sensor, k = {}, 0
        for e in enrichments:
            th_e = th[k:k + len(e.names)]
            k += len(e.names)
            if hasattr(e, "output_on"):
                for ch in e.channels:
                    sensor.setdefault(ch, []).append((_on_channel(e, ch), th_e))
            elif hasattr(e, "output"):
                sensor.setdefault(e.channel, []).append((e.output, th_e))
        self.fns = []
        for ch in channels:
            ops = sensor.get(ch.sensor_name, [])
            if ch.sensor_name != ch.name:   # a joint test's channel: its own terms too
                ops = ops + sensor.get(ch.name, [])
            self.fns.append(self._function(theta, ops) if ops else None)
        self.any = any(f is not None for f in self.fns)
        self._maps = {}

    @staticmethod
    def _function(theta, ops):
        w, h0r, h0i = ca.SX.sym("w"), ca.SX.sym("h0r"), ca.SX.sym("h0i")
        hr, hi = h0r, h0i
        for op, th_e in ops:
            hr, hi = op(hr, hi, w, th_e)
        out = ca.vertcat(hr, hi)
        return ca.Function("channel_output", [theta, w, h0r, h0i],
                           [out, ca.jacobian(out, theta), ca.jacobian(out, h0r)])

    def __call__(self, theta, w, H0):
        """(H, F, dth) at frequencies w: H, F (n_ch, N) complex, dth {channel: dH/dtheta
        (n_theta, N) complex} for the channels with an output family."""
        N = w.size
        H, F, dth = H0.copy(), np.ones(H0.shape, complex), {}
        for c, fn in enumerate(self.fns):
            if fn is None:
                continue
            key = (c, N)
            if key not in self._maps:
                self._maps[key] = fn.map(N)
            out, J, Fo = (np.asarray(x) for x in self._maps[key](
                theta, w[None, :], H0[c].real[None, :], H0[c].imag[None, :]))
            H[c] = out[0] + 1j * out[1]
            F[c] = Fo[0] + 1j * Fo[1]
            J = J.reshape(2, N, self.n_theta)
            dth[c] = (J[0] + 1j * J[1]).T
        return H, F, dth
