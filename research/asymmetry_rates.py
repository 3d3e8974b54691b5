"""The asymmetry test (nlp.diagnosis.asymmetry) on lab cases: each story's even-force z.

    python research/asymmetry_rates.py CASE [CASE ...]

CASE: a lab case folder (scripts/make_lab_benchmark.py, development seeds only). The
reference level is fitted as the level comparison fits it (levels.level_fit); every level's
records are then tested with that model. Prints per case the stories' z (theta / SE),
the first-order 2 kappa / k_eq with its SE, and the decided story's refined bilinear delta, the decision and the truth's links.
"""

import json
import os
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.asymmetry import asymmetry, bilinear_delta  # noqa: E402
from nlp.diagnosis.harmonics import story_matrix  # noqa: E402
from nlp.diagnosis.levels import level_fit  # noqa: E402
from nlp.diagnosis.others import assemble_other  # noqa: E402


def truth_of(path):
    with open(os.path.join(path, "truth.json")) as fh:
        t = json.load(fh)
    links = [f"{ln['kind']}@{ln.get('story', ln.get('j'))}" + (f" delta {ln['delta']}" if "delta" in ln else "")
             for ln in t.get("links", []) if ln["kind"] != "cubic"]
    return t.get("category"), t.get("signal"), links


def one(path):
    t0 = time.perf_counter()
    cfg = load_case(os.path.join(path, "case.yaml"))
    ref = level_fit(cfg, cfg.data.file)
    fits = [ref]
    for p in cfg.data.level_files:
        c, _ = assemble_other(cfg, p, lambda *a, **k: None)
        if c is not None:
            fits.append({"case": c, "problem": ref["problem"], "z": ref["z"]})
    c = ref["case"]
    M, K, C = ref["problem"].matrices(ref["z"])
    B = story_matrix(c.model, M.shape[0])[1]
    tests = [{"records": f["case"].records,
              "H_model": (lambda w, f=f: ref["problem"].channel_frfs(ref["z"], w))}
             for f in fits if f["case"].records is not None]
    tg = c.target
    out = asymmetry(tests, M, C, K, B, c.channels, (tg.excitation, tg.force_dof, tg.ground_r),
                    float(c.f[c.selected].min()))
    k = ref["k"]
    cat, sig, links = truth_of(path)
    print(f"{os.path.basename(os.path.dirname(path.rstrip('/')))}/{os.path.basename(path.rstrip('/'))} "
          f"[{cat}, {sig}, {len(tests)} level(s)] truth {links or '-'}; {time.perf_counter() - t0:.0f} s")
    print("   z per story: " + ", ".join(f"{z:+.1f}" for z in out["z"])
          + f"; gap {out['gap']:.1f}; decided: "
          + (f"story {out['best'] + 1}" if out["best"] is not None else "no"))
    print("   2 kappa / k_eq (first order): " + ", ".join(
        f"{2 * ka / kk:+.3f} +- {2 * se / kk:.3f}" for ka, se, kk in zip(out["kappa"], out["se"], k)))
    if "refined" in out:
        r, s = out["refined"], out["best"]
        print(f"   story {s + 1}: kappa {r['kappa']:.4g} N/m after {r['iterations']} iterations "
              f"({'converged' if r['converged'] else 'not converged'}); bilinear delta "
              f"{bilinear_delta(r['kappa'], k[s]):.3f}")
    sys.stdout.flush()


if __name__ == "__main__":
    for p in sys.argv[1:]:
        one(p)
