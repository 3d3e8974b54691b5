"""The structural model: nominal M and K with their influence matrices (Eqns 23-24), the updating
parameters (bounds, fixing, tying, scaling) and the damping models (Eqn 25f and lighter options)."""
