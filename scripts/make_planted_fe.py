"""Plant a known effect in a matrix-file FE case and simulate it afresh (issue 46).

The structure is the case's truth (``truth.json``: the groups' alpha and the Rayleigh
a0, a1) plus one planted effect; the nominal model the case updates from is unchanged, so
``frf-nlp diagnose OUT/case.yaml`` must find the effect as missing physics. Effects:

* ``appendage``: a mass m_s [kg] on a spring k_s = m_s (2 pi f_s)^2 and a dashpot
  c_s = 2 zeta_s sqrt(k_s m_s) hanging from one DOF (an extra DOF, as a rooftop unit on
  isolators, or an OpenSees zeroLength element to a new node). The frame keeps its Rayleigh
  damping; the appendage has only its own dashpot, so the damping is not classical and the
  FRF is solved per frequency.
* ``mass``: a lumped mass dm [kg] at one node, on each of its translations (ux, uy, uz), as
  OpenSees' ``mass`` command adds it; Rayleigh damping of the whole planted model, as an FE
  program applies it.
* ``support``: flexible supports, every support moving with one base DOF u_b along ``--dof``
  (a foundation of mass m_b [kg] on a sway spring k_b [N/m] to the ground, as soil under a
  mat). The matrix files have the supports' DOFs removed, so the structure's forces on them
  are -K r per unit support translation, r the rigid translation (1 on every ``--dof``
  row): in absolute coordinates K' = [[K, -K r], [-r^T K, r^T K r + k_b]], M' = diag(M, m_b),
  and Rayleigh damping over the whole planted model.

Data are simulated by sparse direct solves of the planted model
(``nlp.testing.sparse_sim``, written apart from the package's FRF code), checked against a
sum over all modes of the planted model with Rayleigh damping (the appendage's dashpot then
replaced by the law) at a few frequencies, and get the case's noise with a new seed. The
frequencies, channels and excitation are the case's own.

    python scripts/make_planted_fe.py --case cases/frame3d_2100/case.yaml --out DIR \\
        --plant appendage --node 100604 --dof ux --kg 2000 --hz 2.10 [--zeta 0.02] [--seed 1]
    python scripts/make_planted_fe.py --case ... --out DIR --plant mass --node 60604 --kg 20000
    python scripts/make_planted_fe.py --case ... --out DIR --plant support --dof ux --kg 30000 \
        --kb 1.24e9
"""

import argparse
import csv
import json
import os
import shutil

import numpy as np
import scipy.io
import scipy.linalg as sla
import scipy.sparse as sp
import yaml

from nlp.testing.plant import appendage_z, attach_transfer
from nlp.testing.sparse_sim import add_noise, frf_sparse, write_case

LABELS = {"ux": 1, "uy": 2, "uz": 3, "rx": 4, "ry": 5, "rz": 6}
POWER = {"receptance": 0, "mobility": 1, "accelerance": 2}


def read_case(path):
    """The case's matrices with its truth applied: M, K (sparse), a0, a1, dofs, case dict."""
    here = os.path.dirname(os.path.abspath(path))
    case = yaml.safe_load(open(path))
    m = case["model"]
    if m.get("type") != "matrices":
        raise SystemExit(f"{path}: model.type: this script plants in matrix-file cases only")
    truth = json.load(open(os.path.join(here, "truth.json")))
    M = scipy.io.mmread(os.path.join(here, m["M"])).tocsc()
    K = scipy.io.mmread(os.path.join(here, m["K"])).tocsc()
    for g, a in truth["alpha"].items():
        K = K + a * sp.load_npz(os.path.join(here, m["stiffness_groups"][g]))
    dofs = [(int(r["node"]), LABELS[r["dof"]] if r["dof"] in LABELS else int(r["dof"]))
            for r in csv.DictReader(open(os.path.join(here, m["dof_map"])))]
    return here, case, truth, sp.csc_matrix(M), sp.csc_matrix(K), truth["a0"], truth["a1"], dofs


def row(dofs, node, dof):
    try:
        return dofs.index((node, LABELS[dof]))
    except (ValueError, KeyError):
        raise SystemExit(f"node {node} has no DOF {dof} in the case's dof map") from None


