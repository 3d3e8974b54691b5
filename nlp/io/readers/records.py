"""Evenly sampled records: channels picked from a file's named columns, converted to SI,
and the time axis checked for even sampling."""

from dataclasses import dataclass

import numpy as np

from nlp.errors import InputError
from nlp.io.readers.units import QUANTITIES, unit_factor

__all__ = ["MAX_JITTER", "TIME_NAMES", "TimeHistories", "records_from_columns"]

MAX_JITTER = 1e-6  # largest accepted |dt_k - dt| / dt
TIME_NAMES = ("t", "time")


@dataclass(frozen=True)
class TimeHistories:
    """Evenly sampled records: time ``t`` [s] (N,), sampling frequency ``fs``
    [Hz], and ``data``, channel name -> record (N,) in SI units (m/s^2, m,
    m/s, N)."""

    t: np.ndarray
    fs: float
    data: dict


def _as_vector(path, key, value):
    """A record as a 1-D float array (a .mat vector's 1 x N or N x 1 raveled)."""
    v = np.asarray(value)
    if v.ndim > 1 and sum(s > 1 for s in v.shape) <= 1:
        v = v.ravel()  # .mat files store vectors as 1 x N or N x 1
    if v.ndim != 1 or not np.issubdtype(v.dtype, np.number) or np.iscomplexobj(v):
        raise InputError(path, key, "a 1-D real numeric record", got=f"{v.dtype} {v.shape}")
    return v.astype(float)


def _check_finite(path, key, v):
    """Raises InputError at the first NaN or inf of a record."""
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
        tkey = next((k for k in cols if k.lower() in TIME_NAMES), None)
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


def records_from_columns(path, cols, channels, fs=None, time_column=None):
    """The channels (:func:`nlp.io.readers.read_time_histories`) from a file's columns
    ``cols`` (name -> 1-D array), in SI, with their time axis."""
    data, n, first = {}, None, None
    for name, spec in channels.items():
        column, factor, derived = _channel_spec(path, name, spec)
        if derived is not None:
            column, factor = derived[0], factor * derived[1]
        if column not in cols:
            avail = ", ".join(k for k in cols if k.lower() not in TIME_NAMES + ("fs",))
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
