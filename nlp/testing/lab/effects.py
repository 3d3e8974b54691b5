"""Nonlinear links between two degrees of freedom, and their simulation.

A link acts on the drift d = q_j - q_i (i = None: the ground, i.e. the table in relative
coordinates) with a force phi(d, d') on top of the linear K, C:

* cubic joint: phi = k3 d^3 (k3 < 0 softens), the equivalent stiffness change at drift
  amplitude A being 3 k3 A^2 / 4 (harmonic balance, sinusoidal d);
* Coulomb friction: phi = F_c tanh(d' / v_0) (a rounded sign; v_0 small against the drift
  velocities, so the stick phase is a stiff dashpot F_c / v_0);
* contact stop (the tool's own nonlinearity family): phi = k_c sign(d) (|d| - gap)+;
* breathing crack: phi = -delta k min(d, 0): the story has k when closed (d >= 0) and
  (1 - delta) k when open; positively homogeneous, so amplitude-independent;
* sliding mass: a mass m_s on floor j held by friction mu m_s g (phi = mu m_s g tanh(d'/v_0)
  between the floor and the mass's own DOF) and a weak centring spring in K: it moves with
  the floor below the acceleration mu g and slips above it.
"""

import numpy as np
from scipy.integrate import solve_ivp

G = 9.80665


def link_force(link, d, v):
    """phi(d, d') of one link [N]."""
    kind = link["kind"]
    if kind == "cubic":
        return link["k3"] * d**3
    if kind in ("friction", "slider"):
        return link["F_c"] * np.tanh(v / link["v0"])
    if kind == "contact":
        return link["k_c"] * np.sign(d) * np.maximum(np.abs(d) - link["gap"], 0.0)
    if kind == "crack":
        return -link["delta"] * link["k"] * np.minimum(d, 0.0)
    raise ValueError(f"unknown link kind {kind!r}")


def link_slopes(link, d, v):
    """d phi / d d and d phi / d d' of one link."""
    kind = link["kind"]
    if kind == "cubic":
        return 3 * link["k3"] * d * d, 0.0
    if kind in ("friction", "slider"):
        return 0.0, link["F_c"] / link["v0"] / np.cosh(min(abs(v / link["v0"]), 350.0)) ** 2
    if kind == "contact":
        return (link["k_c"] if abs(d) > link["gap"] else 0.0), 0.0
    return (-link["delta"] * link["k"] if d < 0 else 0.0), 0.0


def selector(link, n):
    """g with d = g . q for the link."""
    g = np.zeros(n)
    g[link["j"]] = 1.0
    if link.get("i") is not None:
        g[link["i"]] = -1.0
    return g


def simulate_links(M, C, K, b, u, h, links):
    """M q'' + C q' + K q + sum g phi(g.q, g.q') = b u(t) from rest, u linear between
    samples (LSODA: the friction stick phase is stiff). Returns q, v, a (n_dof, N)."""
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    gs = [selector(lk, n) for lk in links]
    MiK, MiC, Mib = Mi @ K, Mi @ C, Mi @ b
    Mig = [Mi @ g for g in gs]

    def accel(t, q, v):
        k = min(int(t / h), u.size - 2)
        ut = u[k] + (u[k + 1] - u[k]) * (t / h - k)
        a = Mib * ut - MiC @ v - MiK @ q
        for lk, g, mg in zip(links, gs, Mig):
            a -= mg * link_force(lk, g @ q, g @ v)
        return a

    def rhs(t, x):
        return np.concatenate([x[n:], accel(t, x[:n], x[n:])])

    ts = np.arange(u.size) * h
    sol = solve_ivp(rhs, (0, ts[-1]), np.zeros(2 * n), t_eval=ts, method="LSODA",
                    max_step=8 * h, rtol=1e-7, atol=1e-12)
    q, v = sol.y[:n], sol.y[n:]
    a = Mib[:, None] * u - MiC @ v - MiK @ q
    for lk, g, mg in zip(links, gs, Mig):
        a -= np.outer(mg, link_force(lk, g @ q, g @ v))
    return q, v, a


def cubic_for_change(change, k, amplitude):
    """k3 whose equivalent stiffness change at drift amplitude A is change * k:
    3 k3 A^2 / 4 = change k (harmonic balance)."""
    return 4 * change * k / (3 * amplitude**2)


