"""``frf-nlp diagnose --resume``: a diagnosis interrupted after its first round, resumed into
the same folder, writes the diagnosis.json of an uninterrupted one, and takes its baseline
search and round of refits from the checkpoint instead of computing them again."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

import nlp.diagnosis.driver as D
from nlp import api
from nlp.diagnosis.checkpoint import checkpoint_dir
from nlp.errors import InputError
from support.diagnosis import coupled_case
from support.paths import ROOT

DROP = {"provenance", "elapsed", "seconds", "time", "timestamps"}


def _clean(x):
    """diagnosis.json without what differs between two runs of the same diagnosis."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items() if k not in DROP}
    if isinstance(x, list):
        return [_clean(v) for v in x]
    return x


def _case(tmp_path):
    """One round of candidates finds the 900 N/m spring between floors 1 and 3."""
    return coupled_case(tmp_path)


def _quiet(*_):
    pass


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The case and its uninterrupted diagnosis.json."""
    folder = tmp_path_factory.mktemp("resume")
    cfg = _case(folder)
    ref = api.diagnose(cfg, folder / "ref", log=_quiet).data
    assert ref["findings"], ref["summary"]   # the round found something to keep
    assert not os.path.exists(checkpoint_dir(folder / "ref"))   # removed when done
    return cfg, ref


@pytest.mark.slow  # three diagnoses of a small case: about a minute on 2 cores
def test_resumed_diagnosis_is_the_uninterrupted_one(tmp_path, monkeypatch, uninterrupted):
    cfg, ref = uninterrupted

    calls = {"search": 0, "refits": 0}
    search, refit_all, inside = D.scatter_best, D.refit_all, D.inside_model_class
    monkeypatch.setattr(D, "scatter_best", lambda *a, **kw: calls.__setitem__(
        "search", calls["search"] + 1) or search(*a, **kw))
    monkeypatch.setattr(D, "refit_all", lambda *a: calls.__setitem__(
        "refits", calls["refits"] + 1) or refit_all(*a))

    def interrupt(*a, **kw):   # Ctrl-C once the first round is done (checks stage)
        raise KeyboardInterrupt

    out = tmp_path / "out"
    monkeypatch.setattr(D, "inside_model_class", interrupt)
    with pytest.raises(KeyboardInterrupt):
        api.diagnose(cfg, out, log=_quiet)
    assert not out.exists()                                   # nothing half-written
    kept = sorted(os.listdir(checkpoint_dir(out)))
    assert [n[4:] for n in kept if n.endswith(".pkl")][:2] == ["baseline.pkl", "levels.pkl"]
    assert "refits.pkl" in [n[4:] for n in kept]
    assert calls == {"search": 1, "refits": 1}

    monkeypatch.setattr(D, "inside_model_class", inside)
    lines = []
    res = api.diagnose(cfg, out, resume=True, log=lines.append).data
    assert calls == {"search": 1, "refits": 1}                # both taken from the checkpoint
    assert any(line.startswith("resumed: ") for line in lines)
    assert _clean(res) == _clean(ref)
    assert _clean(json.loads((out / "diagnosis.json").read_text())) == _clean(ref)
    assert not os.path.exists(checkpoint_dir(out))


def _command(cfg, out, *extra):
    """``frf-nlp diagnose`` in a subprocess that takes SIGINT as a terminal's Ctrl-C does
    (a shell's background job would ignore it)."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-m", "nlp", "diagnose", cfg.path, "--out", str(out),
                             *extra], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


@pytest.mark.slow  # two diagnoses of a small case in subprocesses: about a minute
def test_ctrl_c_then_resume_on_the_command_line(tmp_path, uninterrupted):
    """SIGINT once the baseline search is in the checkpoint: exit status 130, no output
    folder; ``--resume`` then writes the uninterrupted diagnosis.json."""
    cfg, ref = uninterrupted
    out = tmp_path / "out"
    proc = _command(cfg, out)
    folder = checkpoint_dir(out)
    deadline = time.monotonic() + 600
    while not (os.path.isdir(folder) and any(f.endswith("baseline.pkl") for f in os.listdir(folder))):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "continue with --resume" in stdout and "Traceback" not in stderr
    assert not out.exists()
    resumed = _command(cfg, out, "--resume")
    stdout, stderr = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, stderr
    assert "resumed: " in stdout
    assert _clean(json.loads((out / "diagnosis.json").read_text())) == _clean(ref)


def test_resume_without_a_checkpoint_is_refused(tmp_path):
    cfg = _case(tmp_path)
    with pytest.raises(InputError, match="--resume"):
        api.diagnose(cfg, tmp_path / "out", resume=True, log=_quiet)
    assert not (tmp_path / "out").exists()


@pytest.mark.slow  # two diagnoses of a small case: about half a minute on 2 cores
def test_a_spent_budget_stops_the_search_and_resume_goes_on(tmp_path, uninterrupted):
    """A budget spent before the first round: no candidate is tried, the verdict does not
    call the model adequate, the result says where it stopped, and the steps stay; resumed
    without a budget, the diagnosis is the uninterrupted one."""
    cfg, ref = uninterrupted
    out = tmp_path / "out"
    lines = []
    res = api.diagnose(cfg, out, log=lines.append, budget=1e-9).data
    assert res["budget"]["stopped_before"][0] == "selection round 1"
    assert not res["findings"] and res["verdict"] == "ambiguous"
    assert any("time budget" in s for s in res["summary"])
    assert any("--budget" in s for s in res["suggested_measurements"])
    assert os.path.isdir(checkpoint_dir(out))
    assert any("stopped at its time budget" in line for line in lines)
    again = api.diagnose(cfg, out, resume=True, log=_quiet).data
    assert "budget" not in again
    assert _clean(again) == _clean(ref)
    assert not os.path.exists(checkpoint_dir(out))
