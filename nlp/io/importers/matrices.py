"""Models from exported matrices: MAT, NPZ and Matrix Market (.mtx) files.

FE programs export the assembled mass and stiffness matrices (ABAQUS
``*MATRIX GENERATE``, ANSYS ``HBMAT``/``*SMAT``, SAP2000 ``.TXK``/``.TXM``
converted to Matrix Market, ...), usually with the constrained DOFs removed and
a table saying which node and DOF each row is. A case names

* ``M`` and ``K``: the nominal matrices M0, K0 [kg, N/m];
* ``stiffness_groups`` / ``mass_groups``: one file per updating parameter with
  that group's nominal contribution K0_r (M0_r), so K = K0 + sum alpha_r K0_r
  (Eqns 23-24);
* ``dof_map``: the (node, dof) of every row (CSV ``node,dof`` or an (n, 2)
  array); without it rows are named ``dof1..dofn`` and channels use ``floor``;
* ``constrained``: (node, dof) pairs to remove, when the export kept them.

Everything is stored sparse (CSC). The older single-file form (``file:`` with
M0, K0, M_infl, K_infl arrays in one NPZ/MAT) is read by :func:`load_bundle`.
"""

import csv
import os

import numpy as np
import scipy.io
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from nlp.case.checks import check_model_matrices
from nlp.errors import InputError
from nlp.model.nominal import StructuralModel
from nlp.io.importers.dofs import dof_number

__all__ = ["read_matrix", "read_dof_map", "load_matrices", "load_bundle", "check_mass"]


