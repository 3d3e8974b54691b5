"""Field inputs, each from a file written the way instruments and scripts write them:
magnitude-only dB exports, headerless .dat files with a preamble, volts with a sensitivity and a
flipped sensor, a force measured as mass x acceleration, MATLAB complex numbers, several records
averaged, and records with spikes and dropouts. Records come from scipy.signal.lsim (not the
package's simulator); the truth is the simulated model."""

import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import signal

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.io.readers import G, read_frf, read_time_histories
from nlp.output.results import summarize
from nlp.solve.search import SearchConfig, scatter_search

ROOT = Path(__file__).resolve().parents[2]
M_TRUE = np.array([3.0, 2.5])       # kg
K_TRUE = np.array([12000.0, 9000.0])  # N/m
FS = 200.0                          # Hz
M_AMD = 20.0                        # kg: the reaction mass whose acceleration gives the force


def _update(case_path, starts=4, options=None):
    """Updated value and standard error of every mass and stiffness."""
    cfg = load_case(case_path, {"starts": starts, "workers": 1, "seed": 0, "solver": None})
    if options:
        cfg = replace(cfg, solver=replace(cfg.solver, options=options))
    case = assemble(cfg)
    problem = build_problem(case)
    res = summarize(case, problem, scatter_search(problem, SearchConfig(starts=starts)))
    # a parameter on a bound has no standard error (flag at_bound); compare with the
    # Gauss-Newton value it would have inside
    return case, {p["name"]: (p["updated"], p["standard_error"] if p["standard_error"] is not None
                              else p["standard_error_if_interior"])
                  for p in res["parameters"] if p["group"] in ("mass", "stiffness")}


def _agree(a, b, n_se=1.0):
    for name, (va, sa) in a.items():
        vb, sb = b[name]
        assert abs(va - vb) <= n_se * max(sa, sb) + 1e-9 * abs(va), (name, va, vb, sa, sb)


# ------------------------------------------------------------------ magnitude only
def test_magnitude_only_cristallo_updates_to_the_complex_model(tmp_path):
    """The dB export (no phase) of the Cristallo frame gives the complex case's model within
    its standard errors; FRAC and MAC are not computed from it (they need phase)."""
    # IPOPT creeps along a weakly determined damping direction on these real data and stops
    # at max_iter: accept its acceptable level, and solve both from the same start (the
    # nominal model) so both land in the same basin
    opts = {"acceptable_tol": 0.1, "acceptable_iter": 3, "acceptable_obj_change_tol": 1e-6}
    _, complex_ = _update(ROOT / "cases/cristallo_three_storey/case.yaml", 1, opts)
    case, mag = _update(ROOT / "cases/cristallo_three_storey_magnitude/case.yaml", 1, opts)
    assert not case.has_phase and np.all(case.H.imag == 0)
    _agree(mag, complex_)


def test_db_export_with_reference_and_header_reads_back(tmp_path):
    f = np.linspace(1, 50, 50)
    H = 1e-3 * (1 + f) * np.exp(1j * f / 10)
    ref = 1e-6  # dB re 1 micro-unit
    rows = ["# analyser export", "Freq(Hz),Ch1(dB re 1e-6 m/N)"]
    rows += [f"{fi:.6g},{20 * np.log10(abs(h) / ref):.6f}" for fi, h in zip(f, H)]
    (tmp_path / "mag.csv").write_text("\n".join(rows) + "\n")
    f2, H2 = read_frf(tmp_path / "mag.csv", fmt="db_magnitude", db_reference=ref)
    np.testing.assert_allclose(f2, f)
    np.testing.assert_allclose(H2[0].real, np.abs(H), rtol=1e-6)
    assert np.all(H2.imag == 0)


def test_magnitude_only_case_refuses_the_complex_residual(tmp_path):
    raw = yaml.safe_load((ROOT / "cases/cristallo_three_storey_magnitude/case.yaml").read_text())
    raw["objective"]["residual"] = "complex"
    raw["data"]["file"] = str(ROOT / "cases/cristallo_three_storey_magnitude/Experimental_dB.txt")
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(raw))
    with pytest.raises(Exception, match="objective.residual.*no phase"):
        load_case(tmp_path / "c.yaml")


