"""Coloured, partly common-mode measurement noise.

Each channel i records n_i(t) = sigma_i (sqrt(1 - c) z_i(t) + sqrt(c) z_0(t)): z_0 is shared
by every channel of the acquisition system (ground loops, the supply, the table's hydraulics),
z_i is the channel's own. Every z has unit variance and the same spectral shape

    S(f) = (1 - p) / f_N + p / (f ln(f_N / f_lo))     (f_lo <= f <= f_N, one-sided)

white plus a 1/f (flicker) part holding the share p of the variance. Two channels' noises
then have correlation c at every frequency.
"""

import numpy as np

COMMON = (0.2, 0.5)        # c: the shared share of each channel's noise variance
PINK = (0.3, 0.7)          # p: the 1/f share of the variance
LEVEL = (0.01, 0.03)       # sigma_i / RMS of the channel's level-1 record
F_LO = 0.05                # [Hz] lowest frequency of the 1/f part


def shape(f, fs, pink):
    """S(f) of the module docstring, normalised to unit variance over 0 < f <= fs/2."""
    fn = fs / 2
    fc = np.clip(np.asarray(f, float), F_LO, None)
    return (1 - pink) / fn + pink / (fc * np.log(fn / F_LO))


def coloured(rng, n, fs, pink):
    """Unit-variance Gaussian noise of n samples with the spectral shape S (by FFT)."""
    f = np.fft.rfftfreq(n, 1 / fs)
    spec = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    spec *= np.sqrt(shape(f, fs, pink))
    spec[0] = 0.0
    z = np.fft.irfft(spec, n)
    return z / np.std(z)


def lab_noise(rng, names, n, fs, sigma, common, pink):
    """Noise for every channel name: sigma[name] (sqrt(1 - c) z_i + sqrt(c) z_0)."""
    z0 = coloured(rng, n, fs, pink)
    return {k: sigma[k] * (np.sqrt(1 - common) * coloured(rng, n, fs, pink) + np.sqrt(common) * z0)
            for k in names}


def correlation_sd(n, fs, pink, c):
    """Sampling SD of the correlation coefficient of two channels' noises: for Gaussian
    series with autocorrelation r(k), var(r_hat) ~ (1 - c^2)^2 sum_k r(k)^2 / n
    (Bartlett 1946), and sum_k r(k)^2 = n sum_f S_f^2 / (sum_f S_f)^2 over the FFT bins
    (Parseval; both sides counted over positive and negative frequencies)."""
    f = np.fft.rfftfreq(n, 1 / fs)[1:]
    S = shape(f, fs, pink)
    S2 = np.concatenate([S, S])
    return (1 - c * c) * np.sqrt(np.sum(S2**2) / np.sum(S2) ** 2)
