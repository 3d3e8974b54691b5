"""Reading a case file's YAML: the loader, typed access to a mapping with errors that
name the file and the key, and the value kinds several sections share (a location,
a file, a calibration, a scheduler address)."""

import math
import os
import re

import yaml

from nlp.case.schema import ChannelConfig
from nlp.errors import InputError

__all__ = ["YamlLoader", "Reader", "existing", "file_list", "scale_sign", "dof_spec",
           "location", "scheduler_address"]


class YamlLoader(yaml.SafeLoader):
    """SafeLoader that reads YAML 1.2 floats too: ``2.552e6`` and ``1e-3`` are numbers
    (YAML 1.1 wants a dot and a signed exponent, and would read them as text)."""


YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


class Reader:
    """Typed access to a YAML mapping with errors that name file and key."""

    def __init__(self, file):
        self.file = file

    def err(self, key, expected, got=None):
        """The InputError for a key of this file."""
        return InputError(self.file, key, expected, got)

    def mapping(self, d, key, required=False):
        """The mapping at dotted ``key`` of d ({} when absent and not required)."""
        if key is not None:
            if not isinstance(d, dict):
                raise self.err(key.rsplit(".", 1)[0], "a mapping", d)
        v = d if key is None else d.get(key.rsplit(".", 1)[-1])
        if v is None:
            if required:
                raise self.err(key, "a mapping (this section is required)")
            return {}
        if not isinstance(v, dict):
            raise self.err(key, "a mapping of keys to values", v)
        return v

    def check_keys(self, d, key, allowed):
        """Refuse a key of d not in ``allowed``."""
        for k in d:
            if k not in allowed:
                raise self.err(f"{key}.{k}" if key else k,
                               f"one of the known keys {sorted(allowed)}", k)

    def number(self, d, key, path, default=None, positive=False, required=False, integer=False):
        """d[key] as a finite float (or int), ``default`` when absent."""
        if key not in d or d[key] is None:
            if required:
                raise self.err(path, "a number (required)")
            return default
        v = d[key]
        kind = "an integer" if integer else "a number"
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.err(path, f"{kind}{' > 0' if positive else ''}", v)
        if integer and int(v) != v:
            raise self.err(path, kind, v)
        if positive and v <= 0:
            raise self.err(path, f"{kind} > 0", v)
        return int(v) if integer else float(v)

    def choice(self, d, key, path, choices, default):
        """d[key], one of ``choices``."""
        v = d.get(key, default)
        if v not in choices:
            raise self.err(path, f"one of {list(choices)}", v)
        return v

    def numbers(self, v, path, length=None, positive=False):
        """A non-empty list of finite numbers as a tuple of floats."""
        if not isinstance(v, (list, tuple)) or not v:
            raise self.err(path, "a non-empty list of numbers", v)
        out = []
        for i, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise self.err(f"{path}[{i}]", "a finite number", x)
            if positive and x <= 0:
                raise self.err(f"{path}[{i}]", "a number > 0", x)
            out.append(float(x))
        if length is not None and len(out) != length:
            raise self.err(path, f"a list of {length} numbers", f"{len(out)} numbers")
        return tuple(out)

    def interval(self, v, path):
        """[lower, upper] with lower < upper."""
        lo, hi = self.numbers(v, path, length=2)
        if not lo < hi:
            raise self.err(path, "[lower, upper] with lower < upper", list(v))
        return lo, hi


def existing(rd, name, key, base):
    """The absolute path of an existing file named relative to the case file."""
    f = os.path.join(base, str(name))
    if not os.path.isfile(f):
        raise rd.err(key, "an existing file (relative to the case file)", name)
    return f


def file_list(rd, v, key, base):
    """Absolute paths of a list of existing files named relative to the case file."""
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise rd.err(key, "a list of file names (relative to the case file)", v)
    out = []
    for i, x in enumerate(v):
        p = os.path.join(base, x)
        if not os.path.isfile(p):
            raise rd.err(f"{key}[{i}]", "an existing file (relative to the case file)", x)
        out.append(p)
    return out


def scale_sign(rd, d, key):
    """Per-channel calibration: file value x scale x sign = value in the stated unit."""
    scale = rd.number(d, "scale", f"{key}.scale", ChannelConfig.scale, positive=True)
    sign = d.get("sign", ChannelConfig.sign)
    if isinstance(sign, bool) or sign not in (1, -1):
        raise rd.err(f"{key}.sign", "1 or -1", sign)
    return scale, int(sign)


def dof_spec(rd, d, key, path):
    """A DOF as given (number 1-6 or name ux..rz); checked against the model at assembly."""
    v = d.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, str)) or (isinstance(v, int) and not 1 <= v <= 6):
        raise rd.err(f"{path}.{key}", "a DOF number 1-6 or a name (ux, uy, uz, rx, ry, rz)", v)
    return v


def location(rd, d, path, base=False):
    """(floor, node, dof): a floor (shear-frame shorthand, or a row of a matrix model)
    or a node and DOF of an imported model; base: floor 0 (the base) is allowed."""
    if "node" in d or "dof" in d:
        if "floor" in d:
            raise rd.err(f"{path}.floor", "either floor or node and dof, not both", d["floor"])
        node = rd.number(d, "node", f"{path}.node", required=True, integer=True)
        if d.get("dof") is None:
            raise rd.err(f"{path}.dof", "a DOF number 1-6 or a name (ux, uy, uz, rx, ry, rz)")
        return None, node, dof_spec(rd, d, "dof", path)
    if "floor" not in d:
        raise rd.err(f"{path}.floor", "a floor number (required, 1-based), or node and dof")
    floor = rd.number(d, "floor", f"{path}.floor", required=True, integer=True)
    if floor < (0 if base else 1):
        raise rd.err(f"{path}.floor", "a floor number >= 1" + (" (0: a sensor on the base)" if base
                                                                else ""), floor)
    return floor, None, None


def scheduler_address(err, v, key):
    """A Dask scheduler address (protocol://host:port) or None."""
    if v is None:
        return None
    if not isinstance(v, str) or "://" not in v:
        raise err(key, "a Dask scheduler address such as tcp://host:8786", v)
    return v
