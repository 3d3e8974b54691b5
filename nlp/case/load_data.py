"""The data section of a case file: the measured data (FRF files or time histories), its
channels, the estimator settings for records and the layout of a text file."""

import os

from scipy.signal import get_window

from nlp.case.reader import file_list, location, scale_sign
from nlp.case.schema import (CHANNEL_QUANTITIES, DATA_FORMATS, DATA_TYPES, DB_FORMATS,
                             ESTIMATORS, INPUT_QUANTITIES, OUTPUTS, ChannelConfig, DataConfig,
                             ScreenConfig, OtherTest)
from nlp.frf.forms import OUTPUT_OF_QUANTITY

__all__ = ["data_section"]


def data_section(rd, d, base):
    """The validated data section (:class:`nlp.case.schema.DataConfig`); paths are made
    absolute against ``base``, the case file's folder."""
    rd.check_keys(d, "data", {"type", "file", "format", "unit_factor", "channels", "input",
                              "estimator", "nperseg", "overlap", "window", "validation_file",
                              "validation_force_floor", "level_files", "tests", "db_reference", "records",
                              "columns", "skip_rows", "time_column", "fs", "screen",
                              "calibration"})
    kind = rd.choice(d, "type", "data.type", DATA_TYPES, DataConfig.type)
    records = kind == "time_histories"
    f, rec_paths, val = _data_files(rd, d, base, records)
    fmt = rd.choice(d, "format", "data.format", DATA_FORMATS, DataConfig.format)
    unit = rd.number(d, "unit_factor", "data.unit_factor", DataConfig.unit_factor,
                      positive=True)
    inp = _record_input(rd, d) if records else None
    channels = _channels(rd, d, inp)
    est = rd.choice(d, "estimator", "data.estimator", ESTIMATORS, DataConfig.estimator)
    nperseg, overlap = _segments(rd, d)
    vfloor = rd.number(d, "validation_force_floor", "data.validation_force_floor", None,
                       positive=True, integer=True)
    level_paths = file_list(rd, d.get("level_files") or [], "data.level_files", base)
    tests = _joint_tests(rd, d, base, kind, f)
    if tests and val:
        # a held-out test would be judged with the joint model's per-test terms
        raise rd.err("data.validation_file", "no held-out file beside data.tests (list that "
                     "test under data.tests: it is fitted jointly)", d["validation_file"])
    dbref = rd.number(d, "db_reference", "data.db_reference", DataConfig.db_reference,
                       positive=True)
    if "db_reference" in d and fmt not in DB_FORMATS:
        raise rd.err("data.db_reference", "only with format db or db_magnitude", fmt)
    layout = _text_layout(rd, d, records)
    _check_window(rd, d, records)
    cal = rd.number(d, "calibration", "data.calibration", None, positive=True)
    if cal is not None and cal >= 0.5:
        raise rd.err("data.calibration", "the relative tolerance of the transducers' "
                     "sensitivity, a number > 0 and < 0.5 (0.03 for +-3 %)", cal)
    return DataConfig(file=f, format=fmt, unit_factor=unit, channels=channels, type=kind,
                      input=inp, estimator=est, nperseg=nperseg, overlap=overlap,
                      window=str(d.get("window", "boxcar" if nperseg == "all" else DataConfig.window)),
                      validation_file=val,
                      validation_force_floor=vfloor, level_files=tuple(level_paths), tests=tests,
                      db_reference=dbref, records=tuple(rec_paths), calibration=cal, **layout)


def _data_files(rd, d, base, records):
    """(data file, record files, validation file) as absolute paths."""
    rec_paths = _record_files(rd, d, base, records)
    if "file" not in d and not rec_paths:
        raise rd.err("data.file", "the path of the measured data file (required)")
    f = os.path.join(base, str(d["file"])) if "file" in d else rec_paths[0]
    if not os.path.isfile(f):
        raise rd.err("data.file", "an existing file (relative to the case file)", d["file"])
    if "file" in d and rec_paths:
        raise rd.err("data.records", "either data.file or data.records, not both", d["records"])
    val = None
    if d.get("validation_file") is not None:
        val = os.path.join(base, str(d["validation_file"]))
        if not os.path.isfile(val):
            raise rd.err("data.validation_file", "an existing file", d["validation_file"])
    return f, rec_paths, val