def plant_appendage(M, K, a0, a1, p, m_s, f_s, zeta):
    """Bordered M, K, C with the appendage's DOF last: C = a0 M + a1 K on the frame only."""
    n = M.shape[0]
    k_s = m_s * (2 * np.pi * f_s) ** 2
    c_s = 2 * zeta * np.sqrt(k_s * m_s)
    e = sp.csc_matrix(([1.0, -1.0], ([p, n], [0, 0])), shape=(n + 1, 1))
    pad = lambda A: sp.bmat([[A, None], [None, sp.csc_matrix((1, 1))]], format="csc")  # noqa: E731
    Mp = pad(M) + sp.csc_matrix(([m_s], ([n], [n])), shape=(n + 1, n + 1))
    Kp = pad(K) + k_s * (e @ e.T)
    Cp = pad(a0 * M + a1 * K) + c_s * (e @ e.T)
    return Mp.tocsc(), Kp.tocsc(), Cp.tocsc(), {"k_s": k_s, "c_s": c_s}


def plant_mass(M, dofs, node, dm):
    """M plus dm on every translation of ``node``."""
    rows = [i for i, (nd, d) in enumerate(dofs) if nd == node and d <= 3]
    if not rows:
        raise SystemExit(f"node {node} has no translational DOF in the case's dof map")
    return (M + sp.csc_matrix((np.full(len(rows), dm), (rows, rows)), shape=M.shape)).tocsc(), rows


def plant_support(M, K, dofs, dof, m_b, k_b):
    """M', K' with the base DOF last (module docstring) and the rigid translation r."""
    n = M.shape[0]
    r = np.array([1.0 if d == LABELS[dof] else 0.0 for _, d in dofs])
    Kr = sp.csc_matrix(K @ r).reshape(n, 1)
    Kp = sp.bmat([[K, -Kr], [-Kr.T, sp.csc_matrix([[r @ (K @ r) + k_b]])]], format="csc")
    Mp = sp.bmat([[M, None], [None, sp.csc_matrix([[m_b]])]], format="csc")
    return Mp, Kp, r


def modes(M, K):
    """Undamped modes of (K, M), mass-normalised: (w_i^2, Phi)."""
    return sla.eigh(K.toarray(), M.toarray())


def modal_sum(w2, Phi, a0, a1, b, rows, f, power):
    """(jw)^power sum over all modes of phi phi^T b / (w_i^2 - w^2 + jw (a0 + a1 w_i^2))."""
    part = Phi[rows] * (Phi.T @ b)
    w = 2 * np.pi * np.asarray(f)
    den = w2[:, None] - w[None] ** 2 + 1j * w[None] * (a0 + a1 * w2[:, None])
    return (1j * w[None]) ** power * (part @ (1.0 / den))


def planted_frf(frame, a0, a1, b, rows, f, power, Mp, Kp, bp, appendage=None):
    """FRFs of the planted model from modes. An appendage (p, m_s, k_s, c_s) on row p of the
    frame (its own dashpot: not classical) by exact substructuring of the frame's all-mode
    receptances ``frame`` = modes(M, K); any other plant from the planted model's own modes
    (Rayleigh over it: classical)."""
    if appendage is None:
        return modal_sum(*modes(Mp, Kp), a0, a1, bp, rows, f, power)
    p, m_s, k_s, c_s = appendage
    w = 2 * np.pi * np.asarray(f)
    ep = np.zeros(len(b))
    ep[p] = 1.0
    R = modal_sum(*frame, a0, a1, b, rows + [p], f, 0)
    R_rp = modal_sum(*frame, a0, a1, ep, rows + [p], f, 0)
    z = appendage_z(w, m_s, k_s, c_s)
    return (1j * w[None]) ** power * attach_transfer(R[:-1], R_rp[:-1], R[-1], R_rp[-1], z)


def plant_args(doc, dof_choices, script=False):
    """The command line of a planting script, checked: --case, --out, --plant and its sizes."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--case", required=True)
    if script:
        ap.add_argument("--script", help="the case's OpenSeesPy model script "
                                         "(default: frame3d.py beside the case)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--plant", choices=("appendage", "mass", "support"), required=True)
    ap.add_argument("--node", type=int, help="the node of an appendage or a mass")
    ap.add_argument("--dof", default="ux", choices=dof_choices)
    ap.add_argument("--kg", type=float, required=True, help="appendage, added or base mass [kg]")
    ap.add_argument("--kb", type=float, help="the supports' sway stiffness k_b [N/m]")
    ap.add_argument("--hz", type=float, help="appendage's own frequency f_s [Hz]")
    ap.add_argument("--zeta", type=float, default=0.02, help="appendage's damping ratio")
    ap.add_argument("--seed", type=int, default=1, help="noise seed (the case's was 0)")
    a = ap.parse_args()
    if a.plant == "appendage" and not a.hz:
        ap.error("--plant appendage needs --hz")
    if a.plant == "support" and not a.kb:
        ap.error("--plant support needs --kb")
    if a.plant != "support" and a.node is None:
        ap.error(f"--plant {a.plant} needs --node")
    return a


def write_planted(a, here, case, f, H, truth, by):
    """The planted case in a.out: the source case's matrix files, its data and truth."""
    case = {**case, "name": f"{case['name']}_planted_{a.plant}",
            "description": f"{case['name']} with a planted {a.plant} ({by})"}
    os.makedirs(a.out, exist_ok=True)
    m = case["model"]
    for rel in [m["M"], m["K"], m["dof_map"], *m["stiffness_groups"].values()]:
        os.makedirs(os.path.dirname(os.path.join(a.out, rel)) or a.out, exist_ok=True)
        shutil.copy(os.path.join(here, rel), os.path.join(a.out, rel))
    write_case(a.out, f, H, truth, case)


