"""Physical plausibility of a refitted candidate, beside its statistical evidence.

A family is a description of a kind of physics; outside the sizes that physics has, a
fitted candidate is a curve fit that happens to lower the misfit, not a finding. Each
limit here is an argument from what the family describes, not a rate measured on cases:

* an appendage (secondary oscillator) is a light subsystem on a floor: equipment, a
  tuned mass damper, a secondary element. Tuned mass dampers are designed at mass ratios
  of 1-10 % of the modal mass (Den Hartog, Mechanical Vibrations, 1956, ch. 3.3;
  Warburton, Earthq. Eng. Struct. Dyn. 10, 1982), and equipment on a floor at a few
  per cent. A subsystem of a fifth of a floor's mass or more, tuned inside the band,
  splits a storey mode by about +-sqrt(mu)/2 (over 20 %): it is a storey of its own,
  which an engineer would have modelled, and a fit that needs one is more likely
  absorbing a mismatch elsewhere (MU_MAX).
"""

__all__ = ["MU_MAX", "plausible"]

MU_MAX = 0.2   # largest appendage mass, as a fraction of the mean floor mass


def plausible(r):
    """(ok, reason): the refitted candidate r's parameters lie where its family's physics
    lives (module docstring)."""
    if r["physics"] == "secondary_oscillator":
        name = next((n for n in r["parameters"] if n.startswith("mu")), None)
        if name is not None and r["parameters"][name] > MU_MAX:
            return False, (f"{name} = {r['parameters'][name]:.3g} is above {MU_MAX:g} of a floor's "
                           "mass: not an appendage but a storey-sized subsystem, physically "
                           "implausible as this family")
    return True, ""
