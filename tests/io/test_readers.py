"""Readers: round trips per format, unit conversion, one test per kind of bad input."""

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from nlp.errors import InputError
from nlp.io.readers import frf_unit_factor, read_frf, read_time_histories, unit_factor, write_uff58

CRISTALLO = Path(__file__).resolve().parents[2] / "cases" / "cristallo_three_storey" / "test_2.csv"
FS = 256.0  # Hz; dt = 1/256 is exact in 6 significant digits (UFF abscissa format)


@pytest.fixture
def records():
    rng = np.random.default_rng(0)
    t = np.arange(300) / FS
    return t, {"ag": rng.normal(size=300), "a1": rng.normal(size=300), "d1": rng.normal(size=300)}


def _write_csv(path, t, cols, delimiter=","):
    names = ["time"] + list(cols)
    table = np.column_stack([t] + list(cols.values()))
    np.savetxt(path, table, delimiter=delimiter, header=delimiter.join(names), comments="",
               fmt="%.17g")


CHANNELS = {"ground_acceleration": "ag", "acceleration": {"column": "a1", "unit": "g"},
            "d1": {"quantity": "displacement", "unit": "mm"}}


def _check(th, t, cols):
    assert th.fs == pytest.approx(FS, rel=1e-9)
    np.testing.assert_allclose(th.t, t, atol=1e-12)
    np.testing.assert_allclose(th.data["ground_acceleration"], cols["ag"], rtol=1e-12)
    np.testing.assert_allclose(th.data["acceleration"], 9.80665 * cols["a1"], rtol=1e-12)
    np.testing.assert_allclose(th.data["d1"], 1e-3 * cols["d1"], rtol=1e-12)


@pytest.mark.parametrize("delimiter", [",", ";"])
def test_csv_round_trip(tmp_path, records, delimiter):
    t, cols = records
    _write_csv(tmp_path / "r.csv", t, cols, delimiter)
    _check(read_time_histories(tmp_path / "r.csv", CHANNELS), t, cols)


def test_npz_round_trip_with_t_or_fs(tmp_path, records):
    t, cols = records
    np.savez(tmp_path / "r.npz", t=t, **cols)
    _check(read_time_histories(tmp_path / "r.npz", CHANNELS), t, cols)
    np.savez(tmp_path / "f.npz", fs=FS, **cols)
    _check(read_time_histories(tmp_path / "f.npz", CHANNELS), t, cols)


def test_mat_round_trip(tmp_path, records):
    t, cols = records
    scipy.io.savemat(tmp_path / "r.mat", dict(t=t, **cols))  # stored as 1 x N
    _check(read_time_histories(tmp_path / "r.mat", CHANNELS), t, cols)


def test_uff_time_round_trip(tmp_path, records):
    pytest.importorskip("pyuff")
    t, cols = records
    write_uff58(tmp_path / "r.uff", t, np.array(list(cols.values())), names=list(cols))
    th = read_time_histories(tmp_path / "r.uff", CHANNELS)
    assert th.fs == pytest.approx(FS, rel=1e-9)
    np.testing.assert_allclose(th.data["acceleration"], 9.80665 * cols["a1"], rtol=1e-10)
    np.testing.assert_allclose(th.data["d1"], 1e-3 * cols["d1"], rtol=1e-10)


def test_missing_pyuff_gives_install_hint(tmp_path, monkeypatch):
    (tmp_path / "r.uff").write_text("    -1\n")
    monkeypatch.setitem(sys.modules, "pyuff", None)  # makes `import pyuff` fail
    with pytest.raises(InputError, match=r'pip install "frf-nlp\[uff\]"'):
        read_frf(tmp_path / "r.uff")


# --- bad inputs -----------------------------------------------------------

def test_mismatched_length(tmp_path, records):
    t, cols = records
    np.savez(tmp_path / "r.npz", t=t, ag=cols["ag"], a1=cols["a1"][:-1])
    with pytest.raises(InputError, match=r"r\.npz: 'a1': expected 300 samples"):
        read_time_histories(tmp_path / "r.npz", {"ag": None, "a1": None})


def test_nan(tmp_path, records):
    t, cols = records
    cols["a1"][17] = np.nan
    _write_csv(tmp_path / "r.csv", t, cols)
    with pytest.raises(InputError, match=r"'a1': expected finite.*sample 17"):
        read_time_histories(tmp_path / "r.csv", {"ag": None, "a1": None})


def test_uneven_sampling(tmp_path, records):
    t, cols = records
    t = t.copy()
    t[100] += 1e-3 / FS
    np.savez(tmp_path / "r.npz", t=t, **cols)
    with pytest.raises(InputError, match="'t': expected even sampling"):
        read_time_histories(tmp_path / "r.npz", {"ag": None})


def test_unknown_channel_lists_available(tmp_path, records):
    t, cols = records
    _write_csv(tmp_path / "r.csv", t, cols)
    with pytest.raises(InputError) as info:
        read_time_histories(tmp_path / "r.csv", {"force": "F1"})
    msg = str(info.value)
    assert "r.csv" in msg and "channels.force" in msg and "F1" in msg
    assert "available: ag, a1, d1" in msg


