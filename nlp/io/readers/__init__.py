"""Readers for measured time histories and FRFs, with unit conversion to SI.

Formats are chosen by extension, one module each: text tables (CSV and the like,
:mod:`.text`), ``.npz`` (:mod:`.npz`), ``.mat`` (:mod:`.mat`), UFF dataset 58
(:mod:`.uff`; needs the optional ``pyuff`` package, ``pip install "frf-nlp[uff]"``).
Records become channels in SI (:mod:`.records`, :mod:`.units`); FRFs pass the same
checks whatever their format (:mod:`.frf_files`).
"""

from pathlib import Path

from nlp.errors import InputError
from nlp.io.readers.frf_files import checked_frf
from nlp.io.readers.mat import mat_columns
from nlp.io.readers.npz import frf_coherence, frf_from_npz, npz_columns
from nlp.io.readers.records import MAX_JITTER, TimeHistories, records_from_columns
from nlp.io.readers.text import (FRF_FORMATS, MAGNITUDE_ONLY, TEXT_EXT, frf_from_text,
                                 parse_complex, text_columns)
from nlp.io.readers.uff import UFF_EXT, frf_from_uff, uff_columns, write_uff58
from nlp.io.readers.units import G, QUANTITIES, UNITS, frf_unit_factor, unit_factor

__all__ = ["G", "UNITS", "QUANTITIES", "MAX_JITTER", "FRF_FORMATS", "MAGNITUDE_ONLY",
           "TimeHistories", "unit_factor", "frf_unit_factor", "parse_complex",
           "read_columns", "read_time_histories", "read_frf", "read_frf_coherence", "write_uff58"]


def _existing(path):
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "path", "an existing file")
    return path


def read_columns(path, columns=None, skip_rows=0):
    """All named 1-D arrays of a file, keyed by column / array / record name."""
    ext = path.suffix.lower()
    if ext in TEXT_EXT:
        return text_columns(path, columns, skip_rows)
    if columns is not None:
        raise InputError(path, "columns", "column names only for a headerless text file "
                         f"({', '.join(TEXT_EXT)})", got=ext)
    try:
        if ext == ".npz":
            return npz_columns(path)
        if ext == ".mat":
            return mat_columns(path)
    except Exception as exc:  # empty, truncated or corrupt (zipfile, EOF, OS errors)
        raise InputError(path, "<file>", f"a readable {ext} file",
                         got=f"{type(exc).__name__}: {exc}") from None
    if ext in UFF_EXT:
        return uff_columns(path)
    raise InputError(path, "format", "a .csv, .txt, .dat, .asc, .tsv, .npz, .mat, .uff or .unv "
                     "file", got=ext)


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
    cols = read_columns(path, columns, skip_rows)
    return records_from_columns(path, cols, channels, fs, time_column)


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
    if ext in TEXT_EXT:
        f, H = frf_from_text(path, fmt, delimiter, db_reference)
    elif ext == ".npz":
        f, H = frf_from_npz(path)
    elif ext in UFF_EXT:
        f, H = frf_from_uff(path)
    else:
        raise InputError(path, "format", "a .csv, .txt, .dat, .asc, .tsv, .npz, .uff or .unv "
                         "file", got=ext)
    return checked_frf(path, f, H, columns, unit)


def read_frf_coherence(path, n_ch, n_f):
    """Coherence and averaging count stored with FRFs, if any: (coherence (n_ch, n_f) or
    None, n_averages or None). Only ``.npz`` files carry them (:func:`.npz.frf_coherence`)."""
    path = _existing(path)
    if path.suffix.lower() != ".npz":
        return None, None
    return frf_coherence(path, n_ch, n_f)
