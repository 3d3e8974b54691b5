"""Plant known effects in measured FRFs by exact frequency-based substructuring.

Measured FRFs keep their noise and whatever physics the model lacks; these
functions change only what a known attachment or sensor error changes.
Convention: exp(+j w t), so a viscous dashpot c has dynamic stiffness j w c and
a delayed signal is multiplied by exp(-j w tau). Pure numpy; nothing here uses
the package's FRF code, so the planted data are an independent check of it.

Units: w [rad/s], receptance R [m/N], accelerance A [(m/s^2)/N], masses [kg],
stiffness [N/m], dashpot [N s/m], delay [s].
"""

import numpy as np

__all__ = ["receptance", "accelerance", "added_mass_z", "appendage_z", "attach",
           "attach_transfer", "attach_accelerance", "gain", "delay"]


def receptance(A, w):
    """R = -A / w^2 [m/N] from accelerance A [(m/s^2)/N] (A = (j w)^2 R)."""
    return -np.asarray(A) / np.asarray(w) ** 2


def accelerance(R, w):
    """A = -w^2 R [(m/s^2)/N] from receptance R [m/N]."""
    return -np.asarray(w) ** 2 * np.asarray(R)


def added_mass_z(w, dm):
    """Dynamic stiffness of a rigid mass dm [kg]: z(w) = -w^2 dm [N/m]."""
    return -np.asarray(w, dtype=float) ** 2 * dm


def appendage_z(w, m_a, k_a, c_a):
    """Dynamic stiffness [N/m] of a mass m_a on a spring k_a and dashpot c_a, seen at
    its base: z(w) = -w^2 m_a (k_a + j w c_a) / (k_a + j w c_a - w^2 m_a).

    From the appendage's equation -w^2 m_a x_a = -(k_a + j w c_a)(x_a - x_p), its spring
    adds (k_a + j w c_a)(x_p - x_a) = z x_p to the base's equation. Tends to -w^2 m_a
    (rigid) as k_a grows."""
    w = np.asarray(w, dtype=float)
    s = k_a + 1j * w * c_a
    return -w**2 * m_a * s / (s - w**2 * m_a)


def attach(R_col, p, z):
    """Receptance column at the driving point p after attaching z(w) there.

    R'_{:,p} = R_{:,p} / (1 + z R_{p,p}) (exact: the attachment's force -z x_p acts at
    p only, so x' = R_{:,p} (F - z x'_p)).

    R_col : (n_out, n_f) complex, the measured column R_{:,p} [m/N]
    p : row of R_col that is the driving point (0-based)
    z : (n_f,) dynamic stiffness [N/m]
    """
    R_col = np.asarray(R_col)
    return R_col / (1.0 + z * R_col[p])


def attach_transfer(R_rb, R_rp, R_pb, R_pp, z):
    """Receptances R'_{r,b} [m/N] from input b to outputs r after attaching z(w) at p.

    The attachment's force -z x'_p acts at p only, so x' = R_{:,b} F - R_{:,p} z x'_p and
    R' = R_rb - R_rp z R_pb / (1 + z R_pp). Arrays: R_rb, R_rp (n_r, n_w); R_pb, R_pp, z
    (n_w,). With b = p this is :func:`attach`.
    """
    z, R_pb, R_pp = np.asarray(z), np.asarray(R_pb), np.asarray(R_pp)
    return np.asarray(R_rb) - np.asarray(R_rp) * (z * R_pb / (1.0 + z * R_pp))[None]


def attach_accelerance(A_col, w, p, z):
    """:func:`attach` on accelerances [(m/s^2)/N]: through R = -A / w^2 and back."""
    return accelerance(attach(receptance(A_col, w), p, z), w)


def gain(H, g):
    """A channel gain: H' = g H (g dimensionless; 1 is no error)."""
    return g * np.asarray(H)


def delay(H, w, tau):
    """A channel delay tau [s]: H' = H exp(-j w tau)."""
    return np.asarray(H) * np.exp(-1j * np.asarray(w) * tau)
