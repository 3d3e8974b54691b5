"""frf-nlp: FRF-based model updating with general viscous damping.

The method follows "Model Updating with Experimental Frequency Response
Function Considering General Damping" (Eqn 25): stiffness and mass as relative
changes of nominal matrices, damping as a general SPD matrix C = L L^T, the FRF
of the state-space system at each frequency, solved as a CasADi NLP.

The Python API (:mod:`nlp.api`)::

    case = nlp.load_case("cases/four_story_shear_frame/case.yaml")
    result = nlp.run(case, out="results/four_story", starts=4, seed=0)
    nlp.diagnose(case, out="results/four_story_diagnosis")

Subpackages, one concept each: :mod:`nlp.case` (the case file), :mod:`nlp.model`
(M, K, parameters, damping), :mod:`nlp.frf` (FRFs, estimation, noise, backends),
:mod:`nlp.io` (readers, importers), :mod:`nlp.solve` (the NLP and its search),
:mod:`nlp.diagnosis` (missing physics), :mod:`nlp.workflow` (one run of a case),
:mod:`nlp.monitoring` (batch updating), :mod:`nlp.output` (files, figures, report),
:mod:`nlp.testing` (independent simulators for tests and benchmarks).

``import nlp`` is light and changes nothing in the environment: the API loads on
first use (PEP 562). The API runs BLAS on one thread per process
(:mod:`nlp.solve.executors.threads`).
"""

from importlib import metadata

try:
    __version__ = metadata.version("frf-nlp")
except metadata.PackageNotFoundError:  # a source tree on sys.path, not installed
    __version__ = "0+unknown"

API = ("load_case", "run", "diagnose", "batch", "ParameterEstimate", "UpdateResult",
       "RunResult", "Diagnosis", "BatchResult")

__all__ = [*API, "__version__"]


def __getattr__(name):
    """The API names, imported on first use."""
    if name in API:
        from nlp import api  # lazy on purpose: see the module docstring

        return getattr(api, name)
    raise AttributeError(f"module 'nlp' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *API])
