"""Small shear frames with FRF files for the diagnosis tests: the frequency grid, the
frame (Rayleigh damping), the case file over FRF files, and the baseline fit."""

import numpy as np
import yaml
from scipy.linalg import eigh

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.fitting import (diagnosis_problem, fit_target, fit_windows, noise_sigma,
                                   scatter_best)
from nlp.solve.search import SearchConfig
from nlp.testing.frames import shear_K

F = np.arange(0.5, 16.0, 0.02)     # the FRF files' frequencies [Hz]


def write_case_yaml(folder, m_nom, k_nom, files, parameters, damping, channels=3):
    """Write case.yaml for the FRF files [(name, force floor)] (first is the update)."""
    data = {"file": files[0][0],
            "channels": [{"name": f"a{i + 1}", "floor": i + 1, "output": "accelerance",
                          "column": i} for i in range(channels)]}
    if len(files) > 1:
        data["validation_file"] = files[1][0]
        data["validation_force_floor"] = files[1][1]
    case = {"name": "t", "model": {"type": "shear_frame", "masses": [float(x) for x in m_nom],
                                  "stiffnesses": [float(x) for x in k_nom]},
            "parameters": parameters, "damping": damping,
            "excitation": {"type": "force", "floor": files[0][1]}, "data": data,
            "frequencies": {"method": "half_power", "k": 2.0, "fmin": 0.5, "fmax": 15.0},
            "search": {"starts": 8, "seed": 0, "workers": 1}}
    (folder / "case.yaml").write_text(yaml.safe_dump(case, sort_keys=False))
    return load_case(str(folder / "case.yaml"))


def write_frf(folder, name, H):
    """FRF file `name` in folder: H (n_ch, len(F)) on the grid F."""
    np.savez(folder / name, f=F, H=H)


def frame_matrices(m, k, zeta=0.015):
    """M, C, K of a shear frame with Rayleigh damping of ratio zeta at modes 1 and n."""
    M, K = np.diag(m), shear_K(k)
    w = np.sqrt(eigh(K, M, eigvals_only=True))
    a1 = 2 * zeta / (w[0] + w[-1])
    a0 = a1 * w[0] * w[-1]
    return M, a0 * M + a1 * K, K


def baseline_fit(cfg, starts=6):
    """The case's own general-C fit on its half-power windows (a short scatter search)."""
    case = assemble(cfg)
    fit = fit_windows(cfg, case, 1)
    target = fit_target(case, fit, noise_sigma(case, fit))
    pr = diagnosis_problem(case, target)
    res, _ = scatter_best(pr, SearchConfig(starts=starts, seed=0, workers=1))
    return case, {"current": [], "z": res.z, "chi": 2 * res.f, "held": 1.0, "problem": pr}


def coupled_case(folder, kc=900.0, seed=3):
    """A 3-storey frame (5 kg floors, Rayleigh damping) with a spring kc [N/m] between floors
    1 and 3 that its case.yaml leaves out: accelerances to a force at floor 1 with 1 %
    complex noise in frf.npz. One round of candidates finds the spring (about 30 s)."""
    rng = np.random.default_rng(seed)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, _ = frame_matrices(m, k)
    e = np.array([1.0, 0.0, -1.0])
    K = shear_K(k) + kc * np.outer(e, e)
    H = np.empty((3, F.size), complex)
    for i, f in enumerate(F):
        w = 2 * np.pi * f
        H[:, i] = -w**2 * np.linalg.solve(K - w**2 * M + 1j * w * C, np.eye(3)[0])
    H *= 1 + 0.01 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape))
    write_frf(folder, "frf.npz", H)
    return write_case_yaml(folder, m, k, [("frf.npz", 1)],
                           {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                           {"model": "rayleigh", "zeta": 0.015})
