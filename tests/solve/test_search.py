"""Scatter search (seeded, parallel, interruptible) and the CLI outputs."""

import csv
import json
import os

import numpy as np
import pytest

from support.cases import write_case
from nlp.solve import search as search_mod
from nlp.case.assemble import assemble, build_problem
from nlp.cli import main
from nlp.case.load import load_case
from nlp.solve.search import SearchConfig, pick_starts, scatter_search, trial_points


def test_trial_points_inside_bounds_and_seeded():
    lo, hi = np.array([-1.0, 0.0, 2.0]), np.array([1.0, 5.0, 3.0])
    Z = trial_points(lo, hi, 100, seed=4)
    assert Z.shape == (100, 3) and np.all(Z >= lo) and np.all(Z <= hi)
    np.testing.assert_array_equal(Z, trial_points(lo, hi, 100, seed=4))
    assert not np.array_equal(Z, trial_points(lo, hi, 100, seed=5))


def test_pick_starts_are_distant_and_best_first():
    Z = np.array([[0.0], [0.01], [0.5], [1.0]])
    scores = np.array([1.0, 0.5, 2.0, 3.0])
    idx = pick_starts(Z, scores, 2, np.array([0.0]), np.array([1.0]), min_distance=0.1)
    assert list(idx) == [1, 2]


@pytest.fixture
def problem(tmp_path):
    path, truth = write_case(str(tmp_path), noise=0.02, seed=1)
    return build_problem(assemble(load_case(path)))


def test_same_seed_same_answer_any_workers(problem):
    a = scatter_search(problem, SearchConfig(starts=6, seed=3, workers=1))
    b = scatter_search(problem, SearchConfig(starts=6, seed=3, workers=2))
    np.testing.assert_allclose(a.best.z, b.best.z, rtol=1e-10, atol=1e-12)
    assert [r.f for r in a.results] == pytest.approx([r.f for r in b.results], rel=1e-9)
    assert len(a.near_best) >= 1 and a.best.f == min(r.f for r in a.results)


def test_interrupted_search_keeps_finished_starts(problem, monkeypatch):
    real = search_mod._solve_item
    calls = []

    def flaky(problem, z0):
        calls.append(z0)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(problem, z0)

    monkeypatch.setattr(search_mod, "_solve_item", flaky)
    res = scatter_search(problem, SearchConfig(starts=5, workers=1, executor="serial"))
    assert res.interrupted and len(res.results) == 2 and res.best is not None


def test_cli_writes_all_outputs(tmp_path):
    path, truth = write_case(str(tmp_path / "case"), noise=0.02, seed=2,
                             frequencies={"method": "half_power", "k": 2.0, "fmax": 7.0})
    out = tmp_path / "out"
    assert main(["run", path, "--out", str(out), "--starts", "3", "--seed", "1"]) == 0
    res = json.loads((out / "result.json").read_text())
    for key in ("parameters", "matrices", "modal", "objective", "fdac", "identifiability",
                "solver", "search"):
        assert key in res
    C = np.array(res["matrices"]["updated"]["C"])
    assert np.all(np.linalg.eigvalsh(C) > 0)
    m = {p["name"]: p for p in res["parameters"]}
    assert m["m1"]["fixed"] and m["m1"]["updated"] == pytest.approx(5.16)
    for i, k in enumerate(truth["stiffnesses"]):
        assert m[f"k{i + 1}"]["updated"] == pytest.approx(k, rel=0.02)
        assert 0 < m[f"k{i + 1}"]["standard_error"] < 0.02 * k
    assert res["search"]["starts_finished"] == 3 and res["search"]["starts_within_1pct_of_best"] >= 1
    fn = res["modal"]["updated"]["natural_frequencies_hz"]
    np.testing.assert_allclose(fn, truth["natural_frequencies_hz"], rtol=0.01)
    rows = list(csv.reader((out / "parameters.csv").open()))
    assert rows[0][0].startswith("Parameter") and rows[1][0] == "Initial" and rows[2][0] == "Updated"
    assert float(rows[1][rows[0].index("k1")]) == pytest.approx(1019)
    for ch in range(1, 5):
        assert os.path.getsize(out / f"frf_floor{ch}.png") > 10_000
    assert not [p for p in os.listdir(out) if p.startswith(".tmp")]
