"""Write small case folders for tests (YAML + NPZ), from the truth of nlp.testing.four_story."""

import os

import numpy as np
import yaml

from nlp.testing.four_story import MASSES, STIFFNESSES, make, true_damping
from nlp.testing.frames import shear_K

BASE = {
    "name": "test_case",
    "model": {"type": "shear_frame", "masses": [4.64] * 4, "stiffnesses": [1019, 1217, 1420, 2473]},
    "parameters": {"fixed": {"m1": 5.16}},
    "damping": {"model": "general", "zeta": 0.02},
    "excitation": {"type": "ground"},
    "data": {"file": "frf.npz", "window": "none", "channels": [
        {"name": f"floor{i + 1}", "floor": i + 1, "output": "receptance", "column": i}
        for i in range(4)]},
    "frequencies": {"method": "all", "fmin": 0.5, "fmax": 6.5},
    "objective": {"residual": "log_magnitude"},
    "solver": {"name": "ipopt", "options": {}},
    "search": {"starts": 1, "seed": 0, "workers": 1},
}


def deep_update(d, u):
    """Merge u into d; a value of None deletes the key."""
    out = dict(d)
    for k, v in u.items():
        if v is None:
            out.pop(k, None)
        else:
            out[k] = deep_update(d[k], v) if isinstance(v, dict) and isinstance(d.get(k), dict) else v
    return out


def force_frf(output, f=None):
    """Truth-model FRFs of all floors to a force at floor 1 (independent numpy solve)."""
    f = np.arange(0.02, 8, 0.02) if f is None else f
    M, K = np.diag(MASSES), shear_K(STIFFNESSES)
    C = true_damping(M, K)
    w = 2 * np.pi * f
    H = np.array([np.linalg.solve(K - wk**2 * M + 1j * wk * C, np.eye(4)[0]) for wk in w]).T
    H = H * {"receptance": 1, "accelerance": -(w**2)}[output]
    chans = [{"name": f"{output[0]}{i + 1}", "floor": i + 1, "output": output, "column": i}
             for i in range(4)]
    return f, H, chans


def write_case(folder, noise=0.0, seed=0, H=None, f=None, **changes):
    """Write frf.npz and case.yaml in folder; returns (case path, truth)."""
    os.makedirs(folder, exist_ok=True)
    f0, H0, truth = make(seed=seed, noise=noise)
    np.savez(os.path.join(folder, "frf.npz"), f=f0 if f is None else f, H=H0 if H is None else H)
    cfg = deep_update(BASE, changes)
    path = os.path.join(folder, "case.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    return path, truth
