"""The prefit: a first solve of every start on a residual that is smooth in the parameters.

ln|H| has a logarithmic singularity at every anti-resonance; with many modes in the band
(tall frames, FE models) the log-magnitude objective has many local minima near the
initial model. Every start is therefore first fitted on a smooth residual
(:func:`prefit_residual`), and the case's residual starts from that fit
(:meth:`nlp.solve.problem.UpdatingProblem.solve`).
"""

__all__ = ["PREFITS", "PREFIT_MAX_ITER", "PREFIT_FAR", "prefit_residual"]

PREFITS = ("auto", "none", "magnitude", "relative_magnitude", "complex")


# Iterations of a prefit. Prefits from starts that reach the noise floor took 7-21 IPOPT
# iterations on tall frames of 16 to 64 storeys (python scripts/bench_scale.py); a start
# from a far corner of a 129-parameter box was still moving after 500 iterations and
# then spent 500 more on ln|H| to end 10,000x above the floor, and at 256 storeys one
# IPOPT prefit iteration takes about 7 s (mostly 9-10 line-search trial values). 50 is
# 2.5x the slowest converging count; a start still moving then ends (a slow start near
# the floor included: other starts reach it, or the flags say none did).
PREFIT_MAX_ITER = 50
PREFIT_FAR = ("Maximum_Iterations_Exceeded", "Max_Iter_Exceeded")


def prefit_residual(requested, residual, backend, has_phase=True):
    """The residual of the first solve of every start, or None (no prefit).

    ln|H| has a logarithmic singularity at every anti-resonance, and an anti-resonance
    of the model a little off the data's makes a spike of the residual that moves with
    the parameters: with many modes in the band (tall frames, FE models) the
    log-magnitude objective has many local minima. The complex residual (H_a - H_x) /
    |H_x| is smooth in the parameters and weighs every mode alike; without phase,
    relative_magnitude (|H_a| - |H_x|) / |H_x| is its magnitude-only analogue (the
    channel-RMS ``magnitude`` form sees only the largest peaks: on a 64-storey frame it
    left the upper storeys free, and the log fit from there ended at 56 % errors).
    Measured on tall frames with per-storey parameters, one start from the nominal
    model (python scripts/bench_scale.py; docs/method/updating.md): log-magnitude
    alone ends at 1,200 (n = 16) times its noise floor; a complex prefit reaches the
    floor at n = 16, 32 and 64; a relative_magnitude prefit reaches 3.1 times it at n = 64.
    ``auto`` prefits log-magnitude fits on the numeric backends (more DOFs than the dense
    backend takes, :data:`nlp.frf.backends.DENSE_MAX`); small models keep the single
    solve (their few modes leave no local minimum near z0 on the shipped cases).
    """
    if requested not in PREFITS:
        raise ValueError(f"prefit must be one of {PREFITS}, got {requested!r}")
    if requested == "auto":
        if residual != "log_magnitude" or backend == "dense":
            return None
        return "complex" if has_phase else "relative_magnitude"
    return None if requested == "none" or requested == residual else requested