def _joint_tests(rd, d, base, kind, main_file):
    """data.tests: other FRF files of the same structure and sensors, fitted jointly."""
    v = d.get("tests")
    if v is None:
        return ()
    if not isinstance(v, list) or not v:
        raise rd.err("data.tests", "a list of {file, force_floor, label} (other tests of the "
                     "same structure, fitted jointly)", v)
    if kind != "frf":
        raise rd.err("data.tests", "only with FRF files (data.type frf)", kind)
    out, labels = [], {os.path.splitext(os.path.basename(main_file))[0]}
    for i, t in enumerate(v):
        key = f"data.tests[{i}]"
        if not isinstance(t, dict):
            raise rd.err(key, "a mapping {file, force_floor, label}", v[i])
        rd.check_keys(t, key, {"file", "force_floor", "label"})
        if not isinstance(t.get("file"), str):
            raise rd.err(f"{key}.file", "the FRF file's name (relative to the case file)",
                         t.get("file"))
        p = os.path.join(base, t["file"])
        if not os.path.isfile(p):
            raise rd.err(f"{key}.file", "an existing file (relative to the case file)", t["file"])
        floor = rd.number(t, "force_floor", f"{key}.force_floor", None, positive=True,
                          integer=True)
        label = str(t.get("label") or os.path.splitext(os.path.basename(p))[0])
        if label in labels or not label.replace("_", "").replace("-", "").isalnum():
            raise rd.err(f"{key}.label", "a name of letters, digits, - and _ that no other "
                         "test of the case has", label)
        labels.add(label)
        out.append(OtherTest(file=p, force_floor=floor, label=label))
    return tuple(out)


def _record_input(rd, d):
    """data.input of time histories: the column (or mass x acceleration) of the input."""
    inp = rd.mapping(d, "data.input", required=True)
    rd.check_keys(inp, "data.input", {"column", "quantity", "unit", "floor", "from", "scale",
                                      "sign"})
    q = rd.choice(inp, "quantity", "data.input.quantity", INPUT_QUANTITIES, None)
    src = None
    if "from" in inp:
        src = _force_from(rd, inp, q)
    elif "column" not in inp:
        raise rd.err("data.input.column", "the name of the input record's column (or, for a "
                     "force, from: {column, mass, unit})")
    floor = None
    if q == "force":
        floor = rd.number(inp, "floor", "data.input.floor", required=True, positive=True,
                          integer=True)
    scale, sign = scale_sign(rd, inp, "data.input")
    return {"column": None if src else str(inp["column"]), "quantity": q,
            "unit": inp.get("unit"), "floor": floor, "from": src, "scale": scale, "sign": sign}


def _channels(rd, d, inp):
    """data.channels: unique names, each a floor (or node and DOF) with its form; ``inp``:
    the record input (None for FRF files)."""
    chans = d.get("channels")
    if not isinstance(chans, list) or not chans:
        raise rd.err("data.channels", "a list of channels, each {name, floor, output, column}", chans)
    out = []
    names = set()
    for i, c in enumerate(chans):
        key = f"data.channels[{i}]"
        if not isinstance(c, dict):
            raise rd.err(key, "a mapping {name, floor, output, column}", c)
        rd.check_keys(c, key, {"name", "floor", "output", "column", "weight", "quantity", "unit",
                               "node", "dof", "scale", "sign"})
        name = str(c.get("name", f"ch{i + 1}"))
        if name in names:
            raise rd.err(f"{key}.name", "a unique channel name", name)
        names.add(name)
        floor, node, dof = location(rd, c, key, base=True)
        w = rd.number(c, "weight", f"{key}.weight", ChannelConfig.weight, positive=True)
        read = _record_channel if inp is not None else _frf_channel
        out.append(read(rd, c, key, i, name, floor, node, dof, w, inp))
    for i, c in enumerate(out):
        # the base moves only with the ground: a fixed-base model predicts the input
        # itself there, a flexible base (diagnose) the base DOF's absolute motion
        if c.floor == 0 and c.output != "absolute_accelerance":
            raise rd.err(f"data.channels[{i}].floor", "a floor >= 1; floor 0 (a sensor on the "
                         "base) is an absolute acceleration under ground excitation "
                         "(records: quantity acceleration with a ground_acceleration input; "
                         "FRF files: output absolute_accelerance)", 0)
    return tuple(out)


def _record_channel(rd, c, key, i, name, floor, node, dof, w, inp):
    """A time-history channel: a floor, its measured quantity and unit."""
    if node is not None:
        raise rd.err(f"{key}.node", "a floor (time-history channels are floors of a "
                     "shear frame)", node)
    q = rd.choice(c, "quantity", f"{key}.quantity", CHANNEL_QUANTITIES, None)
    ground = inp["quantity"] == "ground_acceleration"
    output = OUTPUT_OF_QUANTITY.get(q, "absolute_accelerance" if ground else "accelerance")
    scale, sign = scale_sign(rd, c, key)
    return ChannelConfig(name=name, floor=floor, output=output, column=str(c.get("column", name)),
                         weight=w, quantity=q, unit=c.get("unit"), node=node, dof=dof,
                         scale=scale, sign=sign)


