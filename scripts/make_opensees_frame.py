"""Make cases/opensees_frame: simulated shake-table FRFs of a 10-storey, 3-bay moment frame.

The model is the OpenSeesPy script cases/opensees_frame/frame.py (120 DOFs:
ux, uy, rz at 40 free nodes). OpenSees assembles M0 and the influence matrix
of every element group the case updates (columns of each storey, lower and
upper beams); the truth multiplies each group's stiffness by 1 + alpha_r with
alpha_r drawn from U(-0.15, 0.15) by the seed. Damping: Rayleigh, 2 % at the
first and seventh sway modes. Data: absolute accelerances of ux at floors 3,
6, 8 and 10 (column line 0) to a horizontal table acceleration, 0.2-20 Hz
(log-spaced, df/f = 0.4 %),
each point computed by a sparse direct solve of (K - w^2 M + jwC) q = -M r
written here (not the package's FRF code), with 2 % complex Gaussian noise.

    python scripts/make_opensees_frame.py [--seed 0] [--noise 0.02] [--out DIR]
"""

import os
import shutil

import numpy as np
import scipy.linalg as sla

from nlp.io.importers.opensees import assemble_script
from nlp.testing.sparse_sim import add_noise, frf_sparse, generator_args, write_case
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "opensees_frame")
STOREYS = 10
GROUPS = {**{f"k_col{s}": f"columns_story{s}" for s in range(1, STOREYS + 1)},
          "k_beams_lower": "beams_lower", "k_beams_upper": "beams_upper"}
SENSOR_FLOORS = (3, 6, 8, 10)


def sway_modes(K, M, dofs):
    """Undamped frequencies [Hz] of the modes with the largest ux participation, ascending."""
    w2, V = sla.eigh(K, M)
    r = np.array([1.0 if d == 1 else 0.0 for _, d in dofs])
    gamma = (V.T @ M @ r) ** 2
    sway = np.sort(np.argsort(-gamma)[:STOREYS])
    return np.sqrt(w2[sway]) / (2 * np.pi)


def make(seed=0, noise=0.02, script=os.path.join(CASE, "frame.py")):
    a = assemble_script(script, GROUPS)
    M, K0, dofs = a["M0"], a["K0"], a["dofs"]
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(-0.15, 0.15, len(GROUPS))
    K = K0 + sum(al * Kr for al, Kr in zip(alpha, a["K_infl"]))
    f_sway = sway_modes(K, M, dofs)
    w1, w7 = 2 * np.pi * f_sway[0], 2 * np.pi * f_sway[6]
    zeta = 0.02
    a1 = 2 * zeta / (w1 + w7)
    a0 = a1 * w1 * w7
    C = a0 * M + a1 * K
    # log-spaced: 10 points per half-power bandwidth (2 zeta f) at every mode
    f = np.geomspace(0.2, 20.0, int(np.log(100) / (0.2 * zeta)) + 1)
    r = np.array([1.0 if d == 1 else 0.0 for _, d in dofs])
    rows = [dofs.index((100 * fl, 1)) for fl in SENSOR_FLOORS]
    H = frf_sparse(M, K, C, -(M @ r), rows, f, power=2) + 1.0  # absolute: relative + table
    truth = {"alpha": dict(zip(GROUPS, alpha.tolist())), "a0": a0, "a1": a1,
             "sway_frequencies_hz": f_sway.tolist(), "zeta_sway_1_and_7": zeta,
             "n_dof": len(dofs), "seed": seed, "noise": noise}
    return f, add_noise(H, noise, rng), truth, (f_sway, a0, a1)


def case_yaml(f_sway):
    """The case file: nominal model, Rayleigh start 3 % at the first and seventh sway modes."""
    w1, w7 = 2 * np.pi * f_sway[0], 2 * np.pi * f_sway[6]
    a1 = 2 * 0.03 / (w1 + w7)
    return {
        "name": "opensees_frame",
        "description": "10-storey 3-bay steel moment frame (OpenSeesPy, 120 DOFs), shake-table "
                       "absolute accelerances at floors 3, 6, 8, 10; 12 element-group stiffnesses",
        "model": {"type": "opensees", "script": "frame.py", "stiffness_groups": dict(GROUPS)},
        "parameters": {"stiffness_bounds": [-0.5, 1.0]},
        "damping": {"model": "rayleigh", "a0": float(a1 * w1 * w7), "a1": float(a1)},
        "excitation": {"type": "ground", "direction": "ux"},
        "data": {"file": "frf.npz", "window": "none", "channels": [
            {"name": f"a{fl}", "node": 100 * fl, "dof": "ux", "output": "absolute_accelerance",
             "column": i} for i, fl in enumerate(SENSOR_FLOORS)]},
        "frequencies": {"method": "half_power", "k": 2.0, "fmin": 0.3, "fmax": 20.0},
        "objective": {"residual": "log_magnitude"},
        "search": {"starts": 4, "seed": 0},
    }


def main():
    a = generator_args(__doc__, CASE)
    f, H, truth, (f_sway, _, _) = make(a.seed, a.noise, os.path.join(CASE, "frame.py"))
    write_case(a.out, f, H, truth, case_yaml(f_sway))
    if os.path.abspath(a.out) != os.path.abspath(CASE):
        shutil.copy(os.path.join(CASE, "frame.py"), a.out)
    print(f"wrote {a.out}: {H.shape[0]} channels x {f.size} points, {truth['n_dof']} DOFs; "
          f"sway modes {np.round(f_sway, 2)} Hz")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
