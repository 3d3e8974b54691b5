"""Search reliability: only converged solves win, failures are recorded, interrupts keep
every finished start, --resume gives the uninterrupted answer, any executor the same best."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from support.cases import write_case
from nlp.case.assemble import assemble, build_problem
from nlp.cli import main
from nlp.case.load import load_case
from nlp.errors import SearchFailed
from nlp.solve.executors import Setup
from nlp.solve.problem import LocalResult, UpdatingProblem
from nlp.solve.search import SearchConfig, pick_starts, scatter_search
from support.paths import ROOT


def _reference_pick(Z, scores, n, lo, hi, min_distance):
    """The point-by-point greedy rule (the package's former code), as the reference."""
    U = (Z - lo) / np.where(hi > lo, hi - lo, 1.0)
    order = np.argsort(np.where(np.isfinite(scores), scores, np.inf), kind="stable")
    chosen = []
    for i in order:
        if len(chosen) == n or not np.isfinite(scores[i]):
            break
        if all(np.linalg.norm(U[i] - U[j]) >= min_distance for j in chosen):
            chosen.append(i)
    for i in order:
        if len(chosen) == n:
            break
        if i not in chosen:
            chosen.append(i)
    return np.array(chosen, dtype=int)


@pytest.mark.parametrize("dim,n_pts,n,d", [(2, 600, 40, 0.1), (2, 400, 300, 0.05), (5, 1500, 300, 0.4),
                                           (17, 3000, 400, 1.3), (3, 500, 50, 2.0)])
def test_pick_starts_matches_point_by_point_rule(dim, n_pts, n, d):
    rng = np.random.default_rng(dim * 1000 + n)
    lo, hi = -rng.random(dim), 1 + rng.random(dim)
    Z = lo + rng.random((n_pts, dim)) * (hi - lo)
    scores = rng.standard_normal(n_pts)
    scores[rng.random(n_pts) < 0.05] = np.nan  # failed trial evaluations
    scores[:10] = scores[10]                   # ties keep the order of the points
    np.testing.assert_array_equal(pick_starts(Z, scores, n, lo, hi, d),
                                  _reference_pick(Z, scores, n, lo, hi, d))


def test_pick_starts_10000_starts_fast():
    rng = np.random.default_rng(0)
    lo, hi = np.zeros(17), np.ones(17)
    Z = rng.random((100_000, 17))
    t0 = time.perf_counter()
    idx = pick_starts(Z, rng.random(100_000), 9_999, lo, hi, 0.1)
    # the 5-s target is bench_search.py's (timing asserts fail on a loaded machine); the
    # point-by-point rule took minutes here, so 30 s still catches a quadratic regression
    assert time.perf_counter() - t0 < 30.0
    assert len(set(idx.tolist())) == 9_999
    U = Z[idx]
    from scipy.spatial import cKDTree
    assert not cKDTree(U).query_pairs(0.1 - 1e-12)  # all picks mutually >= 0.1 apart


@pytest.fixture(scope="module")
def case_path(tmp_path_factory):
    path, _ = write_case(str(tmp_path_factory.mktemp("case")), noise=0.02, seed=1,
                         frequencies={"method": "half_power", "k": 2.0, "fmax": 7.0})
    return path


@pytest.fixture(scope="module")
def problem(case_path):
    return build_problem(assemble(load_case(case_path)))


def test_failed_solves_never_win(problem, monkeypatch):
    real = UpdatingProblem.solve
    calls = {"n": 0}

    def sabotaged(self, z0=None, **kw):
        calls["n"] += 1
        k = calls["n"] % 3
        if k == 1:
            raise RuntimeError("Error in Function::call for 'updater' [IpoptInterface]")
        if k == 2:  # an "answer" better than any real one, from a solver that gave up
            return LocalResult(z=np.asarray(z0, float), f=0.0, success=False,
                               status="Invalid_Number_Detected", iterations=0, seconds=0.0,
                               z0=np.asarray(z0, float))
        res = real(self, z0, **kw)
        return res

    monkeypatch.setattr(UpdatingProblem, "solve", sabotaged)
    res = scatter_search(problem, SearchConfig(starts=9, seed=2, executor="serial"))
    statuses = [r.status for r in res.results]
    assert sum(s.startswith("error: RuntimeError") for s in statuses) == 3
    assert statuses.count("Invalid_Number_Detected") == 3
    failed = [r for r in res.results if not r.success]
    assert len(failed) == 6
    for r in failed:  # never the f = 0 the failed solver reported
        assert r.f == np.inf if r.status.startswith("error") else \
            r.f == pytest.approx(problem.objective(r.z0), rel=1e-12) and r.f > 1.0
    assert res.best.success and res.best.status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    assert res.best.f > 0 and res.best.f == pytest.approx(problem.objective(res.best.z), rel=1e-9)
    assert all(r.success for r in res.near_best)


def test_no_converged_solve_exits_3_and_writes_nothing(case_path, tmp_path, monkeypatch, capsys):
    def broken(self, z0=None, **kw):
        z = np.full(self.params.n_z, np.nan)
        return LocalResult(z=z, f=float("nan"), success=True, status="Solve_Succeeded",
                           iterations=3, seconds=0.0, z0=np.asarray(z0, float))

    monkeypatch.setattr(UpdatingProblem, "solve", broken)
    out = tmp_path / "out"
    assert main(["run", case_path, "--out", str(out), "--starts", "3"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none of the 3 local solves converged" in err[0]
    assert not (out / "result.json").exists() and not (out / "report.html").exists()
    with pytest.raises(SearchFailed):
        scatter_search(build_problem(assemble(load_case(case_path))),
                       SearchConfig(starts=2, executor="serial"))


def _run_cli(args):
    env = dict(os.environ, PYTHONPATH=ROOT)
    return subprocess.Popen([sys.executable, "-m", "nlp", "run", *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _lines(path):
    try:
        with open(path) as fh:
            return [json.loads(x) for x in fh if x.endswith("\n")]
    except FileNotFoundError:
        return []


@pytest.mark.parametrize("workers,sig", [
    pytest.param(1, signal.SIGINT, marks=pytest.mark.slow),  # 20-40 s each
    pytest.param(2, signal.SIGINT, marks=pytest.mark.slow),
    pytest.param(2, signal.SIGTERM, marks=pytest.mark.slow)])
def test_signal_keeps_finished_starts_and_resume_gives_same_best(case_path, problem, tmp_path,
                                                                 workers, sig):
    out = tmp_path / "out"
    ckpt = str(out) + ".partial/checkpoint.jsonl"
    args = [case_path, "--out", str(out), "--starts", "60", "--seed", "4",
            "--workers", str(workers)]
    proc = _run_cli(args)
    t_end = time.time() + 60
    while len(_lines(ckpt)) < 4 and time.time() < t_end and proc.poll() is None:
        time.sleep(0.05)
    seen = len(_lines(ckpt)) - 1
    assert proc.poll() is None and seen >= 3, "the run finished before it could be interrupted"
    t0 = time.time()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    recs = _lines(ckpt)[1:]
    assert len(recs) >= seen and len({r["start"] for r in recs}) == len(recs) < 60
    search = json.loads((out / "result.json").read_text())["search"]
    assert search["interrupted"] and search["starts_finished"] == len(recs)
    assert time.time() - t0 < 20  # search stops at once; the partial result is then written
    resumed = _run_cli(args + ["--resume"])
    _, err = resumed.communicate(timeout=120)
    assert resumed.returncode == 0, err
    res = json.loads((out / "result.json").read_text())
    assert res["search"]["starts_resumed"] == len(recs) and res["search"]["starts_finished"] == 60
    assert not os.path.exists(str(out) + ".partial")
    full = scatter_search(problem, SearchConfig(starts=60, seed=4, executor="serial"))
    assert res["objective"]["updated"] == pytest.approx(full.best.f, rel=1e-12)


@pytest.mark.slow
def test_same_best_on_every_executor(case_path, tmp_path):
    """Serial, 1 and 2 local workers and a 2-worker Dask LocalCluster: the same starts,
    the same objectives, the same best (the workers rebuild the problem from the case)."""
    pytest.importorskip("distributed")
    case = assemble(load_case(case_path))
    problem = build_problem(case)
    runs = {}
    for kind, workers in (("serial", 1), ("local", 1), ("local", 2), ("dask", 2)):
        cfg = SearchConfig(starts=16, seed=5, workers=workers, executor=kind)
        runs[kind, workers] = scatter_search(problem, cfg,
                                             setup=Setup(build_problem, case, value=problem))
    ref = runs["serial", 1]
    for key, r in runs.items():
        assert r.indices == list(range(16)), key
        np.testing.assert_allclose([x.f for x in r.results], [x.f for x in ref.results],
                                   rtol=1e-12, err_msg=str(key))
        np.testing.assert_allclose(r.best.z, ref.best.z, rtol=1e-10, atol=1e-12)
    out = tmp_path / "dask"
    assert main(["run", case_path, "--out", str(out), "--starts", "16", "--seed", "5",
                 "--executor", "dask", "--workers", "2"]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["objective"]["updated"] == pytest.approx(ref.best.f, rel=1e-12)
    theta = problem.theta(ref.best.z)
    for p, spec, th in zip(res["parameters"], case.params.params, theta):
        expected = spec.nominal * (1 + th) if spec.nominal is not None else th
        assert p["updated"] == pytest.approx(expected, rel=1e-9, abs=1e-12), p["name"]


def test_checkpoint_resume_ignores_torn_line_and_refuses_another_search(problem, tmp_path):
    from nlp.solve.checkpoint import Checkpoint
    from nlp.errors import InputError
    from nlp.solve.search import solve_start, start_points

    cfg = SearchConfig(starts=4, seed=1)
    starts, _ = start_points(problem, cfg)
    path = str(tmp_path / "out.partial" / "checkpoint.jsonl")
    ck = Checkpoint(path)
    assert ck.open(problem, cfg, starts) == {}
    res = solve_start(problem, starts[2])
    ck.append(2, res)
    ck.close()
    with open(path, "a") as fh:
        fh.write('{"start": 3, "f": 0.1')  # a line cut by a kill
    again = Checkpoint(path, resume=True)
    got = again.open(problem, cfg, starts)
    again.close()
    assert list(got) == [2] and got[2].f == res.f and np.array_equal(got[2].z, res.z)
    for other in (SearchConfig(starts=4, seed=2), SearchConfig(starts=5, seed=1)):
        s2, _ = start_points(problem, other)
        with pytest.raises(InputError, match="--resume"):
            Checkpoint(path, resume=True).open(problem, other, s2)
    with pytest.raises(InputError, match="there is none"):
        Checkpoint(str(tmp_path / "none" / "checkpoint.jsonl"), resume=True).open(problem, cfg,
                                                                                   starts)


def test_stationary_points_compete_and_unchecked_ones_do_not(problem):
    """A solve UpdatingProblem.solve found stationary (success and a `Stationary ...`
    status) competes like IPOPT's own convergence; the same status without success, or a
    limit status, does not."""
    from nlp.solve.search import converged
    z = np.asarray(problem.z0, float)
    f = float(problem.objective(z))

    def res(status, success):
        return LocalResult(z=z, f=f, success=success, status=status, iterations=3000,
                           seconds=1.0, z0=z)

    assert converged(problem, res("Stationary after 7 Newton steps (decrement 5.4e-05)", True))
    assert converged(problem, res("Stationary (Gauss-Newton decrement 3.0e-07)", True))
    assert not converged(problem, res("Stationary after 7 Newton steps (decrement 5.4e-05)", False))
    assert not converged(problem, res("Maximum_Iterations_Exceeded", False))
    assert converged(problem, res("Solve_Succeeded", True))


def test_stationary_screened_starts_are_not_solved_again(problem, monkeypatch):
    """Screened starts are re-solved at the full tolerance, except those already found
    stationary by the Newton test: IPOPT would only creep to its limit again. Each
    kind is counted by the calls that reach UpdatingProblem.solve."""
    from nlp.solve import search
    z = np.asarray(problem.z0, float)
    calls = []

    def fake(self, z0=None, screen=False, bounds=None, prefit=True):
        assert not prefit  # a re-solve from a screened optimum: no prefit again
        calls.append(screen)
        z0 = np.asarray(z0, float)
        f = float(self.objective(z0))
        return LocalResult(z=z0, f=f, success=True, status="Solve_Succeeded", iterations=1,
                           seconds=0.0, z0=z0)

    monkeypatch.setattr(UpdatingProblem, "solve", fake)
    monkeypatch.setattr(UpdatingProblem, "can_screen", property(lambda self: True))
    f = float(problem.objective(z))
    results = {i: LocalResult(z=z, f=f + i, success=True,
                              status=("Stationary after 2 Newton steps (decrement 1e-05)"
                                      if i % 2 else "Solve_Succeeded"),
                              iterations=5, seconds=0.0, z0=z) for i in range(6)}
    polished = search._polish(problem, results)
    assert polished == tuple(range(6))
    assert calls == [False, False, False]           # starts 0, 2 and 4 only
    assert all(results[i].status.startswith("Stationary") for i in (1, 3, 5))
    assert all(results[i].iterations == 6 for i in (0, 2, 4))
