"""The lab benchmark's case list (nlp/testing/lab/cases.py): every category, the nine
families, the effects outside them, and what truth.json will accept."""

import numpy as np

from nlp.testing.blind.structures import FAMILIES
from nlp.testing.lab.cases import CATEGORIES, VERDICTS, case_name, specs
from nlp.testing.lab.links import OUTSIDE
from nlp.testing.lab.structures import RHO


def test_case_list_covers_every_category_family_and_outside_effect():
    sp = specs(np.random.default_rng(0))
    cats = [s["category"] for s in sp]
    assert set(cats) == set(CATEGORIES)
    assert cats.count("null_lab") >= 8
    fams = [s["effects"][0][0] for s in sp if s["category"] == "in_catalogue"]
    assert sorted(set(fams)) == sorted(FAMILIES)
    assert {s["outside"][0] for s in sp if s["category"] == "out_of_catalogue"} == set(OUTSIDE)
    rhos = [s["rho"] for s in sp if s["category"] == "non_shear"]
    assert min(rhos) >= RHO[0] and max(rhos) <= RHO[1] and max(rhos) / min(rhos) > 3
    assert all(s["two_levels"] for s in sp if s["category"] == "out_of_catalogue")
    assert len({case_name(k, s) for k, s in enumerate(sp)}) == len(sp)


def test_the_seed_drives_the_list_and_out_of_catalogue_never_accepts_a_confident_family():
    a, b = specs(np.random.default_rng(4)), specs(np.random.default_rng(4))
    assert a == b and a != specs(np.random.default_rng(5))
    assert "missing_physics" not in VERDICTS["out_of_catalogue"]
    assert "missing_physics" not in VERDICTS["torsion"]
    assert "missing_physics" not in VERDICTS["null_lab"]
