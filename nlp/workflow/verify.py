"""Time-domain verification: replay the measured input through a model (Figures 7-8).

The updated model is simulated under the recorded input (exact first-order-
hold discretisation, :func:`nlp.frf.simulate.simulate`) and every response channel
is compared with its record: normalised RMS error, correlation coefficient and
peak error, and a figure of the whole record with a close-up around the
largest measured response.
"""

import os

import numpy as np

from nlp.frf.metrics import correlation, nrmse, peak_error
from nlp.output.plots import new_figure, save_figure
from nlp.frf.simulate import simulate

__all__ = ["replay", "plot_replay"]

_FIELD = {"acceleration": "a", "displacement": "q", "velocity": "v"}
_UNIT = {"acceleration": "m/s$^2$", "displacement": "m", "velocity": "m/s"}


def replay(M, C, K, records, data_config):
    """Simulated and measured records of every channel, with their metrics.

    records : readers.TimeHistories (SI units) with the input under
    ``"__input__"``; data_config : config.DataConfig of the case.
    Returns a dict channel -> {"t", "sim", "meas", "nrmse", "correlation",
    "peak_error", "quantity"}.
    """
    inp = data_config.input
    ground = inp["quantity"] == "ground_acceleration"
    resp = simulate(M, C, K, records.data["__input__"], records.fs,
                    input="ground" if ground else "force",
                    dof=None if ground else inp["floor"] - 1)
    out = {}
    for ch in data_config.channels:
        # a sensor on the base (floor 0) of the fixed-base model records the ground input
        sim = records.data["__input__"] if ch.floor == 0 else \
            getattr(resp, _FIELD[ch.quantity])[ch.floor - 1]
        meas = records.data[ch.name]
        out[ch.name] = {"t": resp.t, "sim": sim, "meas": meas, "quantity": ch.quantity,
                        "nrmse": float(nrmse(sim, meas)),
                        "correlation": float(correlation(sim, meas)),
                        "peak_error": float(peak_error(sim, meas))}
    return out


def plot_replay(out_dir, name, rep, closeup_seconds=3.0):
    """Whole record and a close-up around the largest measured value; returns the path."""
    t, sim, meas = rep["t"], rep["sim"], rep["meas"]
    i = int(np.argmax(np.abs(meas)))
    lo = max(t[0], t[i] - closeup_seconds / 2)
    win = (t >= lo) & (t <= lo + closeup_seconds)
    fig = new_figure(figsize=(8, 6))
    a1, a2 = fig.subplots(2, 1)
    for ax, sel in ((a1, slice(None)), (a2, win)):
        ax.plot(t[sel], meas[sel], color="0.4", lw=1.6, label="measured")
        ax.plot(t[sel], sim[sel], color="tab:red", lw=0.9, label="simulated (updated model)")
        ax.set_ylabel(f"{rep['quantity']} [{_UNIT[rep['quantity']]}]")
        ax.grid(alpha=0.3)
    a1.set_title(f"{name}: NRMSE {100 * rep['nrmse']:.1f} %, correlation {rep['correlation']:.3f}, "
                 f"peak error {100 * rep['peak_error']:+.1f} %")
    a1.legend(loc="upper left", fontsize=8)
    a2.set_xlabel("time [s]")
    a2.set_title(f"close-up: {closeup_seconds:g} s around the largest response", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, os.path.join(out_dir, f"time_{name}.png"))
