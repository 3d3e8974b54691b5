"""Output folders are transactional and locked; flags and provenance are written.

Real processes and real signals: SIGKILL at random times during the write phase
leaves --out either untouched or the complete new result, never a mix."""

import hashlib
import math
import json
import os
import random
import signal
import subprocess
import sys
import time

import casadi as ca
import numpy as np
import pytest

from support.cases import write_case
from nlp.output import outdir
from nlp.errors import InputError
from nlp.output.flags import iteration_flag, replay_flags
from nlp.frf.metrics import correlation
from nlp.testing.shake_table import make as make_shake_table
from support.cli import cli, cli_inproc, snapshot
from support.paths import ROOT


def sha(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def consistent(out):
    """A complete result of one run: every file there, one provenance in all of them."""
    names = set(os.listdir(out))
    assert {"result.json", "summary.json", "parameters.csv", "report.html"} <= names, names
    assert outdir.INCOMPLETE not in names and not any(n.startswith(".tmp-") for n in names)
    r = json.load(open(os.path.join(out, "result.json")))
    s = json.load(open(os.path.join(out, "summary.json")))
    assert r["provenance"] == s["provenance"]
    assert r["provenance"]["date_utc"] in open(os.path.join(out, "report.html")).read()
    return r


# ------------------------------------------------------------- the mechanism, forked
def _writer(out, n_files, crash_after):
    """Child: write n files into the staging folder, SIGKILL itself after crash_after."""
    try:
        with outdir.output_folder(out) as stage:
            for i in range(n_files):
                if i == crash_after:
                    os.kill(os.getpid(), signal.SIGKILL)
                with open(os.path.join(stage, f"f{i}.txt"), "w") as fh:
                    fh.write(f"{os.getpid()} {i}\n" * 1000)
    finally:
        os._exit(0 if sys.exc_info()[0] is None else 1)


def test_sigkill_at_any_point_leaves_old_or_new(tmp_path):
    out = str(tmp_path / "out")
    rng = random.Random(0)
    pid = os.fork()
    if pid == 0:  # pragma: no cover - child
        _writer(out, 8, -1)
    os.waitpid(pid, 0)
    old = snapshot(out)
    for trial in range(12):
        crash = rng.randrange(0, 10)  # 8 and 9: after the last file (or never)
        pid = os.fork()
        if pid == 0:  # pragma: no cover - child
            _writer(out, 8, crash if crash < 8 else -1)
        _, status = os.waitpid(pid, 0)
        killed = os.WIFSIGNALED(status)
        assert killed == (crash < 8)
        files = sorted(os.listdir(out))
        assert files == [f"f{i}.txt" for i in range(8)]
        writers = {open(os.path.join(out, f)).read().split()[0] for f in files}
        assert len(writers) == 1  # one run's files, never a mix
        if killed:
            assert {k: v for k, v in snapshot(out).items() if k.startswith("out/")} == \
                {k: v for k, v in old.items() if k.startswith("out/")}
            assert os.path.isfile(os.path.join(out + ".staging", outdir.INCOMPLETE))
        else:
            old = snapshot(out)
            assert os.path.isdir(out + ".prev") and not os.path.exists(out + ".staging")
        assert not os.path.exists(out + ".lock") or killed


def test_input_error_inside_leaves_nothing(tmp_path):
    out = str(tmp_path / "a" / "b" / "out")
    with pytest.raises(InputError):
        with outdir.output_folder(out) as stage:
            open(os.path.join(stage, "x"), "w").write("half")
            raise InputError("case.yaml", "data.file", "something")
    assert os.listdir(tmp_path) == []


def test_a_file_named_like_prev_or_staging_is_replaced(tmp_path):
    out = str(tmp_path / "out")
    os.mkdir(out)
    open(out + ".prev", "w").write("x")
    open(out + ".staging", "w").write("x")
    with outdir.output_folder(out) as stage:
        open(os.path.join(stage, "a"), "w").write("new")
    assert os.listdir(out) == ["a"] and os.path.isdir(out + ".prev")
    assert sorted(os.listdir(tmp_path)) == ["out", "out.prev"]


def test_interrupted_result_says_so_inside(tmp_path):
    out = str(tmp_path / "out")
    with outdir.output_folder(out) as stage:
        open(os.path.join(stage, "summary.json"), "w").write("{}")
        stage.interrupted = True
    assert sorted(os.listdir(out)) == [outdir.INTERRUPTED, "summary.json"]
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_lock_refuses_a_second_writer(tmp_path):
    out = str(tmp_path / "out")
    os.mkdir(out)
    with outdir.output_folder(out):
        with pytest.raises(InputError, match="locked"):
            with outdir.output_folder(out):
                pass
        with pytest.raises(InputError, match="locked"):
            with outdir.locked_folder(out):
                pass
    assert sorted(os.listdir(tmp_path)) == ["out", "out.prev"]


# ------------------------------------------------------------- the real command
@pytest.fixture(scope="module")
def case(tmp_path_factory):
    d = tmp_path_factory.mktemp("tx")
    path, truth = write_case(str(d / "case"))
    return path, truth, d


@pytest.mark.slow
def test_run_twice_prev_permissions_provenance_and_cache_repair(case, tmp_path):
    path, _, _ = case
    out = str(tmp_path / "out")
    cache = str(tmp_path / "cache")
    env = {"FRF_NLP_CACHE": cache}
    old_mask = os.umask(0o022)
    try:
        p1 = cli("run", path, "--out", out, "--starts", 2, "--seed", 1, env=env)
        assert p1.returncode == 0, p1.stderr
        r1 = consistent(out)
        # every cached library damaged: garbage in one, a truncated copy in the others
        libs = [os.path.join(cache, f) for f in os.listdir(cache) if f.endswith(".so")]
        assert libs
        for lib in libs:
            data = open(lib, "rb").read()
            tmp = lib + ".bad"
            open(tmp, "wb").write(data[: len(data) // 3] if len(data) % 2 else b"\x7fELF" + b"\0" * 99)
            os.replace(tmp, lib)
        p2 = cli("run", path, "--out", out, "--starts", 2, "--seed", 2, env=env)
    finally:
        os.umask(old_mask)
    assert p2.returncode == 0, p2.stderr
    assert "rebuilding" in p2.stderr and "solver.options" not in p2.stderr
    r2 = consistent(out)
    assert r2["solver"]["compiled"] is True
    assert r1["provenance"]["command_line"].endswith("--seed 1")
    assert r2["provenance"]["command_line"].endswith("--seed 2")
    prev = consistent(out + ".prev")
    assert prev["provenance"] == r1["provenance"]
    assert sorted(os.listdir(tmp_path)) == ["cache", "out", "out.prev"]
    # same data, same optimum after the rebuild
    u1 = {p["name"]: p["updated"] for p in r1["parameters"]}
    u2 = {p["name"]: p["updated"] for p in r2["parameters"]}
    assert all(abs(u1[k] - u2[k]) <= 1e-3 * abs(u1[k]) + 1e-9 for k in u1 if k[0] in "mk")
    # files are ordinary 0644 (umask 022), not mkstemp's 0600
    for f in ("result.json", "summary.json", "parameters.csv", "report.html", "frf_floor1.png"):
        assert os.stat(os.path.join(out, f)).st_mode & 0o777 == 0o644, f
    # provenance: the files' sha256, recomputed here
    prov = r2["provenance"]
    folder = os.path.dirname(path)
    assert prov["files"][path]["sha256"] == sha(path)
    assert prov["files"][os.path.join(folder, "frf.npz")]["sha256"] == sha(
        os.path.join(folder, "frf.npz"))
    assert prov["version"] and prov["date_utc"].endswith("+00:00")
    assert r2["flags"] == []


@pytest.mark.slow
def test_sigkill_before_the_swap_keeps_the_old_folder(case, tmp_path):
    path, _, _ = case
    out = str(tmp_path / "out")
    assert cli_inproc("run", path, "--out", out, "--starts", 1).returncode == 0
    before = snapshot(out)
    proc = cli("run", path, "--out", out, "--starts", 1, "--seed", 5,
               env={"FRF_NLP_TEST_CRASH": "commit"})
    assert proc.returncode == -signal.SIGKILL
    assert {k: v for k, v in snapshot(out).items() if k.startswith("out/")} == \
        {k: v for k, v in before.items() if k.startswith("out/")}
    stage = out + ".staging"
    assert "result.json" in os.listdir(stage)
    # the lock died with the process; the next writer replaces the dead staging folder
    with outdir.output_folder(out) as new:
        assert os.listdir(new) == [outdir.INCOMPLETE]
        open(os.path.join(new, "result.json"), "w").write("{}")
    assert os.listdir(out) == ["result.json"] and consistent(out + ".prev")
    assert not os.path.exists(stage) and not os.path.exists(out + ".lock")


@pytest.mark.slow
def test_sigkill_at_random_times_during_a_real_run(case, tmp_path):
    path, _, _ = case
    out = str(tmp_path / "out")
    assert cli_inproc("run", path, "--out", out, "--starts", 1).returncode == 0
    old = consistent(out)
    env = dict(os.environ, PYTHONPATH=ROOT)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "nlp", "run", path, "--out", out, "--starts", "1"],
                       env=env, capture_output=True, timeout=240)
    assert p.returncode == 0
    duration = time.perf_counter() - t0
    rng = random.Random(3)
    for _ in range(3):  # kill in the last 60 % of a run: that is where the files are written
        proc = subprocess.Popen([sys.executable, "-m", "nlp", "run", path, "--out", out,
                                 "--starts", "1"], env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        time.sleep(duration * rng.uniform(0.4, 1.0))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        r = consistent(out)  # old or new, but complete and one run's
        assert r["provenance"]["date_utc"] >= old["provenance"]["date_utc"]


def test_second_run_on_a_locked_out_is_refused(case, tmp_path):
    path, _, _ = case
    out = str(tmp_path / "out")
    holder = subprocess.Popen([sys.executable, "-c",
                               "import sys, time; from nlp.output import outdir\n"
                               "with outdir.output_folder(sys.argv[1]):\n"
                               "    print('locked', flush=True); time.sleep(60)\n", out],
                              env=dict(os.environ, PYTHONPATH=ROOT), stdout=subprocess.PIPE,
                              text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        proc = cli("run", path, "--out", out, "--starts", 1)
        assert proc.returncode == 2 and "locked" in proc.stderr and "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1
        rep = cli_inproc("report", out + ".staging")
        assert rep.returncode == 2
    finally:
        holder.kill()
        holder.wait()
    assert not os.path.exists(out)


# ------------------------------------------------------------- flags
def test_parameter_at_a_bound_is_flagged(case, tmp_path):
    path, truth, _ = case
    import yaml
    cfg = yaml.safe_load(open(path))
    # the truth k4 = 2738 N/m lies above this interval: the bound is set across the truth
    cfg["parameters"]["bounds"] = {"k4": [2300.0, 2600.0]}
    p2 = os.path.join(os.path.dirname(path), "bounded.yaml")
    yaml.safe_dump(cfg, open(p2, "w"))
    out = tmp_path / "out"
    proc = cli_inproc("run", p2, "--out", out, "--starts", 2)
    assert proc.returncode == 0, proc.stderr
    res = json.load(open(out / "result.json"))
    k4 = next(p for p in res["parameters"] if p["name"] == "k4")
    assert k4["updated"] == pytest.approx(2600.0, rel=1e-3)
    assert k4["at_bound"] == "upper" and k4["standard_error"] is None
    assert k4["standard_error_if_interior"] > 0
    flagged = [f for f in res["flags"] if f["kind"] == "at_bound"]
    assert "k4" in [f["subject"] for f in flagged]
    assert "WARNING (at_bound): k4" in proc.stdout
    assert "n/a (at upper bound)" in (out / "parameters.csv").read_text()
    html = (out / "report.html").read_text()
    assert "at_bound" in html and "the bound is wrong" in html
    interior = [p for p in res["parameters"] if p["name"] in ("k1", "k2", "k3")]
    assert all(p["at_bound"] is None and p["standard_error"] > 0 for p in interior)


def test_iteration_limit_flag_gives_advice():
    from nlp.solve.problem import LocalResult

    def res(f, status, it=20):
        return LocalResult(z=np.zeros(2), f=f, success=status == "Solve_Succeeded",
                           status=status, iterations=it, seconds=0.1, z0=np.zeros(2))
    best = res(1.0, "Solve_Succeeded")
    assert iteration_flag(best, [best, res(2.0, "Maximum_Iterations_Exceeded", 500)],
                          "ipopt") is None
    f = iteration_flag(best, [best, res(0.5, "Maximum_Iterations_Exceeded", 500)], "ipopt")
    assert f["kind"] == "iteration_limit" and "ipopt.max_iter" in f["advice"]
    f = iteration_flag(res(1.0, "Maximum_Iterations_Exceeded"), [], "sqpmethod")
    assert f["subject"] == "best start" and "solver.options.max_iter" in f["advice"]


def test_negative_replay_correlation_is_flagged_as_sign_error():
    t = np.linspace(0, 10, 2001)
    meas = np.sin(2 * np.pi * 1.3 * t) * np.exp(-0.1 * t)
    reps = {"a1": {"quantity": "acceleration", "correlation": float(correlation(-meas, meas))},
            "a2": {"quantity": "acceleration", "correlation": float(correlation(0.9 * meas, meas))}}
    flags = replay_flags(reps)
    assert [f["subject"] for f in flags] == ["a1"]
    assert "sign or unit" in flags[0]["advice"]


# ------------------------------------------------------------- compiled cache
def test_damaged_cached_library_is_rebuilt(tmp_path, monkeypatch):
    from nlp.solve.codegen import compile_library
    import shutil
    if not shutil.which("gcc") and not shutil.which("cc"):
        pytest.skip("no C compiler")
    monkeypatch.setenv("FRF_NLP_CACHE", str(tmp_path))
    x = ca.SX.sym("x", 2)
    f = ca.Function("rel_probe", [x], [ca.sumsqr(x) + 1.0])
    lib = compile_library([f], stem="reltest")
    first = str(tmp_path / "first.so")
    shutil.copy(lib, first)
    assert float(ca.external("rel_probe", first)([3.0, 4.0])) == 26.0
    other = ca.Function("rel_other", [x], [x[0]])
    foreign = compile_library([other], stem="relother")
    for damage in (b"garbage" * 100, open(lib, "rb").read()[:500], open(foreign, "rb").read()):
        tmp = lib + ".new"
        open(tmp, "wb").write(damage)
        os.replace(tmp, lib)  # a new inode, as a user's copy or a crashed writer would leave
        with pytest.warns(UserWarning, match="rebuilding"):
            again = compile_library([f], stem="reltest")
        assert again == lib
        # load the rebuilt file under a new name: the loader caches libraries by name
        fresh = str(tmp_path / f"eval{len(damage)}.so")
        shutil.copy(again, fresh)
        assert float(ca.external("rel_probe", fresh)([1.0, 2.0])) == 6.0


def test_cache_key_separates_values_and_optimisation(tmp_path, monkeypatch):
    """A constant baked into the C (a nominal value) and the -O level are part of the
    cache key; -O0 and -O2 give the same numbers as CasADi's own evaluation."""
    from nlp.solve.codegen import compile_library
    import shutil
    if not shutil.which("gcc") and not shutil.which("cc"):
        pytest.skip("no C compiler")
    monkeypatch.setenv("FRF_NLP_CACHE", str(tmp_path))
    x = ca.SX.sym("x", 2)
    # the same structure with two nominal stiffnesses: k x1^2 + sin(x2) / k
    f1 = ca.Function("key_probe", [x], [1000.0 * x[0] ** 2 + ca.sin(x[1]) / 1000.0])
    f2 = ca.Function("key_probe", [x], [2000.0 * x[0] ** 2 + ca.sin(x[1]) / 2000.0])
    libs = {(k, opt): compile_library([f], stem="keytest", optimize=opt)
            for k, f in ((1, f1), (2, f2)) for opt in (True, False)}
    assert len(set(libs.values())) == 4
    pt = [0.3, 1.1]
    for (k, opt), lib in libs.items():
        fresh = str(tmp_path / f"eval_{k}_{opt}.so")  # the loader caches libraries by name
        shutil.copy(lib, fresh)
        got = float(ca.external("key_probe", fresh)(pt))
        want = 1000.0 * k * 0.09 + math.sin(1.1) / (1000.0 * k)
        assert got == pytest.approx(want, rel=1e-14)
        assert got == float((f1 if k == 1 else f2)(pt))


@pytest.mark.slow
def test_inverted_sensor_is_flagged_by_the_replay(tmp_path):
    """An accelerometer mounted upside down: |H| (the fit) cannot see it, the time-domain
    replay anti-correlates with its record, and the run says: likely a sign or unit error."""
    import yaml
    t, cols, _ = make_shake_table(seed=5)
    cols["acc4"] = -cols["acc4"]
    names = list(cols)
    np.savetxt(tmp_path / "records.csv", np.column_stack([cols[n] for n in names]),
               delimiter=",", header=",".join(names), comments="")
    cfg = yaml.safe_load(open(os.path.join(ROOT, "cases", "four_story_shake_table", "case.yaml")))
    cfg["data"]["channels"] = cfg["data"]["channels"][:4]  # the accelerometers, one update
    cfg.pop("updates")
    yaml.safe_dump(cfg, open(tmp_path / "case.yaml", "w"))
    proc = cli_inproc("run", tmp_path / "case.yaml", "--out", tmp_path / "out", "--starts", 2,
                      "--workers", 1)
    assert proc.returncode == 0, proc.stderr
    s = json.load(open(tmp_path / "out" / "summary.json"))
    assert s["time_domain"]["a4"]["correlation"] < -0.9
    assert all(s["time_domain"][c]["correlation"] > 0.9 for c in ("a1", "a2", "a3"))
    assert [f["subject"] for f in s["flags"] if f["kind"] == "negative_correlation"] == ["a4"]
    assert "WARNING (negative_correlation)" in proc.stdout
    assert "negative_correlation" in (tmp_path / "out" / "report.html").read_text()
