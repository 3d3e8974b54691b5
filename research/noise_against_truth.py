"""The noise model against the true FRF: mean z^2 of a blind benchmark's measured FRFs.

    python research/noise_against_truth.py --bench BENCH [--kinds null,ordinary]

A baseline fit's reduced chi-square mixes two things: whether the noise model's
sigma is right, and how much of the noise the fitted parameters absorb. Here
the first is measured alone. For every case of a benchmark made by
scripts/make_blind_benchmark.py whose truth has no effect (null and ordinary
cases), the true FRF is computed from truth.json's M, C, K by a direct solve of
(K - w^2 M + j w C) X = b written in this script (not the package's FRF code),
smoothed by the estimate's window where the model sees one, and

    z^2 = (ln|H_measured| - ln|H_true|)^2 / sigma_ln^2

is averaged at the points the diagnosis fits (the half-power windows) and over
the whole band fmin-fmax. A right sigma gives 1 on average; one case's mean
scatters by about sqrt(2 / n_independent), and the points of one window are far
from independent (adjacent bins of a Hann average, channels that share the input
and the modal response), so the standard error printed beside it (+-) is a block
bootstrap over runs of 3 fitted bins with all their channels. The baseline's reduced chi-square is printed beside it
when the benchmark was scored (scores.jsonl).
"""

import argparse
import json
import os
import sys

import numpy as np

BASE = -1


def true_frf(M, C, K, omega, channels, excitation, force_dof):
    """(n_ch, N) FRF of each channel of the true system, by a direct solve per frequency.

    Ground input: b = -M 1 (the story DOFs all move with the table); an absolute
    accelerometer reads -w^2 X + 1, a relative sensor X (p-th derivative: (jw)^p X).
    """
    n = M.shape[0]
    b = -M @ np.ones(n) if excitation == "ground" else np.eye(n)[force_dof]
    out = np.empty((len(channels), omega.size), complex)
    X = np.array([np.linalg.solve(K - w ** 2 * M + 1j * w * C, b) for w in omega]).T
    power = {"receptance": 0, "mobility": 1, "accelerance": 2, "absolute_accelerance": 2}
    for i, ch in enumerate(channels):
        if ch.dof == BASE:
            out[i] = 1.0 if ch.output == "absolute_accelerance" else 0.0
            continue
        out[i] = (1j * omega) ** power[ch.output] * X[ch.dof]
        if ch.output == "absolute_accelerance":
            out[i] += 1.0
    return out


def case_z2(folder):
    from nlp.case.assemble import assemble
    from nlp.case.load import load_case

    cfg = load_case(os.path.join(folder, "case.yaml"))
    case = assemble(cfg)
    sys_ = json.load(open(os.path.join(folder, "truth.json")))["system"]
    M, C, K = (np.asarray(sys_[k], float) for k in "MCK")
    K = K + 1j * np.asarray(sys_.get("Kh", np.zeros_like(K)), float)
    tg = case.target
    w = 2 * np.pi * case.f

    def H(om):
        return true_frf(M, C, K, om, case.channels, tg.excitation, tg.force_dof)

    Ht = H(w)
    if tg.kernel is not None:   # the model's view of a windowed average: three taps
        h, a = tg.kernel
        Ht = a * H(w - h) + (1 - 2 * a) * Ht + a * H(w + h)
    with np.errstate(divide="ignore", invalid="ignore"):
        z2 = (np.log(np.abs(case.H / Ht)) / case.noise.sigma_ln) ** 2
    fr = cfg.frequencies
    band = (case.f >= (fr.fmin or 0.0)) & (case.f <= (fr.fmax or case.f[-1])) & (case.f > 0)
    rows = [i for i, ch in enumerate(case.channels) if ch.dof != BASE]
    z2 = z2[rows]
    zs = z2[:, case.selected]
    return case.noise.route, float(np.mean(zs)), float(np.mean(z2[:, band])), zs.size, \
        block_se(zs)


def block_se(z2, block=3, draws=2000, seed=0):
    """Standard error of mean(z2) by a block bootstrap: blocks of `block` adjacent fitted
    bins with all their channels, which carry the correlation of neighbouring bins and of
    the channels (a shared input, one modal response)."""
    n = z2.shape[1]
    starts = np.arange(0, n, block)
    blocks = [z2[:, s:s + block].ravel() for s in starts]
    rng = np.random.default_rng(seed)
    means = []
    for _ in range(draws):
        pick = rng.integers(0, len(blocks), len(blocks))
        v = np.concatenate([blocks[i] for i in pick])
        means.append(v.mean())
    return float(np.std(means))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", required=True, help="a folder made by make_blind_benchmark.py")
    ap.add_argument("--kinds", default="null,ordinary",
                    help="case kinds (the name after the number): default null,ordinary")
    args = ap.parse_args(argv)
    kinds = tuple(args.kinds.split(","))
    scored = {}
    path = os.path.join(args.bench, "scores.jsonl")
    if os.path.exists(path):
        for line in open(path):
            r = json.loads(line)
            scored[r["case"]] = r.get("baseline_reduced_chi2")
    print(f"{'case':<18}{'route':<15}{'points':>7}{'z2 fitted':>11}{'+-':>7}{'z2 band':>9}"
          f"{'baseline chi2':>15}")
    by_route = {}
    for name in sorted(os.listdir(args.bench)):
        folder = os.path.join(args.bench, name)
        kind = name.split("_", 1)[-1]
        if not (os.path.isdir(folder) and kind.startswith(kinds)):
            continue
        route, zf, zb, n, se = case_z2(folder)
        by_route.setdefault(route, []).append(zf)
        chi = scored.get(name)
        print(f"{name:<18}{route:<15}{n:>7}{zf:>11.3f}{se:>7.3f}{zb:>9.3f}"
              + (f"{chi:>15.3f}" if chi is not None else f"{'-':>15}"), flush=True)
    for route, v in by_route.items():
        print(f"{route}: z2 at the fitted points, mean {np.mean(v):.3f} over {len(v)} cases "
              f"(range {min(v):.3f}-{max(v):.3f})")


if __name__ == "__main__":
    main()
