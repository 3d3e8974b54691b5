"""MATLAB ``.mat`` files: named records (vectors stored as 1 x N or N x 1)."""

import scipy.io

__all__ = ["mat_columns"]


def mat_columns(path):
    """All variables of a .mat file by name (MATLAB's own ``__header__`` etc. left out)."""
    return {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
