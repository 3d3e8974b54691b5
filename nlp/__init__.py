"""frf-nlp: FRF-based model updating with general viscous damping.

The method follows "Model Updating with Experimental Frequency Response
Function Considering General Damping" (Eqn 25): stiffness and mass as relative
changes of nominal matrices, damping as a general SPD matrix C = L L^T, the FRF
of the state-space system at each frequency, solved as a CasADi NLP.

Modules (one concept each)
--------------------------
model, parameters   nominal matrices, influence matrices, bounds/fix/tie
damping             general (Cholesky), Rayleigh, modal, general on band modes, dashpots
frf                 numpy reference FRFs
frf_backends        the FRF inside the NLP: dense (CasADi SX), sparse, reduced
problem, codegen    the NLP built once; compiled per-frequency pieces
search              scatter search over start points
identify            identifiability (Jacobian SVD, scale null space), errors
freqsel, estimate   frequency-point selection; FRF estimation from records
readers             time histories and FRFs from files, units to SI
metrics, simulate   FDAC/FRAC/MAC; exact-discretisation time simulation
peakpick, verify    measured modes vs model; time-domain replay
physics, diagnose   missing-physics families; ``frf-nlp diagnose``
config, case        typed case file; assembling a case into a problem
results, plots      result files and figures; report (report.html)
workflow, cli       one run of a case; the ``frf-nlp`` command
"""

import os

# Small matrix products dominate the numeric FRF backends; a multi-threaded BLAS
# on a busy 2-core machine made a 66 x 66 product 500x slower (measured). Set before
# numpy loads (the CLI imports nlp first); an explicit user setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