def _frf_channel(rd, c, key, i, name, floor, node, dof, w, inp):
    """An FRF-file channel: its output form and FRF index (default: list order)."""
    output = rd.choice(c, "output", f"{key}.output", OUTPUTS, None)
    col = rd.number(c, "column", f"{key}.column", i, integer=True)
    if col < 0:
        raise rd.err(f"{key}.column", "a column index >= 0", col)
    scale, sign = scale_sign(rd, c, key)
    return ChannelConfig(name=name, floor=floor, output=output, column=col, weight=w,
                         node=node, dof=dof, scale=scale, sign=sign)


def _segments(rd, d):
    """(nperseg, overlap) of the Welch estimate (or of the FRF file's averaging)."""
    nperseg = d.get("nperseg")
    if nperseg not in (None, "all"):
        nperseg = rd.number(d, "nperseg", "data.nperseg", positive=True, integer=True)
    overlap = rd.number(d, "overlap", "data.overlap", DataConfig.overlap)
    if not 0 <= overlap < 1:
        raise rd.err("data.overlap", "a fraction in [0, 1)", overlap)
    return nperseg, overlap


def _record_files(rd, d, base, records):
    """Absolute paths of data.records (several records of one test, averaged)."""
    if "records" not in d:
        return []
    if not records:
        raise rd.err("data.records", "records only with type: time_histories", d["records"])
    if not d["records"]:
        raise rd.err("data.records", "a non-empty list of record files", d["records"])
    return file_list(rd, d["records"], "data.records", base)


def _force_from(rd, inp, quantity):
    """data.input.from: a force known as mass x acceleration."""
    if quantity != "force":
        raise rd.err("data.input.from", "only with quantity: force", quantity)
    src = rd.mapping(inp, "data.input.from")
    rd.check_keys(src, "data.input.from", {"column", "mass", "unit"})
    if "column" not in src:
        raise rd.err("data.input.from.column", "the column of the measured acceleration")
    if "column" in inp:
        raise rd.err("data.input.column", "either column or from, not both", inp["column"])
    mass = rd.number(src, "mass", "data.input.from.mass", required=True, positive=True)
    if inp.get("unit") not in (None, "N"):
        raise rd.err("data.input.unit", "no unit with from (the force is mass [kg] x "
                     "acceleration; give the acceleration's unit as from.unit)", inp["unit"])
    return {"column": str(src["column"]), "mass": mass, "unit": src.get("unit")}


def _text_layout(rd, d, records):
    """columns, skip_rows, time_column, fs and screen of the data section."""
    out = {}
    if not records:
        for key in ("columns", "skip_rows", "time_column", "fs", "screen"):
            if key in d:
                raise rd.err(f"data.{key}", "only with type: time_histories", d[key])
        return out
    cols = d.get("columns")
    if cols is not None:
        if not isinstance(cols, list) or not cols or not all(isinstance(x, str) for x in cols) \
                or len(set(cols)) != len(cols):
            raise rd.err("data.columns", "a list of unique column names, in file order", cols)
        out["columns"] = tuple(cols)
    out["skip_rows"] = rd.number(d, "skip_rows", "data.skip_rows", DataConfig.skip_rows,
                                 integer=True)
    if out["skip_rows"] < 0:
        raise rd.err("data.skip_rows", "an integer >= 0", out["skip_rows"])
    if d.get("time_column") is not None:
        out["time_column"] = str(d["time_column"])
    out["fs"] = rd.number(d, "fs", "data.fs", None, positive=True)
    sc = rd.mapping(d, "data.screen")
    rd.check_keys(sc, "data.screen", {"remove", "spike_threshold", "dropout_min_samples"})
    remove = sc.get("remove", ScreenConfig.remove)
    if not isinstance(remove, bool):
        raise rd.err("data.screen.remove", "true or false", remove)
    out["screen"] = ScreenConfig(
        remove=remove,
        spike_threshold=rd.number(sc, "spike_threshold", "data.screen.spike_threshold",
                                  ScreenConfig.spike_threshold,
                                  positive=True),
        dropout_min_samples=rd.number(sc, "dropout_min_samples", "data.screen.dropout_min_samples",
                                      ScreenConfig.dropout_min_samples, positive=True,
                                      integer=True))
    return out


def _check_window(rd, d, records):
    """data.window: a scipy.signal window name; for FRF files also 'none' (not averaged)."""
    if "window" not in d:
        return
    w = d["window"]
    if not records and w == "none":
        return
    try:
        get_window(w, 16)
    except (ValueError, TypeError):
        raise rd.err("data.window", "a scipy.signal window name such as hann or boxcar"
                     + ("" if records else ", or none for an FRF not estimated by windowed "
                        "averaging"), w) from None

