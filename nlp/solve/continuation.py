"""A start found by frequency-band continuation: fit the low band first, then widen it.

On a large model fitted over many modes (the 2,100-DOF 3-D frame: 795 points, 0.5-12
Hz, about 30 modes) the log-magnitude objective has local minima where higher modes
are paired with the wrong peaks; a local solve from the initial model stops in one
(f = 51 there, against 0.80 at the truth). The lowest modes are few and far apart,
so the fit of a low band from the initial model lands in the right basin, and each
wider band starts from the previous fit:

    z_1 = argmin f(z; f <= band_1) from z0,  z_k = argmin f(z; f <= band_k) from z_{k-1},

ending with the case's own band. The last solve competes with the search's starts.
"""

from dataclasses import replace
import time

from nlp.case.assemble import assemble, build_problem

__all__ = ["band_continuation"]


def band_continuation(case, bands, log=print):
    """The local solve at the end of a continuation over ``bands`` [Hz] and the case's band.

    Parameters
    ----------
    case : nlp.case.assemble.Case
    bands : sequence of float
        Increasing upper frequencies [Hz] below the case's highest fitted frequency; the
        sub-band cases keep every other setting (frequency selection, noise, channels).

    Returns
    -------
    (problem, LocalResult)
        The full-band problem and its local solve from the last sub-band fit.
    """
    cfg = case.config
    top = float(case.f[case.selected].max())
    z = case.params.z0
    for fmax in [b for b in bands if b < top]:
        t0 = time.perf_counter()
        sub = assemble(replace(cfg, frequencies=replace(cfg.frequencies, fmax=float(fmax))),
                       channels=[c.name for c in case.channels])
        res = build_problem(sub, centre=z, check=False).solve(z)  # a start only: not checked
        log(f"band continuation: up to {fmax:g} Hz ({sub.target.omega.size} points) f "
            f"{res.f:.6g}, {res.iterations} iterations, {res.status}, "
            f"{time.perf_counter() - t0:.1f} s with the build")
        z = res.z
    problem = build_problem(case, centre=z)
    res = problem.solve(z)
    log(f"band continuation: whole band f {res.f:.6g}, {res.iterations} iterations, {res.status}")
    return problem, res