def test_unknown_unit(tmp_path, records):
    t, cols = records
    np.savez(tmp_path / "r.npz", t=t, **cols)
    with pytest.raises(InputError, match=r"channels\.ag\.unit.*furlong"):
        read_time_histories(tmp_path / "r.npz", {"ag": {"unit": "furlong"}})
    # a displacement unit for an acceleration channel
    with pytest.raises(InputError, match="unit of ground_acceleration"):
        read_time_histories(tmp_path / "r.npz", {"ground_acceleration": {"column": "ag",
                                                                         "unit": "mm"}})
    with pytest.raises(InputError, match="'unit'"):
        frf_unit_factor("furlong/N")


def test_missing_time_information(tmp_path, records):
    _, cols = records
    np.savez(tmp_path / "r.npz", **cols)
    with pytest.raises(InputError, match="'t'"):
        read_time_histories(tmp_path / "r.npz", {"ag": None})
    assert read_time_histories(tmp_path / "r.npz", {"ag": None}, fs=FS).fs == FS


# --- units ------------------------------------------------------------------

def test_unit_factors():
    assert unit_factor("g") == 9.80665
    assert unit_factor("in") == pytest.approx(0.0254)
    assert unit_factor("kN", "force") == 1000.0
    assert unit_factor("lbf") == pytest.approx(0.45359237 * 9.80665)  # avoirdupois pound-force
    assert frf_unit_factor("g/N") == 9.80665
    assert frf_unit_factor("(m/s^2)/N") == 1.0
    assert frf_unit_factor("m/s^2/N") == 1.0
    assert frf_unit_factor("m/N") == 1.0
    assert frf_unit_factor("mm/N") == pytest.approx(1e-3)
    assert frf_unit_factor("m/s^2/(m/s^2)") == 1.0
    assert frf_unit_factor("g/(mm/s^2)") == pytest.approx(9806.65)
    assert frf_unit_factor("mm/kN") == pytest.approx(1e-6)


# --- FRFs -------------------------------------------------------------------

@pytest.fixture
def frfs():
    f = np.arange(1, 41) * 0.25
    rng = np.random.default_rng(1)
    H = rng.normal(size=(3, f.size)) + 1j * rng.normal(size=(3, f.size))
    return f, H


def test_frf_complex_csv_round_trip(tmp_path, frfs):
    f, H = frfs
    lines = [";".join([repr(complex(fi))] + [repr(complex(h)) for h in H[:, i]])
             for i, fi in enumerate(f)]
    (tmp_path / "h.csv").write_text("\n".join(lines) + "\n")
    f2, H2 = read_frf(tmp_path / "h.csv")
    np.testing.assert_array_equal(f2, f)
    np.testing.assert_array_equal(H2, H)
    f3, H3 = read_frf(tmp_path / "h.csv", columns=[2, 0], unit="g/N")
    np.testing.assert_allclose(H3, 9.80665 * H[[2, 0]])


@pytest.mark.parametrize("fmt", ["magphase", "db"])
def test_frf_magphase_and_db_round_trip(tmp_path, frfs, fmt):
    f, H = frfs
    mag = np.abs(H) if fmt == "magphase" else 20 * np.log10(np.abs(H))
    cols = [f]
    for ch in range(3):
        cols += [mag[ch], np.angle(H[ch], deg=True)]
    np.savetxt(tmp_path / "h.csv", np.column_stack(cols), delimiter=",", fmt="%.17g",
               header="f,m1,p1,m2,p2,m3,p3", comments="")
    f2, H2 = read_frf(tmp_path / "h.csv", fmt=fmt)
    np.testing.assert_allclose(f2, f)
    np.testing.assert_allclose(H2, H, rtol=1e-12)


def test_frf_npz_and_uff_round_trip(tmp_path, frfs):
    f, H = frfs
    np.savez(tmp_path / "h.npz", f=f, H=H)
    f2, H2 = read_frf(tmp_path / "h.npz")
    np.testing.assert_array_equal(H2, H)
    pytest.importorskip("pyuff")
    write_uff58(tmp_path / "h.uff", f, H, kind="frf")
    f3, H3 = read_frf(tmp_path / "h.uff")
    np.testing.assert_allclose(f3, f, rtol=1e-12)
    np.testing.assert_allclose(H3, H, rtol=1e-10)


def test_frf_bad_inputs(tmp_path, frfs):
    f, H = frfs
    (tmp_path / "h.csv").write_text("1+0j;2+1j;3\n2+0j;nonsense;4\n")
    with pytest.raises(InputError, match="line 2"):
        read_frf(tmp_path / "h.csv")
    (tmp_path / "r.csv").write_text("1+0j;2+1j;3\n2+0j;4\n")
    with pytest.raises(InputError, match="line 2.*3 fields"):
        read_frf(tmp_path / "r.csv")
    with pytest.raises(InputError, match="'fmt'"):
        read_frf(tmp_path / "r.csv", fmt="polar")
    np.savez(tmp_path / "n.npz", f=f, H=np.where(np.arange(f.size) == 3, np.nan, H))
    with pytest.raises(InputError, match="finite FRF"):
        read_frf(tmp_path / "n.npz")
    np.savez(tmp_path / "d.npz", f=f[::-1], H=H)
    with pytest.raises(InputError, match="increasing"):
        read_frf(tmp_path / "d.npz")


@pytest.mark.skipif(not CRISTALLO.is_file(), reason="Cristallo data not present")
def test_cristallo_file():
    f, H = read_frf(CRISTALLO)
    assert H.shape == (3, 4096) and np.iscomplexobj(H)
    assert f[0] == 0.03125 and f[-1] == 128.0
    np.testing.assert_allclose(np.diff(f), 0.03125)
