#!/usr/bin/env python3
"""False alarms of the live gap watch (docs/benchmarks.md "The live gap watch"): the clean virtual engine, unpaced,
through noisemond into a log for 8.25 hours of engine time, its operating point changed every 41 minutes over six
points (speed 2800 to 3450 rpm, load 0 to 20 N m, SOI 14 to 22 deg BTDC; each change a 5 s ramp, every point visited
twice), then `noisemon gapwatch --log --json` with its defaults (a false alarm every 8 h of engine running, 1 dB).
Every event is a false alarm. Prints the engine hours watched, the events, the measured rate and its 95 % upper
bound, and the daemon's speed against real time.

Usage: gapwatch_false_alarms.py BUILD_DIR [--hours H] [--keep DIR]
"""
import argparse, math, os, shutil, sys, tempfile, threading, time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gapwatch_runs import daemon_config_head, run_daemon, run_gapwatch  # noqa: E402

# (speed rpm, load N m, SOI deg BTDC): fixed here before the first run.
POINTS = {"A": (3050.0, 0.0, 18.0), "B": (3450.0, 20.0, 18.0), "C": (3250.0, 10.0, 18.0),
          "D": (3450.0, 20.0, 14.0), "E": (3050.0, 0.0, 22.0), "F": (2800.0, 5.0, 16.0)}
SEQUENCE = "ABCDEFACBEDF"
RAMP_S = 5.0
REFERENCE_S = 120.0


def schedule(hours):
    segment_s = hours * 3600.0 / len(SEQUENCE)
    steps = [(i * segment_s, POINTS[p]) for i, p in enumerate(SEQUENCE)]
    cycles = sum(segment_s * rpm / 120.0 for _, (rpm, _, _) in steps)
    return segment_s, steps, int(cycles)


def write_config(path, log, steps):
    first = steps[0][1]
    with open(path, "w") as f:
        f.write(daemon_config_head(log))
        f.write("seed = 20261129\n")
        f.write(f"speed_rpm = {first[0]}\nload_nm = {first[1]}\nsoi_deg_btdc = {first[2]}\n")
        for at, (rpm, load, soi) in steps[1:]:
            f.write(f"[[sim.schedule]]\nat_s = {at:.1f}\nramp_s = {RAMP_S}\n"
                    f"speed_rpm = {rpm}\nload_nm = {load}\nsoi_deg_btdc = {soi}\n")


def poisson_upper(n, alpha=0.05):
    """The mean whose chance of n or fewer events is alpha (the one-sided upper bound; 3.00 for n = 0)."""
    cdf = lambda mu: sum(math.exp(-mu) * mu ** k / math.factorial(k) for k in range(n + 1))
    lo, hi = 0.0, 10.0 * (n + 3)
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cdf(mid) > alpha else (lo, mid)
    return hi


def watch_progress(log, stop):
    start = time.time()
    while not stop.wait(300):
        size = os.path.getsize(log) if os.path.exists(log) else 0
        print(f"  {time.time() - start:6.0f} s: log {size / 1e6:.0f} MB", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("build")
    ap.add_argument("--hours", type=float, default=8.25)
    ap.add_argument("--keep", default="")
    args = ap.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="gapwatch-false-alarms-")
    os.makedirs(work, exist_ok=True)
    segment_s, steps, cycles = schedule(args.hours)
    log, toml, events = (os.path.join(work, n) for n in ("clean.lcmlog", "clean.toml", "events.jsonl"))
    write_config(toml, log, steps)
    print(f"{args.hours:g} h of engine time, {cycles} cycles; {len(SEQUENCE)} segments of {segment_s:.0f} s over "
          f"{len(POINTS)} operating points ({SEQUENCE}), {RAMP_S:g} s ramps; unpaced, 0.5 deg encoder", flush=True)
    stop = threading.Event()
    threading.Thread(target=watch_progress, args=(log, stop), daemon=True).start()
    t0 = time.time()
    run_daemon(args.build, toml, cycles)
    daemon_s = time.time() - t0
    stop.set()
    print(f"noisemond: {daemon_s:.0f} s wall for {args.hours * 3600:.0f} s of engine time "
          f"({args.hours * 3600 / daemon_s:.1f} x real time); log {os.path.getsize(log) / 1e6:.0f} MB", flush=True)
    t0 = time.time()
    found = run_gapwatch(args.build, log, events, REFERENCE_S)
    watch_s = time.time() - t0
    watched_h = args.hours - len(POINTS) * REFERENCE_S / 3600.0
    print(f"noisemon gapwatch: {watch_s:.0f} s wall")
    print(f"engine hours watched (after each point's {REFERENCE_S:g} s reference): {watched_h:.2f}")
    print(f"events (all false alarms): {len(found)}")
    for e in found:
        print(f"  {e['effect']} detected at {e['detected_s']:.0f} s, onset {e['onset_s']:.0f} s, "
              f"gap {e['gap_before_db']:.2f} -> {e['gap_after_db']:.2f} dB, confidence {e['confidence']:.2f}")
    upper = poisson_upper(len(found))
    print(f"false-alarm rate: {len(found) / watched_h:.3f} per engine hour (95 % upper bound {upper / watched_h:.3f}); "
          f"the design target: 1 per 8 h = 0.125")
    if not args.keep:
        shutil.rmtree(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
