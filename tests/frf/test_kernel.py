"""The model seen through a Welch estimate's window (Target.kernel, nlp.frf.kernel.smoothing_taps).

For a flat input spectrum the expected Welch H1 is the true FRF convolved with the
window's power kernel |W(nu)|^2 (normalised); here that convolution is computed by
quadrature on a fine grid, independently of the package's three taps.
"""

from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from support.cases import write_case
from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.frf.reference import modal_parameters
from nlp.frf.kernel import smoothing_taps
from nlp.solve.problem import SolverConfig, UpdatingProblem


def test_hann_taps_are_one_bin_and_one_sixth():
    """Hann's power kernel has m2 = m4 = 1/3 bins^2, bins^4 (Parseval with w'' = -(2 pi / L)^2
    (w - 1/2)): the taps matching both sit at h = sqrt(m4 / m2) = 1 bin with a = m2^2 / (2 m4)
    = 1/6."""
    h, a = smoothing_taps("hann", 4096)
    assert h == pytest.approx(1.0, abs=1e-3) and a == pytest.approx(1 / 6, abs=1e-3)


def test_smoothed_model_matches_the_expected_welch_estimate_at_a_sharp_peak(tmp_path):
    path, _ = write_case(str(tmp_path / "c"))
    case = assemble(load_case(path))
    base = UpdatingProblem(case.model, case.damping, case.params, case.target,
                           solver=SolverConfig(compile=False))
    z = base.z0
    M, K, C = base.matrices(z)
    fn, zeta, _ = modal_parameters(M, C, K)
    df = zeta[0] * fn[0]                 # the half-power band of mode 1 spans two bins
    L = 4096
    h, a = smoothing_taps("hann", L)
    smooth = UpdatingProblem(case.model, case.damping, case.params,
                             replace(case.target, kernel=(2 * np.pi * h * df, a)),
                             solver=SolverConfig(compile=False))
    f = fn[0] + df * np.arange(-4, 5)    # bins around the peak

    def receptance(fq):
        return np.array([np.linalg.solve(K - (2 * np.pi * x) ** 2 * M
                                         + 2j * np.pi * x * C, -M @ np.ones(M.shape[0]))
                         for x in fq]).T

    # exact expectation: |W(nu)|^2 of a Hann window of L points on a grid of 1/16 bin,
    # out to +-12 bins (the kernel's mass beyond is below 1e-5)
    P = 16
    W2 = np.abs(np.fft.fft(signal.get_window("hann", L), L * P)) ** 2
    nu = np.fft.fftfreq(L * P, d=1.0 / L)
    near = np.abs(nu) <= 12
    kern = W2[near] / W2.sum()
    expected = np.array([receptance(fk - nu[near] * df) @ kern for fk in f]).T
    raw = base.channel_frfs(z, 2 * np.pi * f)
    model = smooth.channel_frfs(z, 2 * np.pi * f)
    err_raw = np.abs(np.log(np.abs(raw / expected)))
    err_model = np.abs(np.log(np.abs(model / expected)))
    assert err_raw.max() > 0.1                     # the window's bias at this peak is large
    # measured: 0.215 raw, 0.032 with the taps (their fifth-order remainder at a 2-bin peak)
    assert err_model.max() < 0.2 * err_raw.max()   # the three taps carry most of it
