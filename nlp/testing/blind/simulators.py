"""The blind benchmark's simulators, written apart from `nlp.frf.simulate`: Newmark
average acceleration (linear systems), RK45 with a nonlinear story spring, and exact
frequency-domain filtering (hysteretic damping)."""

import numpy as np
from scipy import signal
from scipy.integrate import solve_ivp


def newmark(M, C, K, b, u, h):
    """Average-acceleration Newmark (beta 1/4, gamma 1/2) for M q'' + C q' + K q = b u(t),
    from rest. Returns q, v, a (n_dof, N).

    The scheme is linear and time-invariant: x_{k+1} = T x_k + g0 u_k + g1 u_{k+1} for
    x = (q, v), with a_k = M^-1 (b u_k - C v_k - K q_k). T is diagonalised once and each
    of its modes run as a one-pole recursion by scipy.signal.lfilter (the same numbers
    as the step-by-step loop, in compiled code).
    """
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    S = M + 0.5 * h * C + 0.25 * h * h * K
    Si = np.linalg.inv(S)
    I = np.eye(n)
    # a_k as a function of the state and u_k, then the predictors
    Aq, Av, Au = -Mi @ K, -Mi @ C, Mi @ b
    q_pred = np.hstack([I + 0.25 * h * h * Aq, h * I + 0.25 * h * h * Av])   # times x_k
    v_pred = np.hstack([0.5 * h * Aq, I + 0.5 * h * Av])
    qu, vu = 0.25 * h * h * Au, 0.5 * h * Au                                 # times u_k
    a_next = -Si @ (C @ v_pred + K @ q_pred)
    a_u0 = -Si @ (C @ vu + K @ qu)
    a_u1 = Si @ b
    T = np.vstack([q_pred + 0.25 * h * h * a_next, v_pred + 0.5 * h * a_next])
    g0 = np.concatenate([qu + 0.25 * h * h * a_u0, vu + 0.5 * h * a_u0])
    g1 = np.concatenate([0.25 * h * h * a_u1, 0.5 * h * a_u1])
    lam, V = np.linalg.eig(T)
    Vi = np.linalg.inv(V)
    c0, c1 = Vi @ g0, Vi @ g1
    uc = u.astype(complex)
    Z = np.empty((2 * n, u.size), complex)
    for r in range(2 * n):
        # z_{k+1} = lam z_k + c0 u_k + c1 u_{k+1}, z_0 = 0 (u_{-1} = 0: the input starts at k = 0)
        Z[r] = signal.lfilter([c1[r], c0[r]], [1.0, -lam[r]], uc)
    Z[:, :] -= np.outer(c1, uc[:1]) * (lam[:, None] ** np.arange(u.size))   # x_0 = 0, not c1 u_0
    X = (V @ Z).real
    q, v = X[:n], X[n:]
    a = Aq @ q + Av @ v + np.outer(Au, u)
    return q, v, a


def nonlinear_ivp(M, C, K, b, u, h, story, kind, k_nl, gap):
    """RK45 (scipy solve_ivp) with a nonlinear story spring: cubic k_nl d^3, or a contact
    spring k_nl (|d| - gap)+ sign(d) that engages beyond the gap. Input linear in time."""
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    g = np.zeros(n)
    g[story - 1] = 1.0
    if story > 1:
        g[story - 2] = -1.0
    t_end = (u.size - 1) * h

    def force(d):
        if kind == "cubic":
            return k_nl * d ** 3
        return k_nl * np.sign(d) * max(abs(d) - gap, 0.0)

    def rhs(t, x):
        q, v = x[:n], x[n:]
        k = min(int(t / h), u.size - 2)
        ut = u[k] + (u[k + 1] - u[k]) * (t / h - k)
        a = Mi @ (b * ut - C @ v - K @ q - g * force(g @ q))
        return np.concatenate([v, a])

    ts = np.arange(u.size) * h
    sol = solve_ivp(rhs, (0, t_end), np.zeros(2 * n), t_eval=ts, method="RK45",
                    max_step=4 * h, rtol=1e-7, atol=1e-12)
    q, v = sol.y[:n], sol.y[n:]
    a = np.array([rhs(t, x)[n:] for t, x in zip(ts, sol.y.T)]).T
    return q, v, a


def freq_domain(M, C, K, Kh, b, u, h):
    """Exact response of M q'' + C q' + (K + j Kh sgn w) q = b u by FFT (zero-padded
    to twice the length so the periodic wrap-around is negligible)."""
    N = 2 * u.size
    U = np.fft.rfft(u, N)
    w = 2 * np.pi * np.fft.rfftfreq(N, h)
    Q = np.empty((M.shape[0], w.size), complex)
    for s in range(0, w.size, 20000):      # batched solves, in blocks to bound memory
        wk = w[s:s + 20000, None, None]
        Z = K + 1j * Kh - wk**2 * M + 1j * wk * C
        Q[:, s:s + 20000] = (np.linalg.solve(Z, np.broadcast_to(b, (wk.shape[0], b.size))[..., None])[..., 0]
                             * U[s:s + 20000, None]).T
    q = np.fft.irfft(Q, N)[:, :u.size]
    v = np.fft.irfft(1j * w * Q, N)[:, :u.size]
    a = np.fft.irfft(-(w**2) * Q, N)[:, :u.size]
    return q, v, a
