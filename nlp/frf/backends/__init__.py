"""How the NLP evaluates the model's FRF and its derivatives: three backends, one choice.

``dense``    the FRF as a CasADi SX expression (complex Gaussian elimination,
             :mod:`.dense`), differentiated by CasADi and compiled to C; fastest
             for small n, its cost grows like n^3 per frequency.
``sparse``   the exact FRF with one sparse factorisation per frequency and
             analytic adjoint sensitivities (:mod:`.sparse`), cost following the
             sparsity of M, K (and a rank-m damping term).
``reduced``  the sparse machinery on a fixed basis (band modes plus static and
             residual-flexibility vectors, :mod:`.reduced`), checked against
             the exact FRF on the case's frequencies.

``choose`` picks one from the case key ``model.frf_backend`` (auto | dense |
sparse | reduced): ``auto`` is dense up to ``DENSE_MAX`` DOFs and when added
physics (:mod:`nlp.diagnosis.families`, dense only) is present, sparse above.
"""

__all__ = ["BACKENDS", "DENSE_MAX", "choose"]

BACKENDS = ("auto", "dense", "sparse", "reduced")
DENSE_MAX = 6  # DOFs: above, the cold build of the dense backend (gcc) outweighs its faster solves (README)


def choose(requested, n, enrichments=()):
    """The backend that runs: ``requested`` unless it is ``auto``."""
    if requested not in BACKENDS:
        raise ValueError(f"frf_backend must be one of {BACKENDS}, got {requested!r}")
    if enrichments:
        return "dense"
    if requested != "auto":
        return requested
    return "dense" if n <= DENSE_MAX else "sparse"
