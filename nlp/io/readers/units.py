"""Units of measured records and FRFs, and their multipliers to SI."""

from types import MappingProxyType

from nlp.errors import InputError

__all__ = ["G", "UNITS", "QUANTITIES", "unit_factor", "frf_unit_factor"]

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

