"""Time-domain simulation of the linear lumped model by exact discretisation.

Equations of motion (zero initial state):

* ground input: ``M q'' + C q' + K q = -M 1 a_g``, ``q`` relative to the ground;
* force input:  ``M q'' + C q' + K q = e_k F``.

The input is taken as piecewise linear between samples (first-order hold,
as ``scipy.signal.lsim`` does), and the state-space model is discretised
exactly for that input with the matrix exponential of an augmented matrix.
"""

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from nlp.errors import InputError

__all__ = ["Response", "state_space", "simulate"]

_SRC = "<arguments>"


@dataclass(frozen=True)
class Response:
    """Simulated response.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Time [s], starting at 0.
    q : ndarray, shape (n_dof, N)
        Displacement [m] (relative to the ground for ground input).
    v : ndarray, shape (n_dof, N)
        Velocity [m/s] (relative to the ground for ground input).
    a : ndarray, shape (n_dof, N)
        ABSOLUTE acceleration [m/s^2] (``q'' + a_g`` for ground input).
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray


def _check_matrices(M, C, K):
    """Return float copies of M, C, K after shape and finiteness checks."""
    mats = {}
    for name, m in (("M", M), ("C", C), ("K", K)):
        m = np.asarray(m, dtype=float)
        if m.ndim != 2 or m.shape[0] != m.shape[1]:
            raise InputError(_SRC, name, "a square matrix", got=f"shape {m.shape}")
        if not np.all(np.isfinite(m)):
            raise InputError(_SRC, name, "finite entries")
        mats[name] = m
    n = mats["M"].shape[0]
    for name in ("C", "K"):
        if mats[name].shape != (n, n):
            raise InputError(_SRC, name, f"shape ({n}, {n}) like M",
                             got=f"shape {mats[name].shape}")
    return mats["M"], mats["C"], mats["K"]


def state_space(M, C, K, input="ground", dof=None):
    """First-order form ``x' = A x + B u`` with ``x = [q; q']``.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Mass [kg], damping [N s/m] and stiffness [N/m] matrices.
    input : {"ground", "force"}
        Ground acceleration [m/s^2] or a force [N] at DOF ``dof``.
    dof : int, optional
        0-based DOF of the force (force input only).

    Returns
    -------
    A : ndarray, shape (2n, 2n)
    B : ndarray, shape (2n, 1)
    """
    M, C, K = _check_matrices(M, C, K)
    n = M.shape[0]
    try:
        minv_k = linalg.solve(M, K)
        minv_c = linalg.solve(M, C)
    except linalg.LinAlgError as exc:
        raise InputError(_SRC, "M", "a non-singular mass matrix") from exc
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-minv_k, -minv_c]])
    B = np.zeros((2 * n, 1))
    if input == "ground":
        if dof is not None:
            raise InputError(_SRC, "dof", "None for ground input (it loads every DOF)", got=dof)
        B[n:, 0] = -1.0  # M^-1 (-M 1) = -1
    elif input == "force":
        if dof is None or int(dof) != dof or not 0 <= dof < n:
            raise InputError(_SRC, "dof", f"a 0-based DOF index in [0, {n - 1}]", got=dof)
        B[n:, 0] = linalg.solve(M, np.eye(n)[:, int(dof)])
    else:
        raise InputError(_SRC, "input", '"ground" or "force"', got=input)
    return A, B


def _foh_matrices(A, B, dt):
    """Exact FOH discretisation: x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1].

    ``expm([[A, B, 0], [0, 0, I/dt], [0, 0, 0]] dt)`` holds ``Ad`` and the two
    input integrals; the layout is the one ``scipy.signal.lsim`` uses.
    """
    ns, ni = B.shape
    F = np.zeros((ns + 2 * ni, ns + 2 * ni))
    F[:ns, :ns] = A * dt
    F[:ns, ns:ns + ni] = B * dt
    F[ns:ns + ni, ns + ni:] = np.eye(ni)
    E = linalg.expm(F)
    Ad = E[:ns, :ns]
    B1 = E[:ns, ns + ni:]
    B0 = E[:ns, ns:ns + ni] - B1
    return Ad, B0, B1


def simulate(M, C, K, u, fs, input="ground", dof=None):
    """Simulate the response to a sampled input from rest.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Mass [kg], damping [N s/m] and stiffness [N/m] matrices.
    u : array_like, shape (N,)
        Ground acceleration a_g [m/s^2] (``input="ground"``) or force [N]
        (``input="force"``), sampled at ``fs``; linear between samples.
    fs : float
        Sampling frequency [Hz].
    input : {"ground", "force"}
    dof : int, optional
        0-based DOF loaded by the force (force input only).

    Returns
    -------
    Response
        ``q``, ``v`` (relative to ground for ground input) and the absolute
        acceleration ``a``, each (n, N).
    """
    A, B = state_space(M, C, K, input=input, dof=dof)
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or u.size < 1:
        raise InputError(_SRC, "u", "a non-empty 1-D input record", got=f"shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise InputError(_SRC, "u", "finite samples (no NaN or inf)")
    if not (np.isscalar(fs) and np.isfinite(fs) and fs > 0):
        raise InputError(_SRC, "fs", "a positive sampling frequency in Hz", got=fs)
    n = A.shape[0] // 2
    Ad, B0, B1 = _foh_matrices(A, B, 1.0 / fs)
    # Input contribution of each step, computed at once; the loop only does Ad @ x.
    w = B0[:, 0][:, None] * u[None, :-1] + B1[:, 0][:, None] * u[None, 1:]
    x = np.zeros((2 * n, u.size))
    for k in range(u.size - 1):
        x[:, k + 1] = Ad @ x[:, k] + w[:, k]
    q, v = x[:n], x[n:]
    # q'' from the equation of motion; for ground input the -a_g term cancels
    # in the absolute acceleration q'' + a_g, so only the force case adds B u.
    a = A[n:, :] @ x
    if input == "force":
        a = a + B[n:, :] * u[None, :]
    return Response(t=np.arange(u.size) / fs, q=q, v=v, a=a)
