"""Readers for measured time histories and FRFs, with unit conversion to SI.

Formats are chosen by extension (CSV, ``.npz``, ``.mat``, UFF dataset 58);
UFF needs the optional ``pyuff`` package (``pip install "frf-nlp[uff]"``).
"""

import csv
import re
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np
import scipy.io

from nlp.errors import InputError

__all__ = ["G", "UNITS", "QUANTITIES", "MAX_JITTER", "FRF_FORMATS", "MAGNITUDE_ONLY",
           "TimeHistories", "unit_factor", "frf_unit_factor", "parse_complex",
           "read_time_histories", "read_frf", "write_uff58"]

G = 9.80665  # standard gravity [m/s^2]
#: unit -> SI multiplier, per physical dimension (read-only)
UNITS = MappingProxyType({
    "acceleration": MappingProxyType({"m/s^2": 1.0, "m/s2": 1.0, "g": G, "mm/s^2": 1e-3}),
    "displacement": MappingProxyType({"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254}),
    "velocity": MappingProxyType({"m/s": 1.0, "mm/s": 1e-3}),
    "force": MappingProxyType({"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605}),
})
#: channel quantity -> dimension; acceleration is absolute, displacement and
#: velocity relative to the ground
QUANTITIES = MappingProxyType({"ground_acceleration": "acceleration",
                               "acceleration": "acceleration", "displacement": "displacement",
                               "velocity": "velocity", "force": "force"})
MAX_JITTER = 1e-6  # largest accepted |dt_k - dt| / dt
_UFF_EXT = (".uff", ".unv")
_TEXT_EXT = (".csv", ".txt", ".dat", ".asc", ".tsv")
_TIME_NAMES = ("t", "time")
_COMMENT = ("#", "%", "//", ";;")
#: CSV/text FRF layouts; the last two carry no phase
FRF_FORMATS = ("complex", "magphase", "db", "magnitude", "db_magnitude")
MAGNITUDE_ONLY = ("magnitude", "db_magnitude")


@dataclass(frozen=True)
class TimeHistories:
    """Evenly sampled records: time ``t`` [s] (N,), sampling frequency ``fs``
    [Hz], and ``data``, channel name -> record (N,) in SI units (m/s^2, m,
    m/s, N)."""

    t: np.ndarray
    fs: float
    data: dict


def unit_factor(unit, quantity=None, *, file="<arguments>", key="unit"):
    """SI multiplier of a channel unit in `UNITS` (e.g. ``"g"`` -> 9.80665).

    With a ``quantity`` (one of `QUANTITIES`) the unit must be of its
    dimension. ``file`` and ``key`` name the unit's origin in errors.
    """
    if quantity is not None:
        if quantity not in QUANTITIES:
            raise InputError(file, "quantity", f"one of {', '.join(QUANTITIES)}", got=quantity)
        table = UNITS[QUANTITIES[quantity]]
        if unit not in table:
            raise InputError(file, key, f"a unit of {quantity}: {', '.join(table)}", got=unit)
        return table[unit]
    for table in UNITS.values():
        if unit in table:
            return table[unit]
    known = ", ".join(u for table in UNITS.values() for u in table)
    raise InputError(file, key, f"a known unit ({known})", got=unit)


def frf_unit_factor(unit, *, file="<arguments>", key="unit"):
    """SI multiplier of an FRF unit ``output/input``.

    Examples: ``"g/N"`` -> 9.80665, ``"(m/s^2)/N"`` -> 1, ``"mm/N"`` -> 1e-3,
    ``"m/s^2/(m/s^2)"`` -> 1, ``"g/g"`` -> 1. The split point is the ``/``
    (outside parentheses) that leaves a known unit on both sides.
    """
    text = str(unit).replace(" ", "")
    if text in ("1", "-", ""):
        return 1.0
    depth = 0
    for pos, char in enumerate(text):
        depth += (char == "(") - (char == ")")
        if char == "/" and depth == 0:
            num, den = (p[1:-1] if p[:1] == "(" and p[-1:] == ")" else p
                        for p in (text[:pos], text[pos + 1:]))
            try:
                return unit_factor(num) / unit_factor(den)
            except InputError:
                continue
    known = ", ".join(u for table in UNITS.values() for u in table)
    raise InputError(file, key, f"'output/input' with units from: {known}", got=unit)


def _existing(path):
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "path", "an existing file")
    return path


def _pyuff(path):
    try:
        import pyuff
    except ImportError as exc:
        raise InputError(path, "format", 'the optional UFF support: pip install "frf-nlp[uff]"',
                         got=Path(path).suffix) from exc
    return pyuff


def _read_uff58(path, func_type):
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


def _csv_delimiter(line):
    for delim in (";", ",", "\t"):
        if delim in line:
            return delim
    return None  # whitespace


def _data_lines(path, skip_rows=0):
    """Non-empty lines after ``skip_rows``, without comment lines (#, %, //)."""
    with open(path, newline="") as fh:
        lines = fh.read().splitlines()[skip_rows:]
    return [ln for ln in lines if ln.strip() and not ln.lstrip().startswith(_COMMENT)]


def _load_csv_columns(path, columns=None, skip_rows=0):
    """Columns of a text table: named by its header line, or by ``columns``
    when the file has no header (comment lines and ``skip_rows`` are skipped)."""
    lines = _data_lines(path, skip_rows)
    if not lines:
        raise InputError(path, "rows", "at least one data row")
    delim = _csv_delimiter(lines[0])
    if columns is None:
        header, lines = lines[0], lines[1:]
        names = [n.strip().strip('"') for n in (header.split(delim) if delim else header.split())]
    else:
        names = [str(c) for c in columns]
    try:
        arr = np.genfromtxt(lines, delimiter=delim, dtype=float, ndmin=2)
    except ValueError as exc:
        raise InputError(path, "rows", f"{len(names)} fields in every row",
                         got=str(exc).splitlines()[-1]) from exc
    if arr.size and np.isnan(arr[0]).all():
        raise InputError(path, "columns", "numbers in every row when data.columns names the "
                         "columns (a text line: comment it with #, or skip it with data.skip_rows)",
                         got=lines[0][:60])
    if arr.shape[1] != len(names):
        what = "data.columns" if columns is not None else "header"
        raise InputError(path, what, f"one name per column ({arr.shape[1]} columns)",
                         got=names)
    return {n: arr[:, i] for i, n in enumerate(names)}


def _load_columns(path, columns=None, skip_rows=0):
    """All named 1-D arrays of a file, keyed by column / array / record name."""
    ext = path.suffix.lower()
    if ext in _TEXT_EXT:
        return _load_csv_columns(path, columns, skip_rows)
    if columns is not None:
        raise InputError(path, "columns", "column names only for a headerless text file "
                         f"({', '.join(_TEXT_EXT)})", got=ext)
    try:
        if ext == ".npz":
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        if ext == ".mat":
            return {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    except Exception as exc:  # empty, truncated or corrupt (zipfile, EOF, OS errors)
        raise InputError(path, "<file>", f"a readable {ext} file",
                         got=f"{type(exc).__name__}: {exc}") from None
    if ext in _UFF_EXT:
        x, recs = _read_uff58(path, 1)
        cols = {r["id1"].strip(): np.asarray(r["data"], dtype=float) for r in recs}
        cols.setdefault("t", x)
        return cols
    raise InputError(path, "format", "a .csv, .txt, .dat, .asc, .tsv, .npz, .mat, .uff or .unv "
                     "file", got=ext)


def _as_vector(path, key, value):
    v = np.asarray(value)
    if v.ndim > 1 and sum(s > 1 for s in v.shape) <= 1:
        v = v.ravel()  # .mat files store vectors as 1 x N or N x 1
    if v.ndim != 1 or not np.issubdtype(v.dtype, np.number) or np.iscomplexobj(v):
        raise InputError(path, key, "a 1-D real numeric record", got=f"{v.dtype} {v.shape}")
    return v.astype(float)


def _check_finite(path, key, v):
    bad = ~np.isfinite(v)
    if bad.any():
        raise InputError(path, key, "finite numbers (no NaN or inf)",
                         got=f"{v[bad][0]} at sample {int(np.argmax(bad))}")


_SPEC_KEYS = {"column", "unit", "quantity", "scale", "sign", "from"}


def _channel_spec(path, name, spec):
    """(column, SI factor, derived) of one entry of the channels mapping.

    The factor is ``scale * sign * unit``; ``derived`` is None or, for
    ``from: {column, mass, unit}``, the (column, factor) of the acceleration
    whose product with the mass is the record (a force [N] = kg * m/s^2).
    """
    if spec is None or isinstance(spec, str):
        return spec or name, 1.0, None
    key = f"channels.{name}"
    if not isinstance(spec, dict) or set(spec) - _SPEC_KEYS:
        raise InputError(path, key, "None, a column name or a dict with keys "
                         + ", ".join(sorted(_SPEC_KEYS)), got=spec)
    quantity = spec.get("quantity", name if name in QUANTITIES else None)
    if quantity is not None and quantity not in QUANTITIES:
        raise InputError(path, f"{key}.quantity", f"one of {', '.join(QUANTITIES)}",
                         got=quantity)
    scale = spec.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not np.isfinite(scale) \
            or scale <= 0:
        raise InputError(path, f"{key}.scale", "a positive calibration factor (file value x "
                         "scale = value in the unit; use sign: -1 for a flip)", got=scale)
    sign = spec.get("sign", 1)
    if sign not in (1, -1) or isinstance(sign, bool):
        raise InputError(path, f"{key}.sign", "1 or -1", got=sign)
    factor = float(scale) * sign
    src = spec.get("from")
    if src is not None:
        # force known as mass x acceleration (inertial shaker, active mass damper)
        if quantity != "force":
            raise InputError(path, f"{key}.from", "only for a force: quantity force", got=quantity)
        if not isinstance(src, dict) or set(src) - {"column", "mass", "unit"} \
                or "column" not in src or "mass" not in src:
            raise InputError(path, f"{key}.from", "{column: acceleration column, mass: kg, "
                             "unit: acceleration unit}", got=src)
        mass = src["mass"]
        if isinstance(mass, bool) or not isinstance(mass, (int, float)) or not mass > 0:
            raise InputError(path, f"{key}.from.mass", "a mass in kg > 0", got=mass)
        if spec.get("unit") not in (None, "N"):
            raise InputError(path, f"{key}.unit", "no unit with from: (the force is in N; give "
                             "the acceleration's unit in from.unit)", got=spec["unit"])
        acc = 1.0 if src.get("unit") is None else unit_factor(
            src["unit"], "acceleration", file=path, key=f"{key}.from.unit")
        return None, factor, (str(src["column"]), float(mass) * acc)
    unit = spec.get("unit")
    if unit is not None:
        factor *= unit_factor(unit, quantity, file=path, key=f"{key}.unit")
    return spec.get("column") or name, factor, None


def _time_axis(path, cols, n, fs, time_column=None):
    """Time vector [s] and sampling frequency [Hz], checked for even sampling."""
    if time_column is not None:
        if time_column not in cols:
            raise InputError(path, "time_column", f"a column of the file ({', '.join(cols)})",
                             got=time_column)
        tkey = time_column
    else:
        tkey = next((k for k in cols if k.lower() in _TIME_NAMES), None)
    if tkey is not None:
        t = _as_vector(path, tkey, cols[tkey])
        if t.size != n:
            raise InputError(path, tkey, f"{n} samples like the channels", got=t.size)
        _check_finite(path, tkey, t)
    else:
        fs = np.ravel(cols["fs"]) if "fs" in cols else fs
        if fs is None:
            raise InputError(path, "t", "a time column 't' or 'time', data.time_column naming "
                             "it, an 'fs' entry, or data.fs (sampling rate in Hz)")
        if np.size(fs) != 1 or not np.issubdtype(np.asarray(fs).dtype, np.number) or not fs > 0:
            raise InputError(path, "fs", "one positive sampling frequency in Hz", got=fs)
        return np.arange(n) / float(np.ravel(fs)[0]), float(np.ravel(fs)[0])
    if n < 2:
        raise InputError(path, tkey, "at least 2 samples", got=n)
    steps = np.diff(t)
    dt = (t[-1] - t[0]) / (n - 1)
    if np.any(steps <= 0):
        raise InputError(path, tkey, "strictly increasing times",
                         got=f"step {steps.min()} s at sample {int(np.argmin(steps))}")
    # Time stamps printed with d decimals carry a rounding error up to 10^-d:
    # that is not uneven sampling, so allow it and rebuild the axis.
    res = _resolution(t)
    jitter = np.max(np.abs(steps - dt)) / dt
    if jitter > MAX_JITTER + 2 * res / dt:
        raise InputError(path, tkey, f"even sampling (relative step jitter < {MAX_JITTER:g} "
                         "beyond the time stamps' rounding)",
                         got=f"jitter {jitter:.3g} at sample {int(np.argmax(np.abs(steps - dt)))}")
    if fs is not None and abs(fs * dt - 1) > 1e-6 + 2 * res / dt:
        raise InputError(path, "fs", f"the sampling rate of the time column '{tkey}' "
                         f"({1 / dt:.6g} Hz), or no fs", got=fs)
    return t[0] + dt * np.arange(n), 1.0 / dt


def _resolution(t):
    """Rounding step of printed time stamps: 10^-d for the fewest decimals d that
    reproduce them; 0 for full-precision times."""
    scale = max(np.max(np.abs(t)), 1e-300)
    for d in range(0, 10):
        if np.allclose(t, np.round(t, d), rtol=0, atol=1e-9 * scale):
            return 0.5 * 10.0 ** -d
    return 0.0


def read_time_histories(path, channels, fs=None, *, columns=None, time_column=None,
                        skip_rows=0):
    """Read channel records and convert them to SI units.

    Parameters
    ----------
    path : str or path-like
        Text (``.csv``, ``.txt``, ``.dat``, ``.asc``, ``.tsv``: a header row,
        or none with ``columns``; lines starting with ``#``, ``%`` or ``//``
        are comments), ``.npz`` or ``.mat`` (arrays named like the columns,
        plus ``t`` or ``fs``), ``.uff``/``.unv`` (dataset-58 time records;
        column = ID line 1).
    channels : dict
        ``name -> spec`` where spec is None (column named like the channel),
        a column name, or a dict with optional keys ``column``, ``unit``,
        ``quantity``, ``scale`` (calibration: file value x scale = value in
        ``unit``, e.g. 1/sensitivity for volts), ``sign`` (1 or -1) and, for a
        force known as mass x acceleration, ``from: {column, mass [kg],
        unit}``: the record is ``sign * scale * mass * acceleration`` [N].
        The quantity defaults to the channel name when it is one of
        `QUANTITIES`, the unit to SI. Quantities: ground_acceleration,
        acceleration (absolute), displacement and velocity (relative to the
        ground), force.
    fs : float, optional
        Sampling frequency [Hz] when the file has no time column (checked
        against the time column when it has one).
    columns : sequence of str, optional
        Names of the columns of a headerless text file, in order.
    time_column : str, optional
        Name of the time column [s] (default: ``t`` or ``time`` if present).
    skip_rows : int, optional
        Leading lines of a text file to skip (an instrument's preamble).

    Returns
    -------
    TimeHistories
    """
    path = _existing(path)
    if not channels:
        raise InputError(path, "channels", "at least one channel")
    cols = _load_columns(path, columns, skip_rows)
    data, n, first = {}, None, None
    for name, spec in channels.items():
        column, factor, derived = _channel_spec(path, name, spec)
        if derived is not None:
            column, factor = derived[0], factor * derived[1]
        if column not in cols:
            avail = ", ".join(k for k in cols if k.lower() not in _TIME_NAMES + ("fs",))
            raise InputError(path, f"channels.{name}",
                             f"column '{column}' in the file (available: {avail})")
        v = _as_vector(path, column, cols[column])
        if n is None:
            n, first = v.size, column
        elif v.size != n:
            raise InputError(path, column, f"{n} samples like '{first}'", got=v.size)
        _check_finite(path, column, v)
        data[name] = v * factor
    t, fs_ = _time_axis(path, cols, n, fs, time_column)
    return TimeHistories(t=t, fs=fs_, data=data)


_MATLAB_I = re.compile(r"(?<=[0-9.])[iI](?![A-Za-z0-9])")


def parse_complex(token):
    """A complex number written by Python (``1+2j``) or MATLAB (``1+2i``,
    ``1.0 + 2.0i``); raises ValueError otherwise."""
    return complex(_MATLAB_I.sub("j", token.replace(" ", "")))


parse_complex.__name__ = "complex"  # named so in 'expected ... numbers' messages


def _parse_table(path, delimiter, conv):
    """Rows of a headerless (or one-header-line) numeric CSV as a 2-D array;
    comment lines (#, %, //) are skipped."""
    lines = _data_lines(path)
    if not lines:
        raise InputError(path, "rows", "at least one data row")
    delim = delimiter or _csv_delimiter(lines[0])
    rows = [[tok.strip() for tok in r] for r in
            (csv.reader(lines, delimiter=delim) if delim else (ln.split() for ln in lines))]
    out = []
    for i, row in enumerate(rows):
        try:
            out.append([conv(tok) for tok in row])
        except ValueError as exc:
            if i == 0:
                continue  # a header line
            what = ("complex numbers, Python (1+2j) or MATLAB (1+2i)" if conv is parse_complex
                    else f"{conv.__name__} numbers")
            raise InputError(path, f"data line {i + 1}", what, got=",".join(row)) from exc
        if len(out[-1]) != len(out[0]):
            raise InputError(path, f"line {i + 1}", f"{len(out[0])} fields like the first row",
                             got=len(out[-1]))
    if not out:
        raise InputError(path, "rows", "at least one data row")
    return np.array(out)


def _frf_from_csv(path, fmt, delimiter, db_reference):
    if fmt == "complex":
        tab = _parse_table(path, delimiter, parse_complex)
        if np.any(np.abs(tab[:, 0].imag) > 1e-12 * np.abs(tab[:, 0].real).max()):
            raise InputError(path, "column 0", "real frequencies in Hz (imaginary part 0)")
        return tab[:, 0].real, tab[:, 1:].T
    tab = _parse_table(path, delimiter, float)
    if fmt in MAGNITUDE_ONLY:
        if tab.shape[1] < 2:
            raise InputError(path, "columns", "frequency then one magnitude column per channel",
                             got=f"{tab.shape[1]} columns")
        vals = tab[:, 1:].T
        mag = vals if fmt == "magnitude" else db_reference * 10.0 ** (vals / 20.0)
        if np.any(mag < 0):
            raise InputError(path, "magnitude", "magnitudes >= 0 (no phase in this format)")
        return tab[:, 0], mag.astype(complex)
    if tab.shape[1] < 3 or (tab.shape[1] - 1) % 2:
        what = "magnitude" if fmt == "magphase" else "dB"
        raise InputError(path, "columns", f"frequency then ({what}, phase_deg) pairs (for "
                         "magnitude-only files: format magnitude or db_magnitude)",
                         got=f"{tab.shape[1]} columns")
    mag = tab[:, 1::2].T if fmt == "magphase" else db_reference * 10.0 ** (tab[:, 1::2].T / 20.0)
    return tab[:, 0], mag * np.exp(1j * np.deg2rad(tab[:, 2::2].T))


def read_frf(path, fmt="complex", columns=None, delimiter=None, unit=None, db_reference=1.0):
    """Read measured FRFs.

    Parameters
    ----------
    path : str or path-like
        ``.csv``/``.txt``, ``.npz`` (arrays ``f`` [Hz] and ``H`` (n_ch, n_f))
        or ``.uff``/``.unv`` (dataset-58 FRF records, function type 4).
    fmt : {"complex", "magphase", "db", "magnitude", "db_magnitude"}
        CSV layout, first column frequency [Hz], no header needed (one
        header line and comment lines starting with #, % or // are skipped):
        ``"complex"``: complex numbers per channel, Python (``0.5+0.1j``) or
        MATLAB (``0.5+0.1i``);
        ``"magphase"``: (magnitude, phase [deg]) pairs per channel;
        ``"db"``: (dB, phase [deg]) pairs per channel;
        ``"magnitude"``: one magnitude column per channel, no phase;
        ``"db_magnitude"``: one dB column per channel, no phase.
        Magnitude-only FRFs come back as real, non-negative ``H``.
        Delimiter ``;``, ``,``, tab or whitespace (detected).
    columns : sequence of int, optional
        0-based channel indices to keep (channel 0 is the first FRF, not the
        frequency column); default all.
    delimiter : str, optional
        Overrides delimiter detection for CSV.
    unit : str, optional
        FRF unit in the file (see `frf_unit_factor`), to convert to SI;
        default: values as stored.
    db_reference : float, optional
        The magnitude that 0 dB stands for, in the file's FRF unit:
        ``|H| = db_reference * 10^(dB / 20)``; default 1.

    Returns
    -------
    f : ndarray, shape (n_f,)
        Frequencies [Hz].
    H : ndarray, shape (n_ch, n_f), complex
        FRFs, assumed in the ``exp(-j w t)`` convention (``Y = H X``).
    """
    path = _existing(path)
    ext = path.suffix.lower()
    if ext in _TEXT_EXT:
        if fmt not in FRF_FORMATS:
            raise InputError(path, "fmt", f"one of {', '.join(FRF_FORMATS)}", got=fmt)
        if not (np.isfinite(db_reference) and db_reference > 0):
            raise InputError(path, "db_reference", "a positive magnitude for 0 dB",
                             got=db_reference)
        f, H = _frf_from_csv(path, fmt, delimiter, db_reference)
    elif ext == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                missing = [k for k in ("f", "H") if k not in z.files]
                if missing:
                    raise InputError(path, missing[0], "arrays 'f' and 'H' in the .npz file",
                                     got=z.files)
                f, H = z["f"].astype(float), np.atleast_2d(z["H"]).astype(complex)
        except InputError:
            raise
        except Exception as exc:  # empty, truncated or not a zip archive at all
            raise InputError(path, "<file>", "a readable .npz file with arrays 'f' and 'H'",
                             got=f"{type(exc).__name__}: {exc}") from None
    elif ext in _UFF_EXT:
        f, recs = _read_uff58(path, 4)
        H = np.array([np.asarray(r["data"], dtype=complex) for r in recs])
    else:
        raise InputError(path, "format", "a .csv, .txt, .dat, .asc, .tsv, .npz, .uff or .unv "
                         "file", got=ext)
    if f.ndim != 1 or H.ndim != 2 or H.shape[1] != f.size or H.shape[0] == 0:
        raise InputError(path, "H", f"FRFs shaped (n_channels, {f.size})", got=f"shape {H.shape}")
    if not np.all(np.isfinite(f)) or np.any(np.diff(f) <= 0):
        raise InputError(path, "f", "finite, strictly increasing frequencies in Hz")
    if not np.all(np.isfinite(H)):
        ch, i = np.argwhere(~np.isfinite(H))[0]
        raise InputError(path, f"channel {ch}", "finite FRF values", got=f"{H[ch, i]} at {f[i]} Hz")
    if columns is not None:
        if any(int(c) != c or not 0 <= c < H.shape[0] for c in columns):
            raise InputError(path, "columns", f"channel indices in [0, {H.shape[0] - 1}]",
                             got=columns)
        H = H[[int(c) for c in columns]]
    factor = 1.0 if unit is None else frf_unit_factor(unit, file=path, key="unit")
    return f, H * factor


def read_frf_coherence(path, n_ch, n_f):
    """Coherence and averaging count stored with FRFs in an .npz file, if any.

    Optional arrays ``coherence`` (n_ch, n_f), in [0, 1], and ``n_averages``
    (a positive number: the averages behind the FRFs, overlap-corrected if the
    writer knew it). Other formats carry neither.

    Returns
    -------
    coherence : ndarray (n_ch, n_f) or None
    n_averages : float or None
    """
    path = _existing(path)
    if path.suffix.lower() != ".npz":
        return None, None
    with np.load(path, allow_pickle=False) as z:
        coh = np.atleast_2d(z["coherence"]).astype(float) if "coherence" in z.files else None
        nav = np.ravel(z["n_averages"]) if "n_averages" in z.files else None
    if coh is not None and (coh.shape != (n_ch, n_f) or not np.all(np.isfinite(coh))
                            or coh.min() < 0 or coh.max() > 1):
        raise InputError(path, "coherence", f"an array of values in [0, 1] shaped ({n_ch}, {n_f}) "
                         "like H", got=f"shape {coh.shape}")
    if nav is not None:
        if nav.size != 1 or not np.isfinite(nav[0]) or not nav[0] > 0:
            raise InputError(path, "n_averages", "one positive number (averages behind the FRFs)",
                             got=nav.tolist())
        nav = float(nav[0])
    return coh, nav


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
