"""Make cases/frame3d_2100: force-input FRFs of a 2,100-DOF 3-D moment frame, as matrix files.

OpenSees assembles the model script cases/frame3d_2100/frame3d.py (10 storeys,
7 x 5 columns, 6 DOFs per node); M0, K0 are exported as Matrix Market files,
the 20 group influence matrices (columns of each storey; x and y beams of each
pair of storeys) as scipy.sparse NPZ files, and the node-to-DOF map as
dofs.csv, constrained DOFs removed: the case reads them with model.type
matrices and needs no OpenSees. Truth: each group's stiffness times 1 + alpha_r,
alpha_r from U(-0.15, 0.15) by the seed; Rayleigh damping, 2 % at the 1st and
12th modes. Data: accelerances of ux and uy at two opposite corners of floors
6 and 10 and one corner of floor 3 (10 channels) to a force in x at a roof
corner, 0.3-12 Hz log-spaced, with 2 % complex Gaussian noise. With Rayleigh
damping the sum over all 2,100 undamped modes is the exact FRF; it is written
here (not the package's FRF code) and checked against sparse direct solves of
(K - w^2 M + jwC) q = b (nlp/testing/sparse_sim.py) at a few frequencies.

    python scripts/make_frame3d.py [--seed 0] [--noise 0.02] [--out DIR]
"""

import os

import numpy as np
import scipy.io
import scipy.linalg as sla
import scipy.sparse as sp

from nlp.io.importers.opensees import assemble_script
from nlp.testing.sparse_sim import add_noise, frf_sparse, generator_args, write_case
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "frame3d_2100")
STOREYS = 10
GROUPS = {**{f"k_col{s}": f"columns_story{s}" for s in range(1, STOREYS + 1)},
          **{f"k_bx{a}_{a + 1}": f"beams_x_story{a}_{a + 1}" for a in range(1, STOREYS, 2)},
          **{f"k_by{a}_{a + 1}": f"beams_y_story{a}_{a + 1}" for a in range(1, STOREYS, 2)}}
CORNER_A, CORNER_B = (0, 0), (6, 4)
SENSORS = [(fl, c, d) for fl, corners in ((3, (CORNER_A,)), (6, (CORNER_A, CORNER_B)),
                                          (10, (CORNER_A, CORNER_B)))
           for c in corners for d in ("ux", "uy")]
FORCE = (10, CORNER_B, "ux")
DOF_NUMBER = {"ux": 1, "uy": 2}


def node(floor, corner):
    return 10000 * floor + 100 * corner[0] + corner[1]


def export(a, out):
    """Matrix files of the case: M.mtx, K.mtx, groups/<name>.npz, dofs.csv."""
    os.makedirs(os.path.join(out, "groups"), exist_ok=True)
    for name, A in (("M", a["M0"]), ("K", a["K0"])):
        S = sp.csc_matrix(np.where(np.abs(A) > 1e-12 * np.abs(A).max(), 0.5 * (A + A.T), 0.0))
        scipy.io.mmwrite(os.path.join(out, f"{name}.mtx"), S, symmetry="symmetric",
                         comment=f"frame3d_2100 {name}0, constrained DOFs removed; rows: dofs.csv")
    for name, A in zip(GROUPS, a["K_infl"]):
        S = sp.csc_matrix(np.where(np.abs(A) > 1e-12 * np.abs(A).max(), 0.5 * (A + A.T), 0.0))
        sp.save_npz(os.path.join(out, "groups", f"{name}.npz"), S)
    labels = ("ux", "uy", "uz", "rx", "ry", "rz")
    with open(os.path.join(out, "dofs.csv"), "w") as fh:
        fh.write("node,dof\n" + "".join(f"{nd},{labels[d - 1]}\n" for nd, d in a["dofs"]))


def frf_all_modes(M, K, a0, a1, b, rows, f):
    """Accelerances -w^2 sum_i phi_i phi_i^T b / (w_i^2 - w^2 + jw (a0 + a1 w_i^2)), all modes."""
    w2, Phi = sla.eigh(K, M)  # mass-normalised
    part = Phi[rows] * (Phi.T @ b)  # (n_rows, n_modes)
    w = 2 * np.pi * np.asarray(f)
    den = w2[:, None] - w[None] ** 2 + 1j * w[None] * (a0 + a1 * w2[:, None])
    return -(w**2) * (part @ (1.0 / den)), np.sqrt(w2) / (2 * np.pi)


