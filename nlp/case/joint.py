"""Several tests of one structure fitted jointly (data.tests): one case with their channels
stacked.

Every test has its own driven DOF and its own FRFs; the structure (M, K, C) and the
sensors are shared. The stacked case keeps each test's channels, renamed
``<channel>@<test label>`` after the first test, each with its test's driven DOF and its
physical sensor (:class:`nlp.solve.problem.Channel`), on the frequencies the tests share.
A sensor family (gain, delay) then acts on one sensor in every test, as the sensor did.
"""

from dataclasses import replace

import numpy as np

from nlp.frf.noise import NoiseModel
from nlp.solve.problem import Target

__all__ = ["stack_tests", "common_grid", "label_of", "JOINT_SEP"]

JOINT_SEP = "@"   # <channel>@<test label>: a later test's channel


def common_grid(grids, rtol=1e-9):
    """(f, maps): the frequencies [Hz] every grid holds, and for each grid the indices of
    those frequencies in it; None when they share less than nine tenths of the shortest."""
    f = np.asarray(grids[0], float)
    for g in grids[1:]:
        k = np.clip(np.searchsorted(g, f), 0, len(g) - 1)
        f = f[np.isclose(np.asarray(g)[k], f, rtol=rtol, atol=0.0)]
    if f.size < 0.9 * min(len(g) for g in grids):
        return None
    maps = [np.clip(np.searchsorted(g, f), 0, len(g) - 1) for g in grids]
    return f, maps


def label_of(channel):
    """The label of the test a stacked channel belongs to ("" for the first test)."""
    return channel.name.split(JOINT_SEP, 1)[1] if JOINT_SEP in channel.name else ""


def stack_tests(cfg, cases, labels, maps, f, names=None):
    """One case of config cfg holding the channels of every test (cases: assembled one per
    test, the first is the case's data.file; labels: their names; maps, f: from common_grid).

    names : channel names to keep (default all), as in :func:`nlp.case.assemble.assemble`.
    """
    c0 = cases[0]
    chans, rows = [], []
    for t, (c, lab) in enumerate(zip(cases, labels)):
        for ch in c.channels:
            name = ch.name if t == 0 else f"{ch.name}{JOINT_SEP}{lab}"
            chans.append(replace(ch, name=name, sensor=None if t == 0 else ch.name,
                                 force_dof=c.target.force_dof))
            rows.append((t, c.channels.index(ch)))
    keep = [i for i, ch in enumerate(chans) if names is None or ch.name in names]
    chans = [chans[i] for i in keep]
    rows = [rows[i] for i in keep]

    def stacked(get):
        return np.array([get(cases[t])[r, maps[t]] for t, r in rows])

    H = stacked(lambda c: c.H)
    coherence = stacked(lambda c: c.coherence) if all(c.coherence is not None
                                                     for c in cases) else None
    noise = NoiseModel(stacked(lambda c: c.noise.sigma_ln), stacked(lambda c: c.noise.sigma_phase),
                       c0.noise.route, min(c.noise.n_averages for c in cases),
                       stacked(lambda c: c.noise.detect)
                       if any(c.noise.sigma_detect is not None for c in cases) else None)
    # every test's selected points, on the shared grid: the windows of one structure's modes
    pos = [np.searchsorted(maps[t], c.selected) for t, c in enumerate(cases)]
    selected = np.unique(np.concatenate([p[(p < len(f)) & (maps[t][np.minimum(p, len(f) - 1)]
                                                            == cases[t].selected)]
                                         for t, p in enumerate(pos)]))
    weight = np.array([cases[t].target.weight[r, 0] for t, r in rows])[:, None] \
        * np.ones(selected.size)
    tg = c0.target
    target = Target(omega=2 * np.pi * f[selected], H=H[:, selected], weight=weight,
                    channels=tuple(chans), excitation=tg.excitation, force_dof=tg.force_dof,
                    ground_r=tg.ground_r, kernel=tg.kernel)
    return replace(c0, config=cfg, f=f, H=H, channels=tuple(chans), selected=selected, target=target,
                   coherence=coherence, noise=noise, records=None)
