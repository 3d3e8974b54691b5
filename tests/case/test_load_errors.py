"""Each kind of bad input gets one clear message naming file and key; exit code 2."""

import os

import numpy as np
import pytest
import yaml

from support.cases import BASE, deep_update, write_case
from nlp.case.assemble import assemble
from nlp.cli import main
from nlp.case.load import load_case
from nlp.errors import InputError


def _write(tmp_path, cfg):
    path = os.path.join(str(tmp_path), "case.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    return path


@pytest.fixture
def folder(tmp_path):
    write_case(str(tmp_path))  # frf.npz beside the case
    return tmp_path


BAD = [
    # (change, key named in the message, words expected in the message)
    ({"model": {"masses": None}}, "model.masses", "kg"),
    ({"model": {"masses": [4.64, 4.64, 4.64]}}, "model.stiffnesses", "one per story"),
    ({"model": {"masses": [4.64, -1, 4.64, 4.64]}}, "model.masses[1]", "> 0"),
    ({"parameters": {"stiffness_bounds": [0.5, -0.2]}}, "parameters.stiffness_bounds", "lower < upper"),
    ({"model": {"masses": [4.64, float("nan"), 4.64, 4.64]}}, "model.masses[1]", "finite"),
    ({"solver": {"name": "fmincon"}}, "solver.name", "ipopt"),
    ({"data": {"file": "frf.npz", "channels": [{"name": "x", "floor": 1, "output": "strain"}]}},
     "data.channels[0].output", "receptance"),
    ({"data": {"file": "missing.npz", "channels": []}}, "data.file", "existing file"),
    ({"objective": {"residual": "cubic"}}, "objective.residual", "log_magnitude"),
    ({"parameters": {"fixed": {"m9": 5.0}}}, "parameters.fixed.m9", "parameter name"),
    ({"excitation": {"type": "force"}}, "excitation.floor", "required"),
    ({"search": {"starts": 0}}, "search.starts", "> 0"),
    ({"parameters": {"prior": {"masses": -0.1}}}, "parameters.prior.masses", "> 0"),
    ({"parameters": {"prior": {"m9": 0.1}}}, "parameters.prior.m9", "parameter name"),
    ({"unknown_section": 1}, "unknown_section", "known keys"),
]


@pytest.mark.parametrize("change,key,words", BAD)
def test_bad_case_file_message(folder, change, key, words):
    path = _write(folder, deep_update(BASE, change))
    with pytest.raises(InputError) as ei:
        assemble(load_case(path))
    msg = str(ei.value)
    assert path in msg and f"'{key}'" in msg and words in msg, msg


def test_bad_data_shapes(folder):
    chans = [{"name": "a", "floor": 1, "output": "receptance", "column": 7}]
    path = _write(folder, deep_update(BASE, {"data": {"file": "frf.npz", "window": "none", "channels": chans}}))
    with pytest.raises(InputError, match=r"data.channels\[0\].column"):
        assemble(load_case(path))
    np.savez(os.path.join(folder, "bad.npz"), f=np.arange(5.0), H=np.ones((4, 6)))
    path = _write(folder, deep_update(BASE, {"data": {"file": "bad.npz"}}))
    with pytest.raises(InputError, match="bad.npz"):
        assemble(load_case(path))
    H = np.ones((4, 5), complex)
    H[2, 3] = np.nan
    np.savez(os.path.join(folder, "nan.npz"), f=np.arange(1.0, 6.0), H=H)
    path = _write(folder, deep_update(BASE, {"data": {"file": "nan.npz"}}))
    with pytest.raises(InputError, match="finite"):
        assemble(load_case(path))


def test_unknown_solver_option_is_named(folder):
    path = _write(folder, deep_update(BASE, {"solver": {"name": "sqpmethod",
                                                        "options": {"tolerance": 1}}}))
    from nlp.case.assemble import build_problem
    with pytest.raises(InputError, match="solver.options.*tolerance"):
        build_problem(assemble(load_case(path)))


def test_cli_bad_input_exits_2_without_traceback(folder, capsys):
    path = _write(folder, deep_update(BASE, {"model": {"masses": [4.64, 0, 4.64, 4.64]}}))
    assert main(["run", path, "--out", str(folder / "out")]) == 2
    err = capsys.readouterr().err
    assert "model.masses[1]" in err and "Traceback" not in err
    assert main(["run", str(folder / "nope.yaml")]) == 2
    assert main(["run", path, "--solver", "newton"]) == 2


def test_diagnose_cli_bad_input_exits_2(folder, capsys):
    path = _write(folder, deep_update(BASE, {"frequencies": {"method": "wavelet"}}))
    assert main(["diagnose", path, "--out", str(folder / "d")]) == 2
    err = capsys.readouterr().err
    assert "frequencies.method" in err and "Traceback" not in err
