"""Text tables (CSV and the like): named columns of records, and FRF layouts.

Delimiter ``;``, ``,``, tab or whitespace (detected from the first data line); lines
starting with ``#``, ``%``, ``//`` or ``;;`` are comments.
"""

import csv
import re

import numpy as np

from nlp.errors import InputError

__all__ = ["TEXT_EXT", "FRF_FORMATS", "MAGNITUDE_ONLY", "parse_complex", "text_columns",
           "frf_from_text"]

TEXT_EXT = (".csv", ".txt", ".dat", ".asc", ".tsv")
_COMMENT = ("#", "%", "//", ";;")
#: CSV/text FRF layouts; the last two carry no phase
FRF_FORMATS = ("complex", "magphase", "db", "magnitude", "db_magnitude")
MAGNITUDE_ONLY = ("magnitude", "db_magnitude")


def _csv_delimiter(line):
    """The delimiter of a data line; None for whitespace."""
    for delim in (";", ",", "\t"):
        if delim in line:
            return delim
    return None  # whitespace


def _data_lines(path, skip_rows=0):
    """Non-empty lines after ``skip_rows``, without comment lines (#, %, //)."""
    with open(path, newline="") as fh:
        lines = fh.read().splitlines()[skip_rows:]
    return [ln for ln in lines if ln.strip() and not ln.lstrip().startswith(_COMMENT)]


def text_columns(path, columns=None, skip_rows=0):
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


def frf_from_text(path, fmt, delimiter, db_reference):
    """(f [Hz], H (n_ch, n_f)) of a text FRF table in layout ``fmt`` (:data:`FRF_FORMATS`)."""
    if fmt not in FRF_FORMATS:
        raise InputError(path, "fmt", f"one of {', '.join(FRF_FORMATS)}", got=fmt)
    if not (np.isfinite(db_reference) and db_reference > 0):
        raise InputError(path, "db_reference", "a positive magnitude for 0 dB",
                         got=db_reference)
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