# ------------------------------------------------------------------ MATLAB complex
def test_matlab_complex_literals(tmp_path):
    """writematrix([f.' H.'], 'h.csv') writes 1.5+2.25i (and 3-0.5i, -0i)."""
    f = np.array([1.0, 2.0, 3.0])
    H = np.array([[1.5 + 2.25j, 3 - 0.5j, -1e-3 - 4e5j], [2j, -1.0, 0.5 + 0j]])
    lines = []
    for i, fi in enumerate(f):
        toks = [f"{fi:g}"] + [f"{h.real:g}{h.imag:+g}i" for h in H[:, i]]
        lines.append(",".join(toks))
    (tmp_path / "h.csv").write_text("\n".join(lines) + "\n")
    f2, H2 = read_frf(tmp_path / "h.csv")
    np.testing.assert_allclose(f2, f)
    np.testing.assert_allclose(H2, H, rtol=1e-12)
    (tmp_path / "s.txt").write_text("1 1+2i\n2 1.0000 + 2.0000i\n")  # MATLAB's display, one column
    with pytest.raises(Exception, match="MATLAB"):
        read_frf(tmp_path / "s.txt")


# ------------------------------------------------------------------ records
def _simulate(n, seed, force_dof=1):
    """Absolute accelerations [m/s^2] of a 2-storey shear frame driven by a random force at
    floor ``force_dof + 1`` (scipy.signal.lsim)."""
    m, k = M_TRUE, K_TRUE
    M = np.diag(m)
    K = np.array([[k[0] + k[1], -k[1]], [-k[1], k[1]]])
    C = 0.002 * K + 0.5 * M
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ C]])
    b = np.zeros(2)
    b[force_dof] = 1.0
    B = np.concatenate([np.zeros(2), Mi @ b])[:, None]
    Cy = np.hstack([-Mi @ K, -Mi @ C])
    Dy = (Mi @ b)[:, None]
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    F = signal.lfilter(*signal.butter(4, 40 / (FS / 2)), 20 * rng.normal(size=n))
    _, y, _ = signal.lsim((A, B, Cy, Dy), F, t)
    y = y + 0.002 * np.std(y, axis=0) * rng.normal(size=y.shape)
    return t, F, y.T


def _write_dat(path, t, F, acc, sens=(0.1, 0.1)):
    """A headerless data-logger file: a 3-line preamble, whitespace columns
    time [s], reaction-mass acceleration [g], floor accelerometers [V] at ``sens`` V/g,
    the second mounted upside down."""
    volts = [acc[0] / G * sens[0], -acc[1] / G * sens[1]]
    table = np.column_stack([t, F / M_AMD / G] + volts)
    with open(path, "w") as fh:
        fh.write("LOGGER 7 serial 0042\nstart 2026-11-21 10:00:00\nunits s g V V\n")
        np.savetxt(fh, table, fmt="%.6f %.8e %.8e %.8e")


