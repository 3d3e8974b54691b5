"""FRFs of large models by sparse direct solves, for the case generators.

Written apart from the package's FRF code on purpose: the cases' data must not
come from the code they test. H_k = (jw)^p [(K - w^2 M + jwC)^-1 b]_rows.
"""

import argparse
import json
import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import yaml

__all__ = ["frf_sparse", "add_noise", "generator_args", "write_case"]


def frf_sparse(M, K, C, b, rows, f, power=0):
    """(len(rows), len(f)) complex FRFs; power 0 receptance, 2 accelerance (-w^2 H)."""
    Ms, Ks, Cs = (sp.csc_matrix(A) for A in (M, K, C))
    b = np.asarray(b, complex)
    H = np.empty((len(rows), len(f)), complex)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        q = spla.splu((Ks - w**2 * Ms + 1j * w * Cs).tocsc(), permc_spec="MMD_AT_PLUS_A").solve(b)
        H[:, k] = (1j * w) ** power * q[rows]
    return H


def add_noise(H, noise, rng):
    """H (1 + noise e), e complex Gaussian with E|e|^2 = 1 (noise relative to |H|)."""
    e = (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    return H * (1 + noise * e)


def generator_args(doc, default_out):
    """--seed, --noise, --out of a case generator."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--out", default=default_out)
    return ap.parse_args()


def write_case(out, f, H, truth, case):
    """frf.npz (f [Hz], H), truth.json and case.yaml in out."""
    os.makedirs(out, exist_ok=True)
    np.savez_compressed(os.path.join(out, "frf.npz"), f=f, H=H)
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2)
    with open(os.path.join(out, "case.yaml"), "w") as fh:
        yaml.safe_dump(case, fh, sort_keys=False)
