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
sparse | reduced): ``auto`` is dense up to ``DENSE_MAX`` DOFs, sparse above. Added
physics (:mod:`nlp.diagnosis.families`) is carried by the sparse backend as sparse
terms (:mod:`.terms`) above ``ENRICHED_DENSE_MAX`` DOFs (or when sparse or reduced is
asked for; the reduced backend projects them on its basis); below, and for families the
terms do not carry, by the dense one.
"""

from nlp.frf.backends.terms import supported

__all__ = ["BACKENDS", "DENSE_MAX", "ENRICHED_DENSE_MAX", "choose"]

BACKENDS = ("auto", "dense", "sparse", "reduced")
DENSE_MAX = 6  # DOFs: above, the cold build of the dense backend (gcc) outweighs its faster solves (README)
# DOFs up to which added physics stays on the dense backend: the shear frames that diagnosis
# was developed on keep the backend they were measured with; an FE model goes sparse
ENRICHED_DENSE_MAX = 64


def choose(requested, n, enrichments=(), damping=None, channels=()):
    """The backend that runs: ``requested`` unless it is ``auto``; dense where the sparse
    terms cannot carry the families (:func:`nlp.frf.backends.terms.supported`)."""
    if requested not in BACKENDS:
        raise ValueError(f"frf_backend must be one of {BACKENDS}, got {requested!r}")
    if enrichments:
        if not supported(enrichments, damping, channels) or (requested == "auto" and n <= ENRICHED_DENSE_MAX):
            return "dense"
        return "sparse" if requested == "auto" else requested
    if requested != "auto":
        return requested
    return "dense" if n <= DENSE_MAX else "sparse"
