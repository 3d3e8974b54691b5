"""Never a silently wrong answer: impossible inputs are refused before solving (exit 2,
one line naming file and key, no traceback, nothing created or changed in --out)."""

import os

import numpy as np
import pytest
import yaml

from nlp.case.load import load_case
from nlp.errors import InputError
from nlp.testing.four_story import make
from support.cases import write_case
from support.cli import cli, cli_inproc, snapshot
from support.frames import shear_K


def assert_refused(proc, file, key, out, before):
    """exit 2, one line naming file and key, no traceback, --out as before."""
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert os.path.basename(str(file)) in lines[0], lines[0]
    assert f"'{key}'" in lines[0], lines[0]
    assert "np.float64" not in lines[0]
    assert snapshot(out) == before
    return lines[0]


@pytest.fixture
def case_dir(tmp_path):
    def make(**changes):
        d = tmp_path / "case"
        path, truth = write_case(str(d), **changes)
        return d, path, truth
    return make


def refused(case_path, tmp_path, file, key, existing=False, command="run", subprocess=False):
    out = str(tmp_path / "out")
    if existing:  # a previous result that must not change
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, "result.json"), "w") as fh:
            fh.write('{"old": true}\n')
    before = snapshot(out)
    proc = (cli if subprocess else cli_inproc)(command, case_path, "--out", out)
    return assert_refused(proc, file, key, out, before)


# ------------------------------------------------------------------ broken files
@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated", b"\x00\x01garbage" * 50])
def test_broken_npz_is_an_input_error(case_dir, tmp_path, content):
    d, path, _ = case_dir()
    open(d / "frf.npz", "wb").write(content)
    refused(path, tmp_path, d / "frf.npz", "<file>")


