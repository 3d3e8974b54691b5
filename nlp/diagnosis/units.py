"""A finding's parameters in an engineer's units: the one table of physical conversions.

The families (:mod:`nlp.diagnosis.families`) fit their parameters in the scales the
solver likes: a base stiffness as log10 of N/m, an appendage's mass as a ratio of the mean
floor mass, a gain error as a fraction. The report and the printed conclusion show them
here as a quantity with its unit and a relative standard error.

Error propagation (first order): a parameter fitted as v = log10(x) has
SE(x) / x = ln(10) SE(v); a linear one SE(x) / |x|; a scaled one (x = c v) the same
relative error as v.
"""

from dataclasses import dataclass
import math

__all__ = ["PHYSICAL", "Quantity", "quantity", "quantities", "describe", "fmt_sig",
           "place", "FAMILY_WORDS"]

# (family, parameter-name prefix) -> (label, symbol, unit, conversion). conversion:
# "linear" (the value as fitted), "log10" (10**v), "percent" (100 v), "inverse" (1/v),
# "m_ref" (v times the
# mean floor mass [kg]: shown beside the ratio when that mass is known). The longest
# matching prefix wins. A family whose parameters change name or scale is updated here.
PHYSICAL = {
    ("added_mass", "dm"): ("added mass", "dm", "kg", "linear"),
    ("base_flexibility", "m_base"): ("base mass", "m_b", "kg", "linear"),
    ("base_flexibility", "log10_kb"): ("base stiffness", "k_b", "N/m", "log10"),
    ("base_flexibility", "c_base"): ("base dashpot", "c_b", "N s/m", "linear"),
    ("secondary_oscillator", "mu"): ("appendage mass ratio to the mean floor mass", "mu", "%",
                                     "percent"),
    ("secondary_oscillator", "f_s"): ("appendage frequency", "f_s", "Hz", "linear"),
    ("secondary_oscillator", "zeta_s"): ("appendage damping ratio", "zeta_s", "%", "percent"),
    ("local_damper", "c"): ("dashpot", "c", "N s/m", "linear"),
    ("hysteretic_damping", "eta"): ("loss factor", "eta", "%", "percent"),
    ("nonadjacent_coupling", "k"): ("coupling stiffness", "k", "N/m", "linear"),
    ("frame_action", "rho_inv"): ("beam-column stiffness ratio", "rho", "", "inverse"),
    ("sensor_gain", "gain_"): ("gain error", "g", "%", "percent"),
    ("sensor_delay", "delay_ms_"): ("time delay", "tau", "ms", "linear"),
    ("nonlinearity", "k"): ("story stiffness", None, "N/m", "linear"),
    ("nonlinearity", "relative_change"): ("stiffness change between levels", "dk/k", "%",
                                          "percent"),
    ("nonlinearity", "kappa"): ("even restoring force per unit |drift|", "kappa", "N/m",
                                "linear"),
    ("nonlinearity", "k_equivalent"): ("equivalent linear story stiffness", "k_eq", "N/m",
                                       "linear"),
    ("nonlinearity", "bilinear_delta"): ("stiffness loss on the soft side (bilinear reading)",
                                         "delta", "%", "percent"),
}
# derived quantities shown after a parameter: (family, prefix) -> (label, symbol, unit, ref)
DERIVED = {("secondary_oscillator", "mu"): ("appendage mass", "m_s", "kg", "m_ref")}
# labels that depend on the model, (family, prefix, refs key) -> label: under Rayleigh
# damping the law already damps the base (a0 m_b + a1 k_b), so c_b is only the damping
# beyond it (families.BaseFlexibility), and a reader must not take it for the whole dashpot
# an FE model without node coordinates has no floors: its locations are the channels' DOFs
# (nlp.diagnosis.locations), so m_ref is the mean mass there, not a floor's
IN_CONTEXT = {("base_flexibility", "c_base", "rayleigh"): "base dashpot beyond the Rayleigh law",
              ("secondary_oscillator", "mu", "channel_masses"):
                  "appendage mass ratio to the mean mass at the channels' DOFs"}

FAMILY_WORDS = {"added_mass": "an unmodelled mass", "base_flexibility": "a flexible base",
                "secondary_oscillator": "an appendage (secondary oscillator)",
                "local_damper": "a concentrated damper", "hysteretic_damping": "hysteretic "
                "(frequency-independent) damping", "nonadjacent_coupling": "a stiffness "
                "coupling between non-adjacent floors (non-shear behaviour)",
                "frame_action": "frame action (the beams bend: not a shear building)",
                "sensor_gain": "a sensor calibration (gain) error",
                "sensor_delay": "a sensor time delay", "nonlinearity": "a level-dependent "
                "(nonlinear) stiffness"}


@dataclass(frozen=True)
class Quantity:
    """One parameter in physical units: value, unit, relative standard error (None when
    unknown; inf when the value is 0), and the standard error in the same unit."""
    label: str
    symbol: str
    value: float
    unit: str
    relative_se: "float | None"
    se: "float | None"