def _records_case(folder, files, screen=None):
    """A case reading the headerless records: named time column, volts -> g, a flipped
    sensor, force = reaction mass x its acceleration, force at floor 2."""
    data = {
        "type": "time_histories",
        "columns": ["time_s", "a_amd", "v1", "v2"],
        "skip_rows": 3,
        "time_column": "time_s",
        "input": {"quantity": "force", "floor": 2,
                  "from": {"column": "a_amd", "mass": M_AMD, "unit": "g"}},
        "channels": [
            {"name": "a1", "floor": 1, "quantity": "acceleration", "column": "v1",
             "unit": "g", "scale": 10.0},
            {"name": "a2", "floor": 2, "quantity": "acceleration", "column": "v2",
             "unit": "g", "scale": 10.0, "sign": -1}],
        "nperseg": 1024,
    }
    if len(files) == 1:
        data["file"] = files[0]
    else:
        data["records"] = list(files)
    if screen:
        data["screen"] = screen
    raw = {"name": "amd_frame",
           "model": {"type": "shear_frame", "masses": [2.5, 2.5], "stiffnesses": [10000, 10000]},
           "damping": {"model": "general", "zeta": 0.02},
           "data": data,
           "frequencies": {"method": "half_power", "k": 2.0, "fmin": 2.0, "fmax": 40.0},
           "objective": {"residual": "log_magnitude"},
           "search": {"starts": 4}}
    path = os.path.join(folder, f"case_{len(files)}_{bool(screen)}.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(raw, fh)
    return path


@pytest.fixture(scope="module")
def amd_records(tmp_path_factory):
    folder = tmp_path_factory.mktemp("amd")
    t, F, acc = _simulate(16384, seed=3, force_dof=1)
    _write_dat(folder / "run1.dat", t, F, acc)
    t2, F2, acc2 = _simulate(8192, seed=4, force_dof=1)
    _write_dat(folder / "run2.dat", t2, F2, acc2)
    return folder, (t, F, acc)


def test_headerless_logger_file_with_calibration_and_mass_times_acceleration(amd_records):
    folder, (t, F, acc) = amd_records
    rec = read_time_histories(
        folder / "run1.dat",
        {"force": {"from": {"column": "a_amd", "mass": M_AMD, "unit": "g"}},
         "a1": {"column": "v1", "unit": "g", "scale": 10.0, "quantity": "acceleration"},
         "a2": {"column": "v2", "unit": "g", "scale": 10.0, "sign": -1, "quantity": "acceleration"}},
        columns=["time_s", "a_amd", "v1", "v2"], time_column="time_s", skip_rows=3)
    assert rec.fs == pytest.approx(FS)
    # the file holds 9 significant digits: compare at that precision
    np.testing.assert_allclose(rec.data["force"], F, rtol=1e-7, atol=1e-7 * np.abs(F).max())
    for i, ch in enumerate(("a1", "a2")):
        np.testing.assert_allclose(rec.data[ch], acc[i], rtol=1e-7, atol=1e-7 * np.abs(acc[i]).max())


def test_sampling_rate_instead_of_a_time_column(tmp_path):
    x = np.random.default_rng(0).normal(size=(200, 2))
    np.savetxt(tmp_path / "r.txt", x)  # numpy's default: no header, spaces
    rec = read_time_histories(tmp_path / "r.txt", {"a": "c0", "b": "c1"}, fs=512.0,
                              columns=["c0", "c1"])
    assert rec.fs == 512.0 and rec.t[-1] == pytest.approx(199 / 512.0)
    np.testing.assert_array_equal(rec.data["b"], x[:, 1])


def test_records_averaged_recover_the_frame(amd_records):
    """Two records of the same test, averaged (H1 over all segments): the update finds the
    simulated masses and stiffnesses (force input fixes the scale)."""
    folder, _ = amd_records
    case, upd = _update(_records_case(folder, ["run1.dat", "run2.dat"]))
    assert case.n_averages == (16384 - 1024) // 512 + 1 + (8192 - 1024) // 512 + 1
    truth = dict(m1=M_TRUE[0], m2=M_TRUE[1], k1=K_TRUE[0], k2=K_TRUE[1])
    for name, value in truth.items():
        assert upd[name][0] == pytest.approx(value, rel=0.02), name


def test_spikes_are_reported_and_removal_gives_the_clean_model(amd_records, tmp_path):
    """1 % of the samples of every channel get single-sample glitches, and one channel a
    8-sample dropout: the screen reports them, and with removal on the update gives the
    model of the clean record within its standard errors."""
    folder, _ = amd_records
    lines = (folder / "run1.dat").read_text().splitlines()
    head, body = lines[:3], np.loadtxt(lines[3:])
    rng = np.random.default_rng(11)
    n = body.shape[0]
    spiked = set()
    for col in (1, 2, 3):
        idx = rng.choice(np.arange(10, n - 10), n // 100, replace=False)
        body[idx, col] += rng.choice([-1, 1], idx.size) * 6 * body[:, col].std()
        spiked |= {(col, i) for i in idx}
    body[5000:5008, 2] = 0.0  # a dropout
    with open(tmp_path / "run1.dat", "w") as fh:
        fh.write("\n".join(head) + "\n")
        np.savetxt(fh, body, fmt="%.6f %.8e %.8e %.8e")
    _, clean = _update(_records_case(folder, ["run1.dat"]))
    case, repaired = _update(_records_case(tmp_path, ["run1.dat"], screen={"remove": True}))
    q = case.quality.to_dict()
    assert q["removed"]
    found = sum(c["spikes"] for c in q["channels"].values())
    assert 0.95 * len(spiked) <= found <= len(spiked)  # two side by side make one run
    assert q["channels"]["a1"]["dropouts"] == 1
    _agree(repaired, clean)
