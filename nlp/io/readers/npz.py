"""NumPy ``.npz`` archives: named records, or FRFs ``f`` [Hz] and ``H`` (n_ch, n_f) with
optional ``coherence`` and ``n_averages``."""

import numpy as np

from nlp.errors import InputError

__all__ = ["npz_columns", "frf_from_npz", "frf_coherence"]


def npz_columns(path):
    """All arrays of an .npz file by name."""
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def frf_from_npz(path):
    """(f [Hz], H (n_ch, n_f)) from the arrays ``f`` and ``H`` of an .npz file."""
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in ("f", "H") if k not in z.files]
            if missing:
                raise InputError(path, missing[0], "arrays 'f' and 'H' in the .npz file",
                                 got=z.files)
            f, H = z["f"].astype(float), np.atleast_2d(z["H"]).astype(complex)
    except InputError:
        raise
    except Exception as exc:  # empty, truncated or not a zip archive at all
        raise InputError(path, "<file>", "a readable .npz file with arrays 'f' and 'H'",
                         got=f"{type(exc).__name__}: {exc}") from None
    return f, H


def frf_coherence(path, n_ch, n_f):
    """Coherence and averaging count stored with FRFs in an .npz file (``path``), if any.

    Optional arrays ``coherence`` (n_ch, n_f), in [0, 1], and ``n_averages``
    (a positive number: the averages behind the FRFs, overlap-corrected if the
    writer knew it).

    Returns
    -------
    coherence : ndarray (n_ch, n_f) or None
    n_averages : float or None
    """
    with np.load(path, allow_pickle=False) as z:
        coh = np.atleast_2d(z["coherence"]).astype(float) if "coherence" in z.files else None
        nav = np.ravel(z["n_averages"]) if "n_averages" in z.files else None
    if coh is not None and (coh.shape != (n_ch, n_f) or not np.all(np.isfinite(coh))
                            or coh.min() < 0 or coh.max() > 1):
        raise InputError(path, "coherence", f"an array of values in [0, 1] shaped ({n_ch}, {n_f}) "
                         "like H", got=f"shape {coh.shape}")
    if nav is not None:
        if nav.size != 1 or not np.isfinite(nav[0]) or not nav[0] > 0:
            raise InputError(path, "n_averages", "one positive number (averages behind the FRFs)",
                             got=nav.tolist())
        nav = float(nav[0])
    return coh, nav