def main():
    a = plant_args(__doc__, sorted(LABELS))
    here, case, truth, M, K, a0, a1, dofs = read_case(a.case)
    f = np.load(os.path.join(here, case["data"]["file"]))["f"]
    ex = case["excitation"]
    if ex.get("type") != "force":
        raise SystemExit(f"{a.case}: excitation.type: force input expected")
    n = M.shape[0]
    b = np.zeros(n)
    b[row(dofs, int(ex["node"]), ex["dof"])] = 1.0
    chans = case["data"]["channels"]
    power = {POWER[c.get("output", "accelerance")] for c in chans}
    if len(power) != 1:
        raise SystemExit(f"{a.case}: data.channels: one output type expected")
    power = power.pop()
    rows = [row(dofs, int(c["node"]), c["dof"]) for c in chans]
    if a.plant == "appendage":
        p = row(dofs, a.node, a.dof)
        Mp, Kp, Cp, extra = plant_appendage(M, K, a0, a1, p, a.kg, a.hz, a.zeta)
        bp = np.append(b, 0.0)
        planted = {"family": "secondary_oscillator", "node": a.node, "dof": a.dof, "m_s": a.kg,
                   "f_s_hz": a.hz, "zeta_s": a.zeta, **extra,
                   "mass_ratio_to_dof_mass": a.kg / M[p, p]}
    elif a.plant == "support":
        Mp, Kp, r = plant_support(M, K, dofs, a.dof, a.kg, a.kb)
        Cp, bp = a0 * Mp + a1 * Kp, np.append(b, 0.0)
        planted = {"family": "base_flexibility", "direction": a.dof, "m_base": a.kg, "k_b": a.kb,
                   "rigid_stiffness_rKr": float(r @ (K @ r)),
                   "sway_hz_on_the_spring": float(np.sqrt(a.kb / (r @ (M @ r) + a.kg))
                                                  / (2 * np.pi))}
    else:
        Mp, mrows = plant_mass(M, dofs, a.node, a.kg)
        Kp, Cp, bp = K, a0 * Mp + a1 * K, b
        planted = {"family": "added_mass", "node": a.node, "dofs": [dofs[i][1] for i in mrows],
                   "dm": a.kg, "mass_ratio_to_dof_mass": a.kg / M[mrows[0], mrows[0]]}
    frame = modes(M, K)
    H = planted_frf(frame, a0, a1, b, rows, f, power, Mp, Kp, bp,
                    (p, a.kg, extra["k_s"], extra["c_s"]) if a.plant == "appendage" else None)
    H0 = modal_sum(*frame, a0, a1, b, rows, f, power)
    # checked against sparse direct solves of the planted model itself at a few frequencies
    check = np.array([0, f.size // 3, 2 * f.size // 3, f.size - 1])
    Hs = frf_sparse(Mp, Kp, Cp, bp, rows, f[check], power=power)
    err = np.abs(Hs - H[:, check]).max() / np.abs(Hs).max()
    if err > 1e-8:
        raise SystemExit(f"sparse solve and modal sum of the planted model differ by {err:.1e}")
    change = np.abs(np.log(np.abs(H / H0)))
    rng = np.random.default_rng(a.seed)
    noise = float(truth.get("noise", 0.02))
    Hn = add_noise(H, noise, rng)
    out_truth = {**truth, "seed": a.seed, "planted": planted, "check_rel_error": float(err),
                 "largest_log_change": float(change.max()),
                 "points_changed_over_noise": int((change > noise).sum())}
    write_planted(a, here, case, f, Hn, out_truth, "scripts/make_planted_fe.py")
    where = f"at node {a.node}" if a.node is not None else f"under the supports along {a.dof}"
    print(f"wrote {a.out}: {a.plant} {where}; check {err:.1e}; largest |ln H'/H| "
          f"{change.max():.3f}, {(change > noise).sum()} of {change.size} values changed by "
          f"more than the noise ({noise})")


if __name__ == "__main__":
    main()
