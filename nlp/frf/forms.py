"""The output forms of an FRF channel (Eqns 18-19): what a sensor measures per unit input.

A channel's FRF is the receptance H (displacement per input) times (j w)^p:
``receptance`` p = 0, ``mobility`` p = 1 (j w H, velocity), ``accelerance`` p = 2
(-w^2 H, acceleration relative to the ground under ground input), and for ground
input ``absolute_accelerance`` p = 2 plus 1 (-w^2 H + 1: relative response plus the
ground's own acceleration, what an accelerometer on a shake table reads).
"""

__all__ = ["OUTPUTS", "POWER", "QUANTITY", "OUTPUT_OF_QUANTITY"]

OUTPUTS = ("receptance", "mobility", "accelerance", "absolute_accelerance")

# power p of (j w) that turns the receptance into the form [-]
POWER = {"receptance": 0, "mobility": 1, "accelerance": 2, "absolute_accelerance": 2}

# the response quantity in words and its SI unit
QUANTITY = {"receptance": ("displacement", "m"), "mobility": ("velocity", "m/s"),
            "accelerance": ("acceleration", "m/s^2"),
            "absolute_accelerance": ("absolute acceleration", "m/s^2")}

# a measured record's quantity -> the form of its FRF (acceleration: set by the input)
OUTPUT_OF_QUANTITY = {"displacement": "receptance", "velocity": "mobility"}
