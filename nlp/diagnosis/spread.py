"""How far a right noise model's reduced chi-square may stray from 1 on these data.

A reduced chi-square is the mean of z^2 over the fitted points, z = residual / sigma.
With N independent Gaussian z it scatters about 1 with a standard deviation
sqrt(2 / N). FRF errors are not independent: the input's noise and the leakage of
the common modal response are shared by every channel at one frequency, and a
windowed estimate correlates neighbouring bins. The spread then follows the
effective number of independent points,

    N_eff = N^2 / sum_ij rho_ij^2,     SD(mean z^2) = sqrt(v / N_eff),

where rho_ij is the correlation of z_i and z_j (for Gaussian errors the correlation
of z_i^2 and z_j^2 is rho_ij^2) and v = 2, the variance of one z^2 for a Gaussian
error of unit variance. That is the spread under the hypothesis being checked (the
noise model is right); v is not read from the residuals, whose heavy tails would
widen the range exactly when the model is wrong. The correlations are read from the
residuals: between channels at one bin and between bins up to ``max_lag`` apart
inside contiguous windows, a stationary model along frequency.
"""

import numpy as np

__all__ = ["effective_points", "chi2_spread", "correlation_factor"]


def _contiguous_pairs(idx, lag):
    """Positions k with idx[k + lag] == idx[k] + lag (both inside one window)."""
    idx = np.asarray(idx)
    return np.flatnonzero(idx[lag:] - idx[:-lag] == lag)


def effective_points(z, idx=None, max_lag=3):
    """Effective number of independent points of standardized residuals.

    Parameters
    ----------
    z : ndarray, shape (n_ch, n_f)
        Signed residuals over their noise (mean ~0, variance ~1), channels by bins.
    idx : array of int, optional
        Grid index of each column of z; bins ``lag`` apart on the grid correlate.
        Default: consecutive.
    max_lag : int
        Largest bin lag whose correlation is counted.

    Returns
    -------
    float
        N^2 / sum of squared correlations over all pairs of the N = n_ch x n_f points,
        between 1 and N. Squared sample correlations are debiased by 1/n (their
        expectation under no correlation), so independent errors give about N.
    """
    z = np.atleast_2d(np.asarray(z, float))
    z = np.where(np.isfinite(z), z, 0.0)     # points the fit does not use
    nc, nf = z.shape
    idx = np.arange(nf) if idx is None else np.asarray(idx)
    N = nc * nf
    if nf < 5:
        return float(N)
    s = np.sqrt(np.mean(z ** 2, axis=1))
    s[s == 0] = 1.0
    u = z / s[:, None]

    def sq(c, n):
        # a sample correlation of n independent pairs has E[r^2] = 1/n
        return np.clip(c ** 2 - 1.0 / n, 0.0, None)

    c0 = (u @ u.T) / nf
    off = sq(c0, nf)
    np.fill_diagonal(off, 0.0)
    total = nf * (nc + off.sum())
    for lag in range(1, max_lag + 1):
        k = _contiguous_pairs(idx, lag)
        if k.size >= 5:
            c = (u[:, k] @ u[:, k + lag].T) / k.size
            total += 2 * k.size * sq(c, k.size).sum()
    return float(min(N, N ** 2 / total))


def chi2_spread(z, idx=None, max_lag=3):
    """Standard deviation of mean z^2 about 1 for a right noise model (Gaussian errors).

    Parameters
    ----------
    z, idx, max_lag : see :func:`effective_points`.

    Returns
    -------
    sd : float
        sqrt(2 / N_eff).
    n_eff : float
        :func:`effective_points`.
    """
    n_eff = effective_points(z, idx, max_lag)
    return float(np.sqrt(2.0 / n_eff)), n_eff


def correlation_factor(r, A, idx, max_lag=3):
    """How much correlated residuals inflate the chi-square drop along columns A.

    A quasi-likelihood treats the residuals as independent with one variance phi, so the
    drop from fitting k new parameters is read as phi chi-square(k). With residual
    covariance Sigma the drop along the columns A (each already projected off the other
    parameters' columns) has expectation tr((A^T A)^-1 A^T Sigma A), so

        factor = tr((A^T A)^-1 A^T Sigma A) / (k phi),    phi = mean r^2,

    is 1 for independent residuals, and about 1 + 2 sum_l rho_l (not the 1 + 2 sum_l rho_l^2
    of :func:`effective_points`) for a column smooth along frequency. Sigma is estimated
    from the residuals as a banded (Newey-West type, rectangular kernel) covariance: all
    residuals at one frequency with each other, and at frequencies up to max_lag bins apart
    inside one contiguous window. The drop over phi divided by the factor is then read
    against chi-square(k).

    Parameters
    ----------
    r : ndarray, shape (N * n_r,)
        Residuals, frequency-major (the n_r residuals of frequency 0 first, as the
        problems' residual vectors are laid out).
    A : ndarray, shape (N * n_r, k)
        The columns of the parameters whose drop is judged, in the same layout.
    idx : array of int, shape (N,)
        Grid index of each frequency; bins ``lag`` apart on the grid correlate.
    max_lag : int
        Largest bin lag counted.

    Returns
    -------
    float
        The factor, at least 1 / (2 max_lag + 1) (a rectangular-kernel estimate can dip
        below what any covariance gives); 1.0 when it cannot be formed.
    """
    idx = np.asarray(idx)
    r = np.asarray(r, float).ravel()
    A = np.asarray(A, float).reshape(r.size, -1)
    N = idx.size
    if N < 5 or r.size % N:
        return 1.0
    n_r, k = r.size // N, A.shape[1]
    U = r.reshape(N, n_r)                       # residuals of frequency i in row i
    B = A.reshape(N, n_r, k)
    phi = float(np.mean(U ** 2))
    AtA = A.T @ A
    if phi <= 0 or not np.all(np.isfinite(AtA)) or np.linalg.matrix_rank(AtA) < k:
        return 1.0
    # A^T Sigma A = sum_i B_i^T G0 B_i + sum_l sum_(i, i+l) (B_i^T G_l B_(i+l) + transpose)
    G0 = U.T @ U / N
    S = np.einsum("iak,ab,ibm->km", B, G0, B)
    for lag in range(1, max_lag + 1):
        pairs = _contiguous_pairs(idx, lag)
        if pairs.size < 5:
            continue
        Gl = U[pairs].T @ U[pairs + lag] / pairs.size
        T = np.einsum("iak,ab,ibm->km", B[pairs], Gl, B[pairs + lag])
        S += T + T.T
    factor = float(np.trace(np.linalg.solve(AtA, S))) / (k * phi)
    return max(factor, 1.0 / (2 * max_lag + 1))
