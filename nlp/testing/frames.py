"""Shear-frame matrices written independently of `nlp.model`."""

import numpy as np


def shear_K(k):
    """Shear-frame stiffness [N/m] from story stiffnesses k (story i joins floor i-1 and
    floor i; floor 0 is the ground)."""
    n = len(k)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k[i]
        if i + 1 < n:
            K[i, i] += k[i + 1]
            K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    return K