def test_truncated_npz(case_dir, tmp_path):
    d, path, _ = case_dir()
    good = open(d / "frf.npz", "rb").read()
    open(d / "frf.npz", "wb").write(good[: len(good) // 2])
    refused(path, tmp_path, d / "frf.npz", "<file>", existing=True)


def test_binary_file_given_as_yaml(tmp_path):
    p = tmp_path / "case.yaml"
    p.write_bytes(bytes(range(256)) * 4)
    refused(str(p), tmp_path, p, "<file>", subprocess=True)


def test_yaml_exponent_without_dot_is_a_number(case_dir):
    d, path, _ = case_dir()
    text = open(path).read().replace("- 2473", "- 2.473e3")
    assert "2.473e3" in text
    open(path, "w").write(text)
    assert load_case(path).model.stiffnesses[3] == 2473.0


def test_messages_print_plain_numbers():
    msg = str(InputError("f.yaml", "k", "x", [np.float64(1019.0), np.int64(3)]))
    assert msg.endswith("got [1019.0, 3]")


# ------------------------------------------------------------------ impossible cases
def test_total_mass_below_the_fixed_masses(case_dir, tmp_path):
    _, path, _ = case_dir(parameters={"fixed": {"m1": 5.16, "m2": 5.15}, "total_mass": 8.0})
    line = refused(path, tmp_path, path, "parameters.total_mass", existing=True)
    # reachable range: 5.16 + 5.15 + 2 * 4.64 * (1 - 0.5) .. + 2 * 4.64 * 2
    assert "14.95" in line and "28.87" in line


def test_total_mass_beyond_the_mass_bounds(case_dir, tmp_path):
    # free masses at most 4.64 * 1.1 each: 5.16 + 3 * 5.104 = 20.472 < 25
    _, path, _ = case_dir(parameters={"fixed": {"m1": 5.16}, "mass_bounds": [-0.2, 0.1],
                                      "total_mass": 25.0})
    line = refused(path, tmp_path, path, "parameters.total_mass")
    assert "20.472" in line


def test_points_outside_the_data(case_dir, tmp_path):
    _, path, _ = case_dir(frequencies={"method": "points", "points": [2.0, 40.0, 50.0]})
    refused(path, tmp_path, path, "frequencies.points[1]")


def test_too_few_points_for_the_free_parameters(case_dir, tmp_path):
    # 2 points x 4 channels = 8 residuals for 17 free parameters (7 stiffness/mass + 10 of L)
    _, path, _ = case_dir(frequencies={"method": "points", "points": [2.0, 3.0]})
    line = refused(path, tmp_path, path, "frequencies.points", existing=True)
    assert "17 free parameters" in line and "8 residuals" in line


def test_no_free_parameter(case_dir, tmp_path):
    fixed = {f"m{i}": 4.64 for i in range(1, 5)}
    fixed.update({f"k{i}": k for i, k in enumerate([1019, 1217, 1420, 2473], 1)})
    fixed.update({"a0": 0.1, "a1": 0.001})
    _, path, _ = case_dir(parameters={"fixed": fixed}, damping={"model": "rayleigh", "zeta": 0.02})
    refused(path, tmp_path, path, "parameters.fixed")


def _matrix_case(case_dir, **arrays):
    d, path, _ = case_dir()
    k = np.array([1019.0, 1217, 1420, 2473])
    Ki = [shear_K(k * np.eye(4)[r]) for r in range(4)]
    Mi = [np.diag(4.64 * np.eye(4)[r]) for r in range(4)]
    mats = {"M0": np.diag([4.64] * 4), "K0": shear_K(k), "M_infl": np.array(Mi),
            "K_infl": np.array(Ki), "beta_names": np.array(["m1", "m2", "m3", "m4"]),
            "alpha_names": np.array(["k1", "k2", "k3", "k4"])}
    mats.update(arrays)
    np.savez(d / "model.npz", **mats)
    cfg = yaml.safe_load(open(path))
    cfg["model"] = {"type": "matrices", "file": "model.npz"}
    yaml.safe_dump(cfg, open(path, "w"))
    return d, path


def test_non_symmetric_K0_names_the_model_file(case_dir, tmp_path):
    K0 = shear_K([1019.0, 1217, 1420, 2473])
    K0[0, 1] += 50.0
    d, path = _matrix_case(case_dir, K0=K0)
    refused(path, tmp_path, d / "model.npz", "K0")


def test_non_symmetric_influence_matrix(case_dir, tmp_path):
    Ki = np.array([shear_K(np.array([1019.0, 1217, 1420, 2473]) * np.eye(4)[r]) for r in range(4)])
    Ki[2, 1, 2] += 10.0
    d, path = _matrix_case(case_dir, K_infl=Ki)
    refused(path, tmp_path, d / "model.npz", "K_infl[2]", existing=True)


def test_indefinite_K0(case_dir, tmp_path):
    d, path = _matrix_case(case_dir, K0=np.diag([1000.0, -5.0, 1000.0, 1000.0]))
    refused(path, tmp_path, d / "model.npz", "K0")


def test_name_count_mismatch_names_the_names_key(case_dir, tmp_path):
    d, path = _matrix_case(case_dir, beta_names=np.array(["m1", "m2", "m3"]))
    refused(path, tmp_path, d / "model.npz", "beta_names")


def test_dead_channel_names_its_column(case_dir, tmp_path):
    f, H, _ = make(seed=0, noise=0.0)
    H = H.copy()
    H[2] = 0.0
    d, path, _ = case_dir(f=f, H=H)
    line = refused(path, tmp_path, d / "frf.npz", "column 2", existing=True, subprocess=True)
    assert "floor3" in line


def test_zero_value_gives_an_error_naming_the_channel(case_dir, tmp_path):
    f, H, _ = make(seed=0, noise=0.0)
    H = H.copy()
    k = int(np.argmin(np.abs(f - 3.0)))
    H[1, k] = 0.0
    d, path, _ = case_dir(f=f, H=H)
    line = refused(path, tmp_path, path, "data.channels[1]")
    assert "floor2" in line


def _records_case(tmp_path, ag, acc):
    d = tmp_path / "rec"
    d.mkdir()
    t = np.arange(ag.size) / 100.0
    cols = np.column_stack([t, ag, *acc])
    np.savetxt(d / "rec.csv", cols, delimiter=",", header="t,ag,a1,a2", comments="")
    cfg = {"model": {"type": "shear_frame", "masses": [5.0, 5.0], "stiffnesses": [1000, 1000]},
           "parameters": {"fixed": {"m1": 5.0}},
           "data": {"type": "time_histories", "file": "rec.csv", "nperseg": 256,
                    "input": {"column": "ag", "quantity": "ground_acceleration", "unit": "g"},
                    "channels": [{"name": "x1", "floor": 1, "quantity": "acceleration",
                                  "unit": "g", "column": "a1"},
                                 {"name": "x2", "floor": 2, "quantity": "acceleration",
                                  "unit": "g", "column": "a2"}]},
           "frequencies": {"method": "all", "fmin": 0.5, "fmax": 20}}
    yaml.safe_dump(cfg, open(d / "case.yaml", "w"))
    return d, str(d / "case.yaml")


def test_constant_input_names_the_input_column(tmp_path):
    rng = np.random.default_rng(0)
    n = 4096
    d, path = _records_case(tmp_path, np.full(n, 0.1), rng.standard_normal((2, n)))
    line = refused(path, tmp_path, d / "rec.csv", "ag")
    assert "data.input.column" in line


def test_dead_output_record_names_its_column(tmp_path):
    rng = np.random.default_rng(0)
    n = 4096
    d, path = _records_case(tmp_path, rng.standard_normal(n), [rng.standard_normal(n), np.zeros(n)])
    refused(path, tmp_path, d / "rec.csv", "a2")


def test_incoherent_output_is_refused(tmp_path):
    # an output of pure noise, unrelated to the input: H1 coherence ~ 1/n_averages everywhere
    rng = np.random.default_rng(1)
    n = 8192
    d, path = _records_case(tmp_path, rng.standard_normal(n), rng.standard_normal((2, n)))
    line = refused(path, tmp_path, d / "rec.csv", "a1")
    assert "coheren" in line


def test_nperseg_mistake_names_the_case_key(tmp_path):
    rng = np.random.default_rng(0)
    d, path = _records_case(tmp_path, rng.standard_normal(500), rng.standard_normal((2, 500)))
    cfg = yaml.safe_load(open(path))
    cfg["data"]["nperseg"] = 100000
    yaml.safe_dump(cfg, open(path, "w"))
    refused(path, tmp_path, path, "data.nperseg")


def test_unit_mistake_names_the_case_key(tmp_path):
    rng = np.random.default_rng(0)
    d, path = _records_case(tmp_path, rng.standard_normal(500), rng.standard_normal((2, 500)))
    cfg = yaml.safe_load(open(path))
    cfg["data"]["channels"][1]["unit"] = "mm"  # a displacement unit for an acceleration
    yaml.safe_dump(cfg, open(path, "w"))
    refused(path, tmp_path, path, "data.channels[1].unit")


def test_no_peak_names_a_real_key(tmp_path):
    rng = np.random.default_rng(0)
    n = 4096
    x = rng.standard_normal(n)
    d, path = _records_case(tmp_path, x, [0.5 * x + 0.01 * rng.standard_normal(n),
                                          0.3 * x + 0.01 * rng.standard_normal(n)])
    cfg = yaml.safe_load(open(path))
    cfg["frequencies"] = {"method": "half_power"}
    yaml.safe_dump(cfg, open(path, "w"))
    refused(path, tmp_path, path, "frequencies.method")


# ------------------------------------------------------------------ --out checked first
def test_out_that_is_a_file(case_dir, tmp_path):
    _, path, _ = case_dir()
    out = tmp_path / "out"
    out.write_text("not a folder\n")
    for command in ("run", "diagnose"):
        proc = cli_inproc(command, path, "--out", out)
        assert proc.returncode == 2 and "'--out'" in proc.stderr and "Traceback" not in proc.stderr
        assert out.read_text() == "not a folder\n"
        assert sorted(os.listdir(tmp_path)) == ["case", "out"]


def test_read_only_out_is_refused_before_any_work(case_dir, tmp_path):
    _, path, _ = case_dir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    os.chmod(out, 0o555)
    try:
        before = snapshot(str(out))
        proc = cli("run", path, "--out", out, "--starts", 50)
        assert_refused(proc, out, "--out", str(out), before)
        assert "read-only" in proc.stderr
    finally:
        os.chmod(out, 0o755)


def test_out_below_a_file(case_dir, tmp_path):
    _, path, _ = case_dir()
    (tmp_path / "afile").write_text("x")
    proc = cli_inproc("run", path, "--out", tmp_path / "afile" / "out")
    assert proc.returncode == 2 and "'--out'" in proc.stderr and "Traceback" not in proc.stderr


def test_report_of_a_missing_folder(tmp_path):
    proc = cli_inproc("report", tmp_path / "nothing")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert not (tmp_path / "nothing").exists()
