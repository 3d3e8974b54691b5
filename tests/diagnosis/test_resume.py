"""``frf-nlp diagnose --resume``: a diagnosis interrupted after its first round, resumed into
the same folder, writes the diagnosis.json of an uninterrupted one, and takes its baseline
search and round of refits from the checkpoint instead of computing them again."""

import json
import os

import pytest

import nlp.diagnosis.driver as D
from nlp import api
from nlp.diagnosis.checkpoint import checkpoint_dir
from nlp.errors import InputError
from support.diagnosis import coupled_case

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


@pytest.mark.slow  # three diagnoses of a small case: about a minute on 2 cores
def test_resumed_diagnosis_is_the_uninterrupted_one(tmp_path, monkeypatch):
    cfg = _case(tmp_path)
    ref = api.diagnose(cfg, tmp_path / "ref", log=_quiet).data
    assert ref["findings"], ref["summary"]   # the round found something to keep
    assert not os.path.exists(checkpoint_dir(tmp_path / "ref"))   # removed when done

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
    on_disk = json.loads((out / "diagnosis.json").read_text())
    assert _clean(on_disk) == _clean(json.loads((tmp_path / "ref" / "diagnosis.json").read_text()))
    assert not os.path.exists(checkpoint_dir(out))


def test_resume_without_a_checkpoint_is_refused(tmp_path):
    cfg = _case(tmp_path)
    with pytest.raises(InputError, match="--resume"):
        api.diagnose(cfg, tmp_path / "out", resume=True, log=_quiet)
    assert not (tmp_path / "out").exists()