def _rule(table, physics, name):
    keys = [p for f, p in table if f == physics and name.startswith(p)]
    return table[(physics, max(keys, key=len))] if keys else None


def _relative(x, sx):
    if sx is None:
        return None
    return abs(sx) / abs(x) if x else math.inf


def quantity(physics, name, value, se=None):
    """The parameter ``name`` of a ``physics`` finding as a Quantity (value as fitted when
    the table has no rule for it, labelled by its name)."""
    rule = _rule(PHYSICAL, physics, name)
    if rule is None:
        return Quantity(name, name, value, "", _relative(value, se), se)
    label, symbol, unit, how = rule
    symbol = symbol or name.replace("_level", " at level ")
    if how == "log10":
        x = 10.0 ** value
        rel = None if se is None else math.log(10.0) * abs(se)   # d(10^v)/10^v = ln10 dv
        return Quantity(label, symbol, x, unit, rel, None if rel is None else rel * x)
    if how == "inverse":   # fitted as 1/x, so that its null (x infinite) is 0
        x = 1.0 / value if value else math.inf
        rel = None if se is None else (abs(se / value) if value else math.inf)
        return Quantity(label, symbol, x, unit, rel, None if rel is None else rel * abs(x))
    scale = 100.0 if how == "percent" else 1.0
    return Quantity(label, symbol, scale * value, unit, _relative(value, se),
                    None if se is None else scale * abs(se))


def quantities(finding, refs=None):
    """Every numeric parameter of a finding (diagnosis.json form) as (name, Quantity), in
    order, each followed by its derived quantities (under the same name) when ``refs``
    (m_ref [kg], ...) gives them; ``refs["rayleigh"]`` (the model's damping is a Rayleigh
    law) and ``refs["channel_masses"]`` (m_ref is the channels' DOFs' mean mass) relabel the
    parameters of IN_CONTEXT."""
    out = []
    unc = finding.get("uncertainty") or {}
    physics = finding.get("physics", "")
    for name, v in (finding.get("parameters") or {}).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        q = quantity(physics, name, float(v), unc.get(name))
        for (fam, prefix, key), label in IN_CONTEXT.items():
            if fam == physics and name.startswith(prefix) and (refs or {}).get(key):
                q = Quantity(label, q.symbol, q.value, q.unit, q.relative_se, q.se)
        out.append((name, q))
        d = _rule(DERIVED, physics, name)
        if d and refs and refs.get(d[3]):
            x = float(v) * refs[d[3]]
            out.append((name, Quantity(d[0], d[1], x, d[2], q.relative_se,
                                       None if q.relative_se is None else q.relative_se * abs(x))))
    return out


def fmt_sig(x, sig=3):
    """x to ``sig`` significant figures, as an engineer writes it: 2.56, 0.012, 12400,
    1.24e5."""
    if x is None or x != x:
        return "n/a"
    if x == 0:
        return "0"
    e = int(math.floor(math.log10(abs(x))))
    if -3 <= e < 5:
        return f"{round(x, sig - 1 - e):.{max(sig - 1 - e, 0)}f}".rstrip("0").rstrip(".") \
            if sig - 1 - e > 0 else f"{round(x, sig - 1 - e):.0f}"
    m, ex = f"{x:.{sig - 1}e}".split("e")
    return f"{m}e{int(ex)}"


def _percent(rel):
    """A relative error as '2.1 %', '7 %', '250 %'."""
    p = 100 * rel
    return f"{p:.0f} %" if p >= 10 else f"{p:.2g} %"


def describe(q):
    """'k_b = 1.24e4 N/m (± 2.1 %)'; a quantity in percent gives its error in percentage
    points and relative: 'g = -12.4 % (± 1.05 % points, 8.5 % relative)'."""
    val = f"{q.symbol} = {fmt_sig(q.value)}{' ' + q.unit if q.unit else ''}"
    if q.relative_se is None:
        return val
    rel = _percent(q.relative_se) if math.isfinite(q.relative_se) else None
    if q.unit == "%":
        return f"{val} (± {fmt_sig(q.se, 2)} % points" + (f", {rel} relative)" if rel else ")")
    return f"{val} (± {rel})" if rel else f"{val} (± {fmt_sig(q.se, 2)} {q.unit})".rstrip()


def place(loc):
    """Where a finding acts, in words: 'at floor 3', 'in story 2 (between floor 1 and
    floor 2)', 'on channel a2', 'in the whole structure'."""
    loc = loc or {}
    if "where" in loc:      # an FE model's location in its own terms (nlp.diagnosis.locations)
        return loc["where"]
    if "floor" in loc:
        return f"at floor {loc['floor']}"
    if "between" in loc:
        a, b = loc["between"]
        lo = "the ground" if a == 0 else f"floor {a}"
        return (f"in story {b} (between {lo} and floor {b})" if b == a + 1
                else f"between {lo} and floor {b}")
    if "channel" in loc:
        return f"on channel {loc['channel']}"
    return "in the whole structure"
