"""Which test determines every storey of a tall frame? Fisher standard errors (issue 47).

The 256-storey frame of ``scripts/bench_scale.py`` leaves 51 of its 511 parameter
combinations with standard errors over 100 %: 4 receptances and 0.5 % noise do not
determine 513 per-storey parameters. This script asks which test would, at the truth of
``nlp.testing.tall.tall_frame`` (no fit, no package FRF code): for a layout of sensors
and frequency points it forms the Jacobian of ln|H| in the relative parameters
(stiffnesses, masses but floor 1's, ln a0, ln a1) by adjoint solves of the tridiagonal
dynamic stiffness Z = K - w^2 M + i w (a0 M + a1 K), and prints the Cramer-Rao standard
errors sqrt(diag((J^T J / sigma^2)^-1)) of the stiffnesses, sigma = noise / sqrt(2) (the
ln-magnitude part of a relative complex noise). Layouts are compared at a fixed number of
channel points (sensors x points), the cost of one evaluation, and more.

Run:  python research/tall_design.py [--n 256] [--layouts 4x40 8x20 16x10 32x5 ...]
      (SxP: S sensors spread evenly from floor 1 to the roof, P points per storey)
"""

import argparse

import numpy as np

from nlp.testing.tall import NOISE, tall_frame


def _thomas(lower, diag, upper, rhs):
    """Solve tridiagonal systems batched over the first axis (one per frequency).
    lower, upper: (N, n-1); diag: (N, n); rhs: (N, n, r)."""
    N, n = diag.shape
    c = np.empty((N, n - 1), complex)
    d = np.empty(rhs.shape, complex)
    c[:, 0] = upper[:, 0] / diag[:, 0]
    d[:, 0] = rhs[:, 0] / diag[:, 0, None]
    for i in range(1, n):
        den = diag[:, i] - lower[:, i - 1] * c[:, i - 1]
        if i < n - 1:
            c[:, i] = upper[:, i] / den
        d[:, i] = (rhs[:, i] - lower[:, i - 1, None] * d[:, i - 1]) / den[:, None]
    for i in range(n - 2, -1, -1):
        d[:, i] -= c[:, i, None] * d[:, i + 1]
    return d


def _drift(x):
    """Story drifts x_s - x_(s-1), ground at rest (axis 1 is the floor)."""
    return np.diff(x, axis=1, prepend=0.0)


def jacobian_lnH(m, k, a0, a1, omega, dofs):
    """d ln|H_o(w)| / d theta, rows (channel, frequency), columns: theta_k (n), theta_m of
    floors 2..n, ln a0, ln a1 (theta: relative change, k = k0 (1 + theta))."""
    n, N = k.size, omega.size
    w = omega[:, None]
    kk = k[None, :] * (1 + 1j * w * a1)                   # story stiffness with its damping
    diag = (kk + np.append(kk[:, 1:], np.zeros((N, 1)), axis=1)
            + (-w ** 2 + 1j * w * a0) * m[None, :])
    off = -kk[:, 1:]
    rhs = np.zeros((N, n, 1 + len(dofs)), complex)
    rhs[:, :, 0] = -m[None, :]                            # b = -M 1 (ground acceleration)
    for j, o in enumerate(dofs):
        rhs[:, o, 1 + j] = 1.0
    sol = _thomas(off, diag, off, rhs)
    u, G = sol[:, :, 0], sol[:, :, 1:]
    du = _drift(u)
    rows = []
    for j, o in enumerate(dofs):
        g = G[:, :, j]
        H = u[:, o][:, None]
        dk = -(kk * _drift(g) * du)
        dm = -m[None, :] * g * (1 + (-w ** 2 + 1j * w * a0) * u)
        Mu = m[None, :] * u
        Ku = np.append(-np.diff(k[None, :] * du, axis=1), k[None, -1:] * du[:, -1:], axis=1)
        da0 = -(1j * w[:, 0] * a0) * np.sum(g * Mu, axis=1)
        da1 = -(1j * w[:, 0] * a1) * np.sum(g * Ku, axis=1)
        dH = np.hstack([dk, dm[:, 1:], da0[:, None], da1[:, None]])
        rows.append(np.real(dH / H))
    return np.vstack(rows)


def layout(n, sensors, points, seed=0):
    fr = tall_frame(n, seed=seed, points_per_storey=1)
    f1, fn = fr.f[0] / 0.5, fr.f[-1] / 1.1
    f = np.linspace(0.5 * f1, 1.1 * fn, points * n)
    dofs = sorted(set(np.linspace(0, n - 1, sensors).round().astype(int).tolist()))
    return fr, 2 * np.pi * f, dofs


def standard_errors(fr, omega, dofs, noise=NOISE, chunk=512):
    n = fr.n
    F = np.zeros((2 * n + 1, 2 * n + 1))
    for s in range(0, omega.size, chunk):
        J = jacobian_lnH(fr.m, fr.k, fr.a0, fr.a1, omega[s:s + chunk], dofs)
        F += J.T @ J
    F /= (noise / np.sqrt(2)) ** 2
    cov = np.linalg.pinv(F, rcond=1e-14, hermitian=True)
    return np.sqrt(np.clip(np.diag(cov), 0, None)), np.linalg.eigvalsh(F)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=256)
    ap.add_argument("--layouts", nargs="*", default=["4x40", "8x20", "16x10", "32x5", "8x40", "16x40"])
    ap.add_argument("--check", action="store_true", help="compare the Jacobian with finite differences")
    a = ap.parse_args()
    if a.check:
        check()
    print(f"n = {a.n}, noise {NOISE:.1%}: Cramer-Rao standard errors of the storey stiffnesses")
    print(f"{'layout':>8} {'sensors':>7} {'points':>7} {'ch.points':>9} {'median SE':>9} "
          f"{'max SE':>7} {'storeys SE>0.5%':>15} {'eig<1':>6}")
    for spec in a.layouts:
        s, p = (int(v) for v in spec.split("x"))
        fr, omega, dofs = layout(a.n, s, p)
        se, eig = standard_errors(fr, omega, dofs)
        sk = se[:a.n]
        print(f"{spec:>8} {len(dofs):>7} {omega.size:>7} {omega.size * len(dofs):>9} "
              f"{np.median(sk):>9.3%} {sk.max():>7.2%} {int(np.sum(sk > 0.005)):>15} "
              f"{int(np.sum(eig < 1)):>6}", flush=True)


def check(n=12):
    """The adjoint Jacobian against central differences of the package-free modal sum."""
    from nlp.testing.tall import modal_receptance
    fr, omega, dofs = layout(n, 3, 10)
    J = jacobian_lnH(fr.m, fr.k, fr.a0, fr.a1, omega, dofs)
    base = np.concatenate([np.zeros(2 * n - 1), [0.0, 0.0]])

    def lnH(t):
        k = fr.k * (1 + t[:n])
        m = fr.m * (1 + np.concatenate([[0.0], t[n:2 * n - 1]]))
        H, _ = modal_receptance(m, k, omega, dofs, fr.a0 * np.exp(t[-2]), fr.a1 * np.exp(t[-1]))
        return np.log(np.abs(H)).ravel()
    h = 1e-6
    fd = np.column_stack([(lnH(base + h * e) - lnH(base - h * e)) / (2 * h) for e in np.eye(base.size)])
    err = np.abs(fd - J).max() / np.abs(fd).max()
    print(f"Jacobian check (n = {n}): largest difference to central differences {err:.1e} of the largest entry")


if __name__ == "__main__":
    main()