def make(seed=0, noise=0.02, out=CASE):
    a = assemble_script(os.path.join(CASE, "frame3d.py"), GROUPS)
    export(a, out)
    M, dofs = sp.csc_matrix(a["M0"]), a["dofs"]
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(-0.15, 0.15, len(GROUPS))
    K = sp.csc_matrix(a["K0"] + sum(al * Kr for al, Kr in zip(alpha, a["K_infl"])))
    Kd = a["K0"] + sum(al * Kr for al, Kr in zip(alpha, a["K_infl"]))
    Md = a["M0"]
    w2 = sla.eigh(Kd, Md, eigvals_only=True, subset_by_index=[0, 29])
    w1, w12 = np.sqrt(w2[0]), np.sqrt(w2[11])
    zeta = 0.02
    a1 = 2 * zeta / (w1 + w12)
    a0 = a1 * w1 * w12
    f = np.geomspace(0.3, 12.0, int(np.log(40) / (0.2 * zeta)) + 1)
    rows = [dofs.index((node(fl, c), DOF_NUMBER[d])) for fl, c, d in SENSORS]
    b = np.zeros(len(dofs))
    b[dofs.index((node(FORCE[0], FORCE[1]), DOF_NUMBER[FORCE[2]]))] = 1.0
    H, fn = frf_all_modes(Md, Kd, a0, a1, b, rows, f)
    check = np.array([0, f.size // 3, f.size - 1])
    Hs = frf_sparse(M, K, a0 * M + a1 * K, b, rows, f[check], power=2)
    err = np.abs(Hs - H[:, check]).max() / np.abs(Hs).max()
    if err > 1e-8:
        raise RuntimeError(f"modal sum and sparse solve differ by {err:.1e}")
    fn = fn[:30]
    H = add_noise(H, noise, rng)
    truth = {"alpha": dict(zip(GROUPS, alpha.tolist())), "a0": a0, "a1": a1,
             "natural_frequencies_hz": fn.tolist(), "n_dof": len(dofs), "seed": seed,
             "noise": noise}
    a1_0 = 2 * 0.03 / (w1 + w12)
    case = {
        "name": "frame3d_2100",
        "description": "3-D steel moment frame, 10 storeys on a 7 x 5 grid, 2,100 DOFs exported "
                       "from OpenSees as matrix files; force at a roof corner, accelerances at "
                       "10 DOFs; 20 element-group stiffnesses",
        "model": {"type": "matrices", "M": "M.mtx", "K": "K.mtx", "dof_map": "dofs.csv",
                  "stiffness_groups": {g: f"groups/{g}.npz" for g in GROUPS}},
        "parameters": {"stiffness_bounds": [-0.5, 1.0]},
        "damping": {"model": "rayleigh", "a0": float(a1_0 * w1 * w12), "a1": float(a1_0)},
        "excitation": {"type": "force", "node": node(FORCE[0], FORCE[1]), "dof": FORCE[2]},
        "data": {"file": "frf.npz", "window": "none", "channels": [
            {"name": f"f{fl}{'a' if c == CORNER_A else 'b'}_{d}", "node": node(fl, c), "dof": d,
             "output": "accelerance", "column": i} for i, (fl, c, d) in enumerate(SENSORS)]},
        # every point of 0.5-12 Hz: the half-power windows find only the 12 modes below 7 Hz,
        # too few for 10 storeys (predicted standard errors up to 5.5 % instead of 0.4 %)
        "frequencies": {"method": "all", "fmin": 0.5, "fmax": 12.0},
        "objective": {"residual": "log_magnitude"},
        "search": {"starts": 2, "seed": 0},
    }
    return f, H, truth, case


def main():
    a = generator_args(__doc__, CASE)
    f, H, truth, case = make(a.seed, a.noise, a.out)
    write_case(a.out, f, H, truth, case)
    print(f"wrote {a.out}: {H.shape[0]} channels x {f.size} points, {truth['n_dof']} DOFs, "
          f"{len(GROUPS)} groups; modes {np.round(truth['natural_frequencies_hz'][:12], 2)} Hz")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
