"""Plant an effect in the OpenSeesPy model of a matrix-file FE case and simulate it (issue 46).

``scripts/make_planted_fe.py`` plants by editing the exported matrices. Here the planted
structure is an OpenSees model: the case's own model script plus the effect written as
OpenSees commands, assembled by OpenSees (``GimmeMCK``, as the case's matrices were), so the
data do not come from our matrix edits. The edits are the check: both routes must give the
same FRF.

* ``mass``: ``dm`` [kg] added to the node's three translational masses (``ops.mass``).
* ``appendage``: a new node on a ``zeroLength`` spring k_s = m_s (2 pi f_s)^2 along ``--dof``,
  mass m_s; its dashpot c_s = 2 zeta_s sqrt(k_s m_s) and the frame's Rayleigh damping
  (a0 M + a1 K of the frame alone), as in ``make_planted_fe.py``.
* ``support``: the column bases released along ``--dof`` (``remove sp``), their masses moved
  to a foundation node of mass m_b on a ``zeroLength`` spring k_b to the ground, each base tied
  to it by a ``zeroLength`` link TIE_RATIO times k_b (a stiff grade beam: the ties' compliance
  is the only difference from the rigid base of the matrix route); Rayleigh damping of the
  whole planted model, as OpenSees' ``rayleigh`` applies it.

The truth's group scalings (``truth.json``: alpha) act on the groups OpenSees assembles in
the planted model; each frequency is a sparse direct solve (``nlp.testing.sparse_sim``, not
the package's FRF code), then the case's noise with a new seed.

    python scripts/make_planted_opensees.py --case cases/frame3d_2100/case.yaml --out DIR \\
        --plant support --dof ux --kg 30000 --kb 1.24e9 [--seed 1]
"""

import os
import tempfile

import numpy as np
import scipy.sparse as sp

from make_frame3d import GROUPS as FRAME3D_GROUPS
from make_planted_fe import (LABELS, POWER, modal_sum, modes, plant_args, plant_mass,
                             plant_support, planted_frf, read_case, row, write_planted)
from nlp.io.importers.opensees import assemble_script
from nlp.testing.sparse_sim import add_noise, frf_sparse

TIE_RATIO = 1.0e4      # link stiffness over k_b: the grade beam is four orders stiffer
MATERIAL = 900001      # uniaxial material tags of the plant, above any the model script uses


def plant_commands(plant, node, dof, kg, kb=None, hz=None):
    """Python lines that add the plant to the model the script built (OpenSees commands)."""
    d = LABELS[dof]
    free = ", ".join("0" if i == d else "1" for i in range(1, 7))
    only = ", ".join(f"{kg!r}" if i == d else "0.0" for i in range(1, 7))
    if plant == "mass":
        return [f"m = ops.nodeMass({node})",
                f"ops.mass({node}, *[v + ({kg!r} if i < 3 else 0.0) for i, v in enumerate(m)])"]
    if plant == "appendage":
        k_s = kg * (2 * np.pi * hz) ** 2
        return ["a = max(ops.getNodeTags()) + 1",
                f"ops.node(a, *ops.nodeCoord({node}))", f"ops.fix(a, {free})",
                f"ops.mass(a, {only})",
                f"ops.uniaxialMaterial('Elastic', {MATERIAL}, {k_s!r})",
                f"ops.element('zeroLength', max(ops.getEleTags()) + 1, {node}, a, "
                f"'-mat', {MATERIAL}, '-dir', {d})"]
    return ["nodes = ops.getNodeTags()",
            "z0 = min(ops.nodeCoord(n)[-1] for n in nodes)",
            "base = [n for n in nodes if abs(ops.nodeCoord(n)[-1] - z0) < 1e-9]",
            "centre = np.mean([ops.nodeCoord(n) for n in base], axis=0)",
            "b, g = max(nodes) + 1, max(nodes) + 2",
            "ops.node(b, *centre); ops.node(g, *centre)",
            f"ops.fix(b, {free}); ops.fix(g, 1, 1, 1, 1, 1, 1); ops.mass(b, {only})",
            f"ops.uniaxialMaterial('Elastic', {MATERIAL}, {kb!r})",
            f"ops.uniaxialMaterial('Elastic', {MATERIAL + 1}, {TIE_RATIO * kb!r})",
            f"ops.element('zeroLength', max(ops.getEleTags()) + 1, g, b, '-mat', {MATERIAL}, "
            f"'-dir', {d})",
            "for n in base:",
            f"    ops.remove('sp', n, {d})",
            "    ops.mass(n, *([0.0] * 6))",
            f"    ops.element('zeroLength', max(ops.getEleTags()) + 1, n, b, '-mat', "
            f"{MATERIAL + 1}, '-dir', {d})"]


def assemble_planted(script, groups, lines):
    """OpenSees' M, K0 and group matrices of the script's model with the plant added."""
    with tempfile.TemporaryDirectory() as tmp:
        wrapper = os.path.join(tmp, "planted.py")
        with open(wrapper, "w") as fh:
            fh.write("import runpy\nimport numpy as np\nimport openseespy.opensees as ops\n"
                     f"groups = runpy.run_path({script!r}, run_name='__frf_nlp__')['groups']\n"
                     + "\n".join(lines) + "\n")
        return assemble_script(wrapper, groups)


