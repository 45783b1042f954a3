#!/usr/bin/python3
"""One case of tests/bench/vs_scipy.sh: the timing rows and how far scipy_way.py's levels lie from noisemon's.

    vs_scipy_report.py LABEL ENGINE_S BASE EPOCH_UTIME VARIANT...

VARIANT: K (scipy_way.py --oversample K) or K:ODE (--oversample K --ode ODE). Reads BASE.import, BASE.replay,
BASE.scipyVARIANT ("wall cpu" seconds), BASE.noisemon.csv (replay --csv) and BASE.scipyVARIANT.csv (scipy_way.py
--csv). Cycles are matched by their start time (noisemon: (utime - EPOCH) / 1e6); noisemon's settling cycles are
left out. A K:solve_ivp variant is also compared with K:tustin, cycle by cycle, when both are given.
"""
import sys

import numpy as np


def times(path):
    return [float(x) for x in open(path).read().split()]


def row(what, wall, cpu, engine_s):
    print(f"  {what:44s} {wall:8.2f} {cpu:8.2f} {engine_s / wall:9.1f}x")


def energy_mean(levels):
    return 10 * np.log10(np.mean(10 ** (levels / 10)))


def agreement(base, k, epoch):
    """Energy-mean Lp(A), predicted and measured, of both over the same (non-settling) cycles."""
    n = np.genfromtxt(f"{base}.noisemon.csv", delimiter=",", names=True, dtype=None, encoding=None)
    s = np.genfromtxt(f"{base}.scipy{k}.csv", delimiter=",", names=True)
    start = (n["utime"] - epoch) / 1e6
    j = np.clip(np.searchsorted(s["t_start_s"], start - 5e-4), 0, len(s) - 1)
    ok = (np.abs(s["t_start_s"][j] - start) < 5e-4) & ((n["flags"] & 1) == 0)  # same cycle, not settling
    for q in ("predicted", "measured"):
        a, b = s[f"lpa_{q}_db"][j[ok]], n[f"lpa_{q}_db"][ok]
        print(f"    Lp(A) {q:9s} over {ok.sum()} cycles: noisemon {energy_mean(b):.2f}, SciPy {energy_mean(a):.2f} "
              f"dB(A): SciPy - noisemon {energy_mean(a) - energy_mean(b):+.2f} dB "
              f"(per cycle {np.min(a - b):+.2f} .. {np.max(a - b):+.2f})")


def ode_agreement(base, k):
    """Predicted Lp(A) per cycle, --ode solve_ivp against --ode tustin (same cycles: same run, same K)."""
    a = np.genfromtxt(f"{base}.scipy{k}:solve_ivp.csv", delimiter=",", names=True)["lpa_predicted_db"]
    b = np.genfromtxt(f"{base}.scipy{k}:tustin.csv", delimiter=",", names=True)["lpa_predicted_db"]
    print(f"    Lp(A) predicted over {len(a)} cycles: solve_ivp - tustin {energy_mean(a) - energy_mean(b):+.3f} dB "
          f"(per cycle {np.min(a - b):+.3f} .. {np.max(a - b):+.3f})")


def main():
    label, engine_s, base, epoch = sys.argv[1], float(sys.argv[2]), sys.argv[3], int(sys.argv[4])
    variants = sys.argv[5:]
    imp, rep = times(f"{base}.import"), times(f"{base}.replay")
    nm = [imp[0] + rep[0], imp[1] + rep[1]]
    print(f"{label}: {engine_s:.2f} s of engine time")
    row("noisemon import", *imp, engine_s)
    row("noisemon replay", *rep, engine_s)
    row("noisemon import + replay", *nm, engine_s)
    for v in variants:
        k, _, ode = v.partition(":")
        sp = times(f"{base}.scipy{v}")
        row("scipy_way.py" + (f" --oversample {k}" if k != "1" else "") + (f" --ode {ode}" if ode else ""), *sp,
            engine_s)
        print(f"    {'ratio noisemon / SciPy':42s} {nm[0] / sp[0]:8.2f} {nm[1] / sp[1]:8.2f}")
        agreement(base, v, int(epoch))
        if ode == "solve_ivp" and f"{k}:tustin" in variants:
            ode_agreement(base, k)


if __name__ == "__main__":
    main()
