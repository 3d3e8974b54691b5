"""Universal File Format dataset 58 (time records, FRFs), through the optional ``pyuff``
package (``pip install "frf-nlp[uff]"``); the records are matched by ID line 1."""

from pathlib import Path

import numpy as np

from nlp.errors import InputError

__all__ = ["UFF_EXT", "read_uff58", "uff_columns", "frf_from_uff", "write_uff58"]

UFF_EXT = (".uff", ".unv")


def _pyuff(path):
    """The pyuff module, or an InputError saying how to install it."""
    try:
        import pyuff
    except ImportError as exc:
        raise InputError(path, "format", 'the optional UFF support: pip install "frf-nlp[uff]"',
                         got=Path(path).suffix) from exc
    return pyuff


def read_uff58(path, func_type):
    """UFF 58 records of one function type (1 time response, 4 FRF)."""
    pyuff = _pyuff(path)
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exceptions for malformed files
        raise InputError(path, "format", "a readable UFF file", got=str(exc)) from exc
    sets = [sets] if isinstance(sets, dict) else sets
    recs = [s for s in sets if s.get("type") == 58 and s.get("func_type") == func_type]
    if not recs:
        raise InputError(path, "func_type", f"at least one dataset-58 record of function type "
                         f"{func_type}")
    x = np.asarray(recs[0]["x"], dtype=float)
    for r in recs[1:]:
        if r["x"].shape != x.shape or not np.allclose(r["x"], x, rtol=1e-9, atol=0):
            raise InputError(path, r["id1"].strip(), "the same abscissa as the first record")
    return x, recs


def uff_columns(path):
    """Time records of a UFF file by ID line 1, with the abscissa as ``t`` [s]."""
    x, recs = read_uff58(path, 1)
    cols = {r["id1"].strip(): np.asarray(r["data"], dtype=float) for r in recs}
    cols.setdefault("t", x)
    return cols


def frf_from_uff(path):
    """(f [Hz], H (n_ch, n_f)) of the FRF records (function type 4) of a UFF file."""
    f, recs = read_uff58(path, 4)
    H = np.array([np.asarray(r["data"], dtype=complex) for r in recs])
    return f, H


def write_uff58(path, x, data, kind="time", names=None, units=None):
    """Write records as UFF dataset 58 (ASCII, double precision), minimal.

    ``x`` is time [s] (``kind="time"``, real ``data``) or frequency [Hz]
    (``kind="frf"``, complex ``data``); ``data`` is (n_ch, n). ``names`` go
    to ID line 1, which the readers match channels against (default ``ch1``,
    ...); ``units`` are ordinate unit labels. The file is overwritten.
    An even abscissa is stored as start and step, which the format writes
    with 6 significant digits: choose ``dt`` / ``df`` accordingly.
    """
    pyuff = _pyuff(path)
    x = np.asarray(x, dtype=float)
    data = np.atleast_2d(np.asarray(data))
    if kind not in ("time", "frf"):
        raise InputError(path, "kind", '"time" or "frf"', got=kind)
    if x.ndim != 1 or x.size < 2 or data.shape[1] != x.size:
        raise InputError(path, "data", f"records shaped (n_channels, {x.size})",
                         got=f"shape {data.shape}")
    names = names or [f"ch{i + 1}" for i in range(data.shape[0])]
    units = units or ["NONE"] * data.shape[0]
    steps = np.diff(x)
    even = bool(np.all(np.abs(steps - steps.mean()) <= 1e-9 * abs(steps.mean())))
    frf = kind == "frf"
    sets = [pyuff.prepare_58(
        binary=0, id1=names[i], func_type=4 if frf else 1, rsp_node=i + 1, rsp_dir=1,
        ref_node=1 if frf else 0, ref_dir=1 if frf else 0, ord_data_type=6 if frf else 4,
        abscissa_spacing=int(even), abscissa_spec_data_type=18 if frf else 17,
        ordinate_spec_data_type=0, orddenom_spec_data_type=0, z_axis_spec_data_type=0,
        ordinate_axis_units_lab=units[i],
        data=data[i].astype(complex if frf else float), x=x) for i in range(data.shape[0])]
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return path