def main():
    a = plant_args(__doc__, ("ux", "uy", "uz"), script=True)
    here, case, truth, M, K, a0, a1, dofs = read_case(a.case)
    script = a.script or os.path.join(here, "frame3d.py")
    groups = {g: FRAME3D_GROUPS[g] for g in case["model"]["stiffness_groups"]}
    f = np.load(os.path.join(here, case["data"]["file"]))["f"]
    ex, chans = case["excitation"], case["data"]["channels"]
    if ex.get("type") != "force":
        raise SystemExit(f"{a.case}: excitation.type: force input expected")
    power = {POWER[c.get("output", "accelerance")] for c in chans}
    if len(power) != 1:
        raise SystemExit(f"{a.case}: data.channels: one output type expected")
    power = power.pop()

    print(f"assembling the planted model with OpenSees ({a.plant})", flush=True)
    asm = assemble_planted(os.path.abspath(script), groups,
                           plant_commands(a.plant, a.node, a.dof, a.kg, a.kb, a.hz))
    pd = list(asm["dofs"])
    Kp = asm["K0"] + sum(truth["alpha"][g] * Kr for g, Kr in zip(groups, asm["K_infl"]))
    Mp = asm["M0"]
    Mp, Kp = sp.csc_matrix(0.5 * (Mp + Mp.T)), sp.csc_matrix(0.5 * (Kp + Kp.T))
    n_new = len(pd) - len(dofs)
    rows = [pd.index((int(c["node"]), LABELS[c["dof"]])) for c in chans]
    bp = np.zeros(len(pd))
    bp[pd.index((int(ex["node"]), LABELS[ex["dof"]]))] = 1.0
    if a.plant == "appendage":
        k_s = a.kg * (2 * np.pi * a.hz) ** 2
        c_s = 2 * a.zeta * np.sqrt(k_s * a.kg)
        old = set(dofs)
        p = pd.index((a.node, LABELS[a.dof]))
        q = next(i for i, d in enumerate(pd) if d not in old)    # the appendage's one DOF
        e = sp.csc_matrix(([1.0, -1.0], ([p, q], [0, 0])), shape=(len(pd), 1))
        mq = sp.csc_matrix(([a.kg], ([q], [q])), shape=Mp.shape)
        Cp = a0 * (Mp - mq) + a1 * (Kp - k_s * (e @ e.T)) + c_s * (e @ e.T)
        planted = {"family": "secondary_oscillator", "node": a.node, "dof": a.dof, "m_s": a.kg,
                   "f_s_hz": a.hz, "zeta_s": a.zeta, "k_s": k_s, "c_s": c_s}
    else:
        Cp = a0 * Mp + a1 * Kp
        planted = ({"family": "added_mass", "node": a.node, "dm": a.kg,
                    "dofs": ["ux", "uy", "uz"]} if a.plant == "mass" else
                   {"family": "base_flexibility", "direction": a.dof, "m_base": a.kg,
                    "k_b": a.kb, "tie_stiffness_each": TIE_RATIO * a.kb})
    print(f"planted model: {len(pd)} DOFs ({n_new:+d}); solving {f.size} frequencies", flush=True)
    H = frf_sparse(Mp, Kp, sp.csc_matrix(Cp), bp, rows, f, power=power)

    # the check: the same plant as edits of the exported matrices (make_planted_fe.py)
    n = M.shape[0]
    b = np.zeros(n)
    b[row(dofs, int(ex["node"]), ex["dof"])] = 1.0
    rws = [row(dofs, int(c["node"]), c["dof"]) for c in chans]
    frame = modes(M, K)
    app = None
    if a.plant == "mass":
        Mq, Kq, bq = plant_mass(M, dofs, a.node, a.kg)[0], K, b
    elif a.plant == "support":
        Mq, Kq, _ = plant_support(M, K, dofs, a.dof, a.kg, a.kb)
        bq = np.append(b, 0.0)
    else:
        Mq = Kq = bq = None
        app = (row(dofs, a.node, a.dof), a.kg, k_s, c_s)
    H_np = planted_frf(frame, a0, a1, b, rws, f, power, Mq, Kq, bq, app)
    diff = float(np.abs(H - H_np).max() / np.abs(H_np).max())
    limit = 1e-6 if a.plant != "support" else 10.0 / TIE_RATIO
    if diff > limit:
        raise SystemExit(f"OpenSees model and matrix edits differ by {diff:.1e} (limit {limit:.0e})")
    H0 = modal_sum(*frame, a0, a1, b, rws, f, power)
    change = np.abs(np.log(np.abs(H / H0)))
    noise = float(truth.get("noise", 0.02))
    Hn = add_noise(H, noise, np.random.default_rng(a.seed))
    out_truth = {**truth, "seed": a.seed, "planted": planted,
                 "simulator": "OpenSeesPy assembly of the planted model, sparse direct solves",
                 "matrix_edit_rel_difference": diff, "largest_log_change": float(change.max()),
                 "points_changed_over_noise": int((change > noise).sum())}
    write_planted(a, here, case, f, Hn, out_truth, "scripts/make_planted_opensees.py")
    print(f"wrote {a.out}: {a.plant}; OpenSees model vs matrix edits {diff:.1e}; largest "
          f"|ln H'/H| {change.max():.3f}, {(change > noise).sum()} of {change.size} values "
          f"changed by more than the noise ({noise})")


if __name__ == "__main__":
    main()
