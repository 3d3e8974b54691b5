"""Compatibility name: the dense symbolic FRF now lives in :mod:`nlp.frf_backends.dense`."""

from .frf_backends.dense import complex_solve, frf_symbolic  # noqa: F401

__all__ = ["complex_solve", "frf_symbolic"]
