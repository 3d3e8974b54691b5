"""What every FRF file must hold, whatever its format: H (n_ch, n_f) on strictly
increasing frequencies, finite; the channels kept and the unit converted to SI."""

import numpy as np

from nlp.errors import InputError
from nlp.io.readers.units import frf_unit_factor

__all__ = ["checked_frf"]


def checked_frf(path, f, H, columns=None, unit=None):
    """(f, H in SI) after the checks; ``columns`` 0-based channels to keep, ``unit`` the
    file's FRF unit (:func:`nlp.io.readers.units.frf_unit_factor`)."""
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