def crack_equivalent(delta):
    """Equivalent linear stiffness ratio of the bilinear story, k_eq / k, from the
    period of the bilinear oscillator, half cycles at k and at (1 - delta) k:
    T = pi/w_1 + pi/w_2, so w_eq/w_1 = 2 / (1 + 1/sqrt(1 - delta)), squared."""
    return (2.0 / (1.0 + 1.0 / np.sqrt(1.0 - delta))) ** 2


def link_arrays(links):
    """The links' parameters as arrays (zero where a kind does not apply)."""
    get = lambda kinds, key, default=0.0: np.array(                       # noqa: E731
        [lk[key] if lk["kind"] in kinds else default for lk in links], float)
    return {"k3": get(("cubic",), "k3"), "F_c": get(("friction", "slider"), "F_c"),
            "v0": get(("friction", "slider"), "v0", 1.0), "k_c": get(("contact",), "k_c"),
            "gap": get(("contact",), "gap"),
            "dk": np.array([lk["delta"] * lk["k"] if lk["kind"] == "crack" else 0.0 for lk in links])}


def forces_slopes(p, d, dv):
    """phi, d phi/d d, d phi/d d' of every link at once (link_force, vectorised)."""
    x = np.minimum(np.maximum(dv / p["v0"], -350.0), 350.0)
    over = np.abs(d) > p["gap"]
    phi = (p["k3"] * d**3 + p["F_c"] * np.tanh(x) + p["k_c"] * np.sign(d) * np.maximum(np.abs(d) - p["gap"], 0.0)
           - p["dk"] * np.minimum(d, 0.0))
    s_d = 3 * p["k3"] * d * d + p["k_c"] * over - p["dk"] * (d < 0)
    s_v = p["F_c"] / p["v0"] / np.cosh(x) ** 2
    return phi, s_d, s_v


def newmark_links(M, C, K, b, u, h, links, iterations=20, tol=1e-10):
    """Average-acceleration Newmark with the links' forces implicit (unconditionally
    stable, so the friction stick phase needs no small steps). Per step, Newton on the
    link forces phi only: with S = M + h/2 C + h^2/4 K, W = G S^-1 G^T and the linear
    step's drifts d_lin, d'_lin, the step's drifts are d = d_lin - h^2/4 W phi,
    d' = d'_lin - h/2 W phi, and phi = Phi(d, d') is solved for. Returns q, v, a."""
    n = M.shape[0]
    G = np.array([selector(lk, n) for lk in links]).reshape(len(links), n)
    p = link_arrays(links)
    Si = np.linalg.inv(M + 0.5 * h * C + 0.25 * h * h * K)
    SiG = Si @ G.T
    W = G @ SiG
    Wq, Wv = 0.25 * h * h * W, 0.5 * h * W
    # plain substitution converges when |D| |W| < 1 (D: the links' slopes scaled by the step)
    Sib, SiC, SiK = Si @ b, Si @ C, Si @ K
    N = u.size
    X = np.zeros((N, 3, n))                       # q, v, a per step
    X[0, 2] = np.linalg.solve(M, b * u[0])
    phi = np.zeros(len(links))
    eye = np.eye(len(links))
    w_max = np.abs(W).sum(axis=1).max()
    for k in range(N - 1):
        q, v, a = X[k]
        qp = q + h * v + 0.25 * h * h * a
        vp = v + 0.5 * h * a
        a_lin = Sib * u[k + 1] - SiC @ vp - SiK @ qp
        d_lin = G @ (qp + 0.25 * h * h * a_lin)
        v_lin = G @ (vp + 0.5 * h * a_lin)
        for _ in range(iterations):
            f, s_d, s_v = forces_slopes(p, d_lin - Wq @ phi, v_lin - Wv @ phi)
            D = 0.25 * h * h * s_d + 0.5 * h * s_v
            if np.abs(D).max() * w_max < 0.05:
                step = phi - f         # a contraction: plain substitution converges
            else:
                step = np.linalg.solve(eye + D[:, None] * W, phi - f)
            phi = phi - step
            if np.abs(step).max() <= tol * (1.0 + np.abs(phi).max()):
                break
        an = a_lin - SiG @ phi
        X[k + 1, 0] = qp + 0.25 * h * h * an
        X[k + 1, 1] = vp + 0.5 * h * an
        X[k + 1, 2] = an
    return X[:, 0].T.copy(), X[:, 1].T.copy(), X[:, 2].T.copy()
