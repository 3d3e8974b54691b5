"""Batch updating and change detection (issue 10, monitoring).

The change detector is checked on series with known steps and known nulls;
the batch command on records made by nlp.testing.monitoring, a simulator
that shares no code with the package's FRF code.
"""

import json
import os
import re

import numpy as np
import pytest

from nlp.monitoring.campaign import find_records, record_time
from nlp.monitoring.changes import detect_changes
from nlp.cli import main
from nlp.testing.monitoring import write_campaign
from support.paths import CASES


def test_no_false_alarm_on_noise_drift_and_daily_cycle():
    rng = np.random.default_rng(0)
    n = 120
    t = np.arange(n)
    alarms = 0
    for _ in range(100):
        x = (rng.standard_normal(n) + 2.0 * np.sin(2 * np.pi * t / 4 + rng.uniform(0, 6))
             + 3.0 * t / n)  # noise, a daily cycle twice as large, a slow drift
        alarms += bool(detect_changes(x, window=10))
    assert alarms <= 2


def test_step_found_at_its_record():
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(50):
        x = rng.standard_normal(120)
        x[70:] -= 5.0  # 5 standard deviations
        ch = detect_changes(x, window=10)
        hits += len(ch) == 1 and abs(ch[0].index - 70) <= 1
        if ch:
            assert ch[0].after - ch[0].before == pytest.approx(-5.0, abs=1.0)
    assert hits >= 47


def test_two_steps_and_standard_error_floor():
    rng = np.random.default_rng(2)
    x = 0.1 * rng.standard_normal(150)
    x[50:] += 3.0
    x[110:] -= 2.0
    ch = detect_changes(x, window=8)
    assert [c.index for c in ch] == [50, 110]
    # the same history with standard errors far above its scatter: no step is beyond them
    assert detect_changes(x, se=np.full(150, 5.0), window=8) == []


def test_record_time_from_npz_and_name(tmp_path):
    p = tmp_path / "r.npz"
    np.savez(p, f=np.arange(3.0), H=np.ones((1, 3)), timestamp="2026-03-01T06:00")
    assert record_time(str(p)) == "2026-03-01T06:00"
    q = tmp_path / "acc_20260302_1830.csv"
    q.write_text("t,a\n0,1\n")
    assert record_time(str(q)) == "2026-03-02T18:30"
    assert record_time(str(tmp_path / "plain.csv")) is None


def test_find_records_refuses_what_matches_nothing(tmp_path):
    from nlp.errors import InputError

    (tmp_path / "a.npz").write_bytes(b"")
    (tmp_path / "notes.md").write_text("x")
    assert find_records([str(tmp_path)]) == [str(tmp_path / "a.npz")]
    with pytest.raises(InputError, match="RECORDS"):
        find_records([str(tmp_path / "*.mat")])


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """30 records from the independent simulator; story 2 loses 8 % at record 20."""
    case_dir = tmp_path_factory.mktemp("monitoring")
    write_campaign(str(case_dir), records=30, change=20)
    truth = json.loads((case_dir / "truth.json").read_text())
    src = open(os.path.join(CASES, "monitoring", "case.yaml")).read()
    first = truth["records"][0]["file"]
    (case_dir / "case.yaml").write_text(re.sub(r"file: records/\S+", f"file: records/{first}", src))
    return case_dir, truth


@pytest.mark.slow  # a campaign of updates: ~15 s
def test_batch_finds_the_stiffness_drop(campaign, tmp_path):
    case_dir, truth = campaign
    out = tmp_path / "out"
    rc = main(["batch", str(case_dir / "case.yaml"), str(case_dir / "records"),
               "--out", str(out), "--workers", "2", "--starts", "3"])
    assert rc == 0
    res = json.loads((out / "changes.json").read_text())
    assert res["records"] == 30 and not res["failed"]
    moved = {nm: c for nm, c in res["changes"].items() if c}
    assert list(moved) == ["k2"], moved
    (c,) = moved["k2"]
    assert abs(c["index"] - 20) <= 1
    k_true = np.array([r["stiffnesses"][1] for r in truth["records"]])
    true_rel = np.median(k_true[20:]) / np.median(k_true[:20]) - 1
    assert c["relative_change"] == pytest.approx(true_rel, abs=0.01)
    assert (out / "trend.png").stat().st_size > 1000
    assert "k2" in (out / "report.html").read_text()
    hist = (out / "history.csv").read_text().splitlines()
    assert len(hist) == 31 and hist[0].startswith("record,time,status,objective")


@pytest.mark.slow
def test_batch_resume_updates_only_the_rest(campaign, tmp_path, capsys):
    case_dir, _ = campaign
    out = tmp_path / "out"
    recs = sorted(str(p) for p in (case_dir / "records").glob("*.npz"))
    args = ["batch", str(case_dir / "case.yaml"), *recs[:12], "--out", str(out), "--starts", "3"]
    assert main(args) == 0
    first = (out / "history.csv").read_text().splitlines()
    assert main(args[:2] + recs[:16] + args[-4:] + ["--resume"]) == 0
    log = capsys.readouterr().out
    assert "16 records (12 already done)" in log
    again = (out / "history.csv").read_text().splitlines()
    assert again[:13] == first and len(again) == 17


def _history(out):
    rows = [ln.split(",") for ln in (out / "history.csv").read_text().splitlines()[1:]]
    return {r[0]: r[3:] for r in rows}


@pytest.mark.slow
def test_batch_same_answer_on_every_executor(campaign, tmp_path):
    """1 worker, the local pool and a Dask LocalCluster of 2 give the same history."""
    pytest.importorskip("distributed")
    case_dir, _ = campaign
    recs = sorted(str(p) for p in (case_dir / "records").glob("*.npz"))[:6]
    runs = {}
    for tag, extra in (("one", ["--workers", "1"]), ("pool", ["--workers", "2"]),
                       ("dask", ["--executor", "dask", "--workers", "2"])):
        out = tmp_path / tag
        assert main(["batch", str(case_dir / "case.yaml"), *recs, "--out", str(out),
                     "--starts", "3", *extra]) == 0
        runs[tag] = _history(out)
    assert runs["one"] == runs["pool"] == runs["dask"]