def read_matrix(path, key=None):
    """One matrix from a .mtx, .npz or .mat file as ``scipy.sparse.csc_matrix``.

    key : array name inside an NPZ/MAT file holding several (default: its only
    array, or a ``scipy.sparse.save_npz`` file). Raises InputError(path, key).
    """
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".mtx":
            A = scipy.io.mmread(path)
        elif ext == ".npz":
            with np.load(path, allow_pickle=False) as z:
                names = list(z.files)
                if key is None and {"indptr", "indices", "data", "shape", "format"} <= set(names):
                    A = None
                else:
                    A = _pick(z, names, key, path)
            if A is None:
                A = sp.load_npz(path)
        elif ext == ".mat":
            raw = scipy.io.loadmat(path)
            A = _pick(raw, [k for k in raw if not k.startswith("__")], key, path)
        else:
            raise InputError(path, "<file>", "a matrix file ending in .mtx, .npz or .mat")
    except InputError:
        raise
    except Exception as exc:  # unreadable or malformed: a user mistake
        raise InputError(path, key or "<file>", f"a readable matrix file ({exc})") from None
    A = sp.csc_matrix(A, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise InputError(path, key or "<matrix>", "a square matrix", f"shape {A.shape}")
    if not np.all(np.isfinite(A.data)):
        raise InputError(path, key or "<matrix>", "finite entries")
    return A


def _pick(store, names, key, path):
    if key is None:
        if len(names) != 1:
            raise InputError(path, "<key>", f"a key naming one of the arrays {names}")
        key = names[0]
    if key not in names:
        raise InputError(path, key, f"an array of that name; the file has {names}")
    return store[key]


def read_dof_map(path, n=None, ndf=None, ndm=None):
    """The (node, dof) of each matrix row, from a CSV (header ``node,dof``) or an (n, 2) array.

    dof may be a number (1-based) or a name (ux, uy, uz, rx, ry, rz).
    Returns a tuple of (int node, int dof) pairs.
    """
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext in (".npz", ".mat"):
            raw = dict(np.load(path)) if ext == ".npz" else scipy.io.loadmat(path)
            arr = _pick(raw, [k for k in raw if not k.startswith("__")],
                        "dofs" if "dofs" in raw else None, path)
            rows = [(r[0], r[1]) for r in np.asarray(arr).reshape(-1, 2)]
        else:
            with open(path, newline="") as fh:
                rd = csv.reader(fh)
                head = [h.strip().lower() for h in next(rd)]
                if head[:2] != ["node", "dof"]:
                    raise InputError(path, "<header>", "a CSV header 'node,dof'", ",".join(head))
                rows = [(r[0].strip(), r[1].strip()) for r in rd if r and r[0].strip()]
    except InputError:
        raise
    except Exception as exc:
        raise InputError(path, "<file>", f"a readable node-to-DOF map ({exc})") from None
    out = []
    numeric = [_as_int(d) for _, d in rows]
    named = {str(d).strip().lower() for (_, d), v in zip(rows, numeric) if v is None}
    # names only: a 2-D frame (ux, uy, rz = 1, 2, 3) unless a 3-D name appears
    ndf = ndf or max([d for d in numeric if d is not None]
                     + [6 if named & {"uz", "rx", "ry"} or ndm == 3 else 3])
    for i, (node, d) in enumerate(rows):
        try:
            nd = int(float(node))
        except ValueError:
            raise InputError(path, f"row {i + 1}.node", "an integer node tag", node) from None
        num = numeric[i] if numeric[i] is not None else dof_number(str(d), 6 if ndf > 3 else ndf, ndm)
        if num is None or not 1 <= num <= 6:
            raise InputError(path, f"row {i + 1}.dof", "a DOF number 1-6 or a name ux..rz", d)
        out.append((nd, num))
    if len(set(out)) != len(out):
        raise InputError(path, "<rows>", "each (node, dof) once")
    if n is not None and len(out) != n:
        raise InputError(path, "<rows>", f"one row per matrix row ({n})", f"{len(out)} rows")
    return tuple(out)


def _as_int(v):
    try:
        f = float(v)
    except ValueError:
        return None
    return int(f) if f == int(f) else None


def check_mass(M, path, key):
    """Raise InputError unless M is symmetric positive definite (a massless DOF is not).

    Sparse M: the pivots of an LDL^T-like factorisation with a symmetric ordering and no
    pivoting count the negative and zero eigenvalues (Sylvester's law of inertia).
    """
    if sp.issparse(M):
        Ms = sp.csc_matrix(0.5 * (M + M.T))
        try:
            lu = spla.splu(Ms, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
            ok = np.all(lu.U.diagonal() > 0) and np.all(lu.perm_r == lu.perm_c)
        except RuntimeError:  # exactly singular
            ok = False
    else:
        Md = np.asarray(M)
        try:
            sla.cholesky(0.5 * (Md + Md.T), lower=True)
            ok = True
        except np.linalg.LinAlgError:
            ok = False
    if not ok:
        raise InputError(path, key, "a symmetric positive definite mass matrix (give every DOF "
                         "some mass, e.g. rotational inertia, or condense massless DOFs out)")


def _symmetric(A, path, key):
    scale = abs(A).max() if A.nnz else 1.0
    if scale and abs(A - A.T).max() > 1e-9 * scale:
        raise InputError(path, key, "a symmetric matrix")


def _file(spec):
    """(path, key) of a matrix spec: a path string or {file, key}."""
    return (spec["file"], spec.get("key")) if isinstance(spec, dict) else (spec, None)


def load_matrices(cfg, case_path):
    """StructuralModel from separate matrix files named in the case (see module docstring).

    cfg : nlp.case.schema.ModelConfig with M, K, stiffness_groups, mass_groups,
    dof_map, constrained (paths already absolute).
    """
    if cfg.file is not None:
        return load_bundle(cfg.file)
    mats = {}
    for key, spec in (("M", cfg.M), ("K", cfg.K)):
        path, k = _file(spec)
        mats[key] = read_matrix(path, k)
        _symmetric(mats[key], path, k or key)
    n_full = mats["K"].shape[0]
    groups = {}
    for section, specs in (("stiffness_groups", cfg.stiffness_groups),
                           ("mass_groups", cfg.mass_groups)):
        for name, spec in specs.items():
            path, k = _file(spec)
            A = read_matrix(path, k)
            _symmetric(A, path, k or name)
            groups[(section, name)] = A
    for (section, name), A in [(("model.M", "M"), mats["M"])] + list(groups.items()):
        if A.shape[0] != n_full:
            key = f"model.{section}.{name}" if section != "model.M" else "model.M"
            raise InputError(case_path, key, f"a {n_full} x {n_full} matrix like model.K",
                             f"shape {A.shape}")
    dofs = read_dof_map(cfg.dof_map, n_full, ndm=cfg.ndm) if cfg.dof_map else ()
    keep = np.arange(n_full)
    if cfg.constrained:
        if not dofs:
            raise InputError(case_path, "model.constrained", "a model.dof_map to find them in")
        drop = set()
        ndf = max(dd for _, dd in dofs)
        for i, (node, d) in enumerate(cfg.constrained):
            num = _as_int(d)
            d = num if num is not None else dof_number(str(d), 6 if ndf > 3 else ndf, cfg.ndm)
            if (node, d) not in dofs:
                raise InputError(case_path, f"model.constrained[{i}]",
                                 "a (node, dof) pair of model.dof_map", [node, d])
            drop.add(dofs.index((node, d)))
        keep = np.array([i for i in range(n_full) if i not in drop])
        dofs = tuple(dofs[i] for i in keep)

    def cut(A):
        return sp.csc_matrix(A[keep][:, keep])

    M0, K0 = cut(mats["M"]), cut(mats["K"])
    check_mass(M0, _file(cfg.M)[0], "M")
    Ks = [(n, cut(A)) for (s, n), A in groups.items() if s == "stiffness_groups"]
    Ms = [(n, cut(A)) for (s, n), A in groups.items() if s == "mass_groups"]
    return StructuralModel(
        M0=M0, K0=K0, M_infl=tuple(A for _, A in Ms), K_infl=tuple(A for _, A in Ks),
        beta_names=tuple(n for n, _ in Ms), alpha_names=tuple(n for n, _ in Ks),
        beta_nominal=np.ones(len(Ms)), alpha_nominal=np.ones(len(Ks)),
        dof_names=tuple(f"{nd}.{d}" for nd, d in dofs) or tuple(f"dof{i + 1}" for i in range(K0.shape[0])),
        dofs=dofs)


def load_bundle(path):
    """Dense model from one NPZ/MAT holding M0, K0 (n, n), M_infl, K_infl (r, n, n)
    and optional alpha_names / beta_names."""
    try:
        if path.endswith(".npz"):
            with np.load(path, allow_pickle=False) as z:
                raw = {k: z[k] for k in z.files}
        else:
            raw = scipy.io.loadmat(path)
    except Exception as exc:  # unreadable, empty or truncated file: a user mistake
        raise InputError(path, "<file>", "a readable .npz or .mat file",
                         f"{type(exc).__name__}: {exc}") from None
    for key in ("M0", "K0", "M_infl", "K_infl"):
        if key not in raw:
            raise InputError(path, key, "an array named so (M0, K0: n x n; M_infl, K_infl: "
                             "r x n x n)")
    M0, K0 = np.asarray(raw["M0"], float), np.asarray(raw["K0"], float)
    n = M0.shape[0]
    Mi, Ki = np.asarray(raw["M_infl"], float), np.asarray(raw["K_infl"], float)
    for key, a, dims in (("M0", M0, 2), ("K0", K0, 2), ("M_infl", Mi, 3), ("K_infl", Ki, 3)):
        if a.ndim != dims or a.shape[-2:] != (n, n) or not np.all(np.isfinite(a)):
            raise InputError(path, key, f"finite array of shape {'(r, ' if dims == 3 else '('}{n}, {n})",
                             f"shape {a.shape}")
    check_model_matrices(path, M0, K0, Mi, Ki)

    def names(key, r, prefix):
        v = raw.get(key)
        if v is None:
            return tuple(f"{prefix}{i + 1}" for i in range(r))
        out = tuple(str(x).strip() for x in np.ravel(v))
        if len(out) != r:  # name the key at fault, not a later CasADi error
            raise InputError(path, key, f"{r} names, one per matrix of "
                             f"{'M_infl' if key == 'beta_names' else 'K_infl'}",
                             f"{len(out)} names")
        return out

    return StructuralModel(M0=M0, K0=K0, M_infl=tuple(Mi), K_infl=tuple(Ki),
                           beta_names=names("beta_names", len(Mi), "beta"),
                           alpha_names=names("alpha_names", len(Ki), "alpha"),
                           beta_nominal=np.ones(len(Mi)), alpha_nominal=np.ones(len(Ki)),
                           dof_names=tuple(f"dof{i + 1}" for i in range(n)))
