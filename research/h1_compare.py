"""Two records' H1 of one channel side by side over a band: magnitude and coherence.

    python research/h1_compare.py RECORDS_A RECORDS_B CHANNEL FMIN FMAX [--fs 100] [--nperseg 4096]

RECORDS_*: records.csv files of the lab generator (column `input` and the channel's column,
e.g. acc1). Hann window, half overlap, as the lab's case files ask. Used to see whether a
development null's "resonance the model lacks" is in the records with and without the lab's
joints (research/nulls_without_joints.py).
"""

import argparse

import numpy as np
from scipy.signal import csd, welch


def h1(path, column, fs, nperseg):
    """Frequencies, H1 and coherence of `column` against `input`."""
    names = open(path).readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    x, y = data[:, names.index("input")], data[:, names.index(column)]
    kw = dict(fs=fs, nperseg=nperseg, noverlap=nperseg // 2, window="hann")
    f, pxy = csd(x, y, **kw)
    _, pxx = welch(x, **kw)
    _, pyy = welch(y, **kw)
    return f, pxy / pxx, np.abs(pxy) ** 2 / (pxx * pyy)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("column")
    ap.add_argument("fmin", type=float)
    ap.add_argument("fmax", type=float)
    ap.add_argument("--fs", type=float, default=100.0)
    ap.add_argument("--nperseg", type=int, default=4096)
    a = ap.parse_args()
    f, ha, ca = h1(a.a, a.column, a.fs, a.nperseg)
    _, hb, cb = h1(a.b, a.column, a.fs, a.nperseg)
    print("f [Hz]   |H| a    coh a   |H| b    coh b")
    for i in np.flatnonzero((f >= a.fmin) & (f <= a.fmax)):
        print(f"{f[i]:6.3f}  {abs(ha[i]):7.3f}  {ca[i]:6.3f}  {abs(hb[i]):7.3f}  {cb[i]:6.3f}")


if __name__ == "__main__":
    main()
