"""The case's measured data: an FRF file, or time histories read, screened and averaged
into an FRF estimate, with their quality report."""

import os

import numpy as np

from nlp.case.checks import check_coherence, check_record_alive
from nlp.errors import InputError
from nlp.frf.estimate import default_nperseg, estimate_frf
from nlp.io.quality import QualityReport, screen_records
from nlp.io.readers import read_frf, read_frf_coherence, read_time_histories

__all__ = ["read_data"]


def _record_spec(d):
    """Channel specs for readers.read_time_histories: the input, then each channel."""
    inp = d.input
    spec = {"__input__": {"column": inp["column"], "quantity": inp["quantity"], "unit": inp["unit"],
                          "from": inp.get("from"), "scale": inp.get("scale", 1.0),
                          "sign": inp.get("sign", 1)}}
    for c in d.channels:
        spec[c.name] = {"column": c.column, "quantity": c.quantity, "unit": c.unit,
                        "scale": c.scale, "sign": c.sign}
    return {k: {kk: vv for kk, vv in v.items() if vv is not None} for k, v in spec.items()}


def _read_records(cfg, paths):
    """Records of the case (screened, and repaired when asked), the FRF estimate over
    all their segments, and the quality report."""
    d = cfg.data
    spec = _record_spec(d)
    xs, ys, reports, first = [], [], [], None
    for path in paths:
        try:
            rec = read_time_histories(path, spec, fs=d.fs, columns=d.columns,
                                      time_column=d.time_column, skip_rows=d.skip_rows)
        except InputError as exc:  # a unit or column named in the case file: say which key
            raise _case_key_error(cfg, exc) from None
        check_record_alive(path, d.input["column"], rec.data["__input__"],
                           f"data.input.column of {cfg.path}")
        for i, c in enumerate(d.channels):
            check_record_alive(path, c.column, rec.data[c.name],
                               f"data.channels[{i}] of {cfg.path}")
        if first is not None and abs(rec.fs - first.fs) > 1e-9 * first.fs:
            raise InputError(path, "fs", f"the sampling rate of the first record ({first.fs:g} Hz)",
                             rec.fs)
        sc = d.screen
        data, rep = screen_records(rec.data, rec.fs, remove=sc.remove,
                                   spike_threshold=sc.spike_threshold,
                                   dropout_min_samples=sc.dropout_min_samples, t0=float(rec.t[0]))
        if sc.remove:
            rec = type(rec)(t=rec.t, fs=rec.fs, data=data)
        first = first or rec
        reports.append((path, rep))
        xs.append(rec.data["__input__"])
        ys.append(np.array([rec.data[c.name] for c in d.channels]))
    n = min(x.size for x in xs)
    nperseg = n if d.nperseg == "all" else d.nperseg
    noverlap = None if nperseg is None else int(d.overlap * nperseg)
    if nperseg is None:  # the default segment, with the case's overlap (not scipy's half)
        nperseg = default_nperseg(n)
        noverlap = int(d.overlap * nperseg)
    try:
        est = estimate_frf(xs, ys, first.fs, estimator=d.estimator, nperseg=nperseg,
                           noverlap=noverlap, window=d.window, source=paths[0])
    except InputError as exc:  # segment settings come from the case file: name its key
        if exc.key not in ("nperseg", "noverlap"):
            raise
        raise InputError(cfg.path, "data.nperseg" if exc.key == "nperseg" else "data.overlap",
                         f"{exc.expected} (the records have {n} samples)", exc.got) from None
    check_coherence(cfg, est.f, est.coherence, [c.column for c in d.channels],
                    [f"data.channels[{i}]" for i in range(len(d.channels))], est.n_averages,
                    source=", ".join(map(str, paths)))
    return est, first, reports


def read_data(cfg, path=None):
    """(f, H, coherence, records, n_averages, quality) of the case's data (or another test's)."""
    d = cfg.data
    if d.type == "frf":
        path = path or d.file
        fmt = d.format
        if fmt == "auto":
            fmt = "npz" if path.endswith(".npz") else "complex"
        f, H = read_frf(path, fmt=fmt if fmt != "npz" else "complex", db_reference=d.db_reference)
        coh, n_avg = read_frf_coherence(path, *H.shape)   # .npz may carry them (noise model)
        return f, H * d.unit_factor, coh, None, n_avg or 1, None
    paths = [path] if path else list(d.records or (d.file,))
    est, rec, reports = _read_records(cfg, paths)
    return est.f, est.H, est.coherence, rec, est.n_averages, _merge_quality(reports)


def _merge_quality(reports):
    """One report over all records (file named in each glitch's channel when several)."""
    if len(reports) == 1:
        return reports[0][1]
    glitches = []
    for path, rep in reports:
        tag = os.path.basename(path)
        glitches += [type(g)(f"{tag}:{g.channel}", g.kind, g.start, g.stop, g.time_s)
                     for g in rep.glitches]
    return QualityReport(tuple(glitches), sum(r.n_samples for _, r in reports), reports[0][1].removed,
                         reports[0][1].settings)


def _case_key_error(cfg, exc):
    """A records-file error about a channel spec, renamed to the case file's key."""
    key = exc.key
    if key.startswith("channels."):
        _, name, *rest = key.split(".")
        field = rest[0] if rest else "column"
        if name == "__input__":
            return InputError(cfg.path, f"data.input.{field}", exc.expected, exc.got)
        for i, c in enumerate(cfg.data.channels):
            if c.name == name:
                return InputError(cfg.path, f"data.channels[{i}].{field}", exc.expected, exc.got)
    return exc
