"""Baseline chi-square of a null FRF file fitted without and with its coherence (same records).

How far a right noise model would put such a file from 1.

    python research/frf_file_coherence_control.py --out /tmp/ctl SEED [SEED ...]
    python research/frf_file_coherence_control.py --out /tmp/ctl --lead SEED ...

For each seed, case 62 of ``scripts/make_blind_benchmark.py`` (a null FRF file without
coherence) is written twice from the same records: as the generator writes it, and with its
coherence and number of averages stored (``SEED/coherent``). The H of the two files is the
same array. The baseline that ``diagnose`` fits first (its windows, its noise model, a scatter
search with 20 starts) is fitted to each, and its reduced chi-square printed: ``scatter`` (the
noise read from the file's own scatter, the route that a file without coherence takes) and
``coherence`` (the noise from the stored coherence: what the records themselves say). The
coherence variance checks against the true FRF at mean z^2 0.76-1.22 on the blind files 61
(README), so the ``coherence`` column is what a right noise model gives on that data: its
spread is sampling, not the noise model.

``--lead`` adds a third column, not in the package: the scatter read from third differences of
ln(H / H_b), H_b the baseline model through the window's three taps, so that the structure's
own sharp peaks do not count as scatter, with the whole squared resolution bias kept as the
leakage variance (``LEAKAGE_KEEP`` 1 in place of 0.4), and the baseline refitted with it.
"""

import argparse
import dataclasses
import os
import sys
from types import SimpleNamespace
from unittest import mock

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

from nlp.testing.blind import cases as gen  # noqa: E402
from nlp.frf import noise as N  # noqa: E402
from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.fitting import _problem, _search, _target, _windows, noise_sigma  # noqa: E402
from nlp.solve.search import SearchConfig  # noqa: E402

CASE = 62


def write_pair(out, seed):
    """Case 62 of ``seed`` as generated, and the same with its coherence: two folders."""
    spec = gen.specs(np.random.default_rng(seed))[CASE]
    name = gen.case_name(CASE, spec)
    plain, coherent = os.path.join(out, str(seed), name), os.path.join(out, str(seed), "coherent")
    for folder, s in ((plain, spec), (coherent, dict(spec, coherence=True))):
        if not os.path.exists(os.path.join(folder, "case.yaml")):
            gen.make_case(folder, s, seed * 1000 + CASE, base_channel=True)
    return plain, coherent


def baseline(case, z0=None):
    """diagnose's baseline on ``case``: (problem, optimum, reduced chi-square)."""
    cfg = case.config
    fit = _windows(cfg, case, 1)
    pr = _problem(case, _target(case, fit, noise_sigma(case, fit)))
    if z0 is None:
        res = _search(pr, SearchConfig(starts=20, seed=cfg.search.seed, workers=1))[0]
    else:
        res = pr.solve(z0)
    return pr, res, 2 * res.f / max(pr.n_used - pr.params.n_z, 1)


def lead(case, pr, z):
    """Reduced chi-square with the scatter of ln(H / H_b) (module docstring)."""
    h, a = case.target.kernel
    w = 2 * np.pi * case.f
    Hb = sum(c * pr.channel_frfs(z, w + s * h) for s, c in ((-1, a), (0, 1 - 2 * a), (1, a)))
    ratio = case.H / Hb
    spaced = N.spaced_scatter
    with mock.patch.object(N, "spaced_scatter",
                           lambda f, H, half_width=25, window=None: spaced(f, ratio, half_width,
                                                                           window)), \
            mock.patch.object(N, "LEAKAGE_KEEP", 1.0):
        model = N.noise_model(SimpleNamespace(
            config=case.config, f=case.f, H=case.H, coherence=None, records=None,
            channels=case.channels, n_averages=1, kernel=case.target.kernel))
    return baseline(dataclasses.replace(case, noise=model), z0=z)[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seeds", nargs="+", type=int)
    ap.add_argument("--out", required=True, help="folder for the generated files")
    ap.add_argument("--lead", action="store_true", help="add the scatter about the baseline")
    a = ap.parse_args()
    rows = []
    print(f"{'seed':>8} {'scatter':>8} {'coherence':>10}" + (f" {'lead':>6}" if a.lead else ""))
    for seed in a.seeds:
        plain, coherent = write_pair(a.out, seed)
        case = assemble(load_case(os.path.join(plain, "case.yaml")))
        assert case.noise.route == "scatter"
        pr, res, chi_s = baseline(case)
        cc = assemble(load_case(os.path.join(coherent, "case.yaml")))
        assert cc.noise.route == "frf_coherence" and np.array_equal(cc.H, case.H)
        chi_c = baseline(cc)[2]
        row = [chi_s, chi_c] + ([lead(case, pr, res.z)] if a.lead else [])
        rows.append(row)
        print(f"{seed:>8} {row[0]:8.2f} {row[1]:10.2f}" + (f" {row[2]:6.2f}" if a.lead else ""),
              flush=True)
    v = np.array(rows)
    for j, name in enumerate(["scatter", "coherence", "lead"][:v.shape[1]]):
        c = v[:, j]
        print(f"{name}: mean {c.mean():.2f}, SD {c.std(ddof=1) if c.size > 1 else 0:.2f}, "
              f"range {c.min():.2f}-{c.max():.2f}, outside 0.8-1.3: "
              f"{int(np.sum((c < 0.8) | (c > 1.3)))} of {c.size}")


if __name__ == "__main__":
    main()
