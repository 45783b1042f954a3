#!/usr/bin/env python3
"""Proof of the live gap watch (docs/benchmarks.md "The live gap watch"): every effect of the catalogue switched on
mid-run in the virtual engine at two magnitudes fixed here beforehand (and a slow drift of a microphone), run
unpaced through noisemond into a log, then `noisemon gapwatch --log --json`. Prints per scenario: the effect named,
the detection delay in cycles and seconds, the onset's error in cycles, the fitted parameters against the truth, and
false alarms (an event before the onset).

Usage: gapwatch_effects.py BUILD_DIR [--jobs N] [--only NAME,...] [--keep DIR]
"""
import argparse, os, sys, tempfile
from concurrent.futures import ThreadPoolExecutor

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gapwatch_runs import daemon_config_head, run_daemon, run_gapwatch  # noqa: E402

REFERENCE_S = 120.0
ONSET_S = 150.0
AFTER_S = 90.0
# name, effect text, [sim] overrides, the truth's parameters to compare (key: value)
SCENARIOS = [
    ("mic_gain small", "mic_gain=1.5,mic=4", {}, {"mic": 4, "db": 1.5}),
    ("mic_gain large", "mic_gain=4,mic=7", {}, {"mic": 7, "db": 4.0}),
    ("second_mode small", "second_mode=4,hz=3150", {}, {"hz": 3150, "db": 4.0}),
    ("second_mode large", "second_mode=8,hz=2000", {}, {"hz": 2000, "db": 8.0}),
    ("background_noise small", "background_noise=100", {}, {"db": 100.0}),
    ("background_noise large", "background_noise=105", {}, {"db": 105.0}),
    ("mechanical_noise small", "mechanical_noise=95", {}, {"db": 95.0}),
    ("mechanical_noise large", "mechanical_noise=102", {}, {"db": 102.0}),
    ("transducer_noise small", "transducer_noise=0.1", {}, {"bar": 0.1}),
    ("transducer_noise large", "transducer_noise=0.3", {}, {"bar": 0.3}),
    ("speed_dependence small", "speed_dependence=4", {"speed_rpm": 3450.0, "load_nm": 20.0}, {"gain_db": 1.6}),
    ("speed_dependence large", "speed_dependence=8", {"speed_rpm": 3450.0, "load_nm": 20.0}, {"gain_db": 3.2}),
    ("cubic_damping small", "cubic_damping=1000", {}, {}),
    ("cubic_damping large", "cubic_damping=4000", {}, {}),
    ("cubic_stiffness small", "cubic_stiffness=5e12", {}, {}),
    ("cubic_stiffness large", "cubic_stiffness=2e13", {}, {}),
    ("mic_gain drift", "mic_gain=1,mic=2", {"ramp_s": 600.0}, {"mic": 2, "db": 1.0}),
]


def run(build, name, effect, sim, work):
    ramp = sim.pop("ramp_s", 0.0)
    speed = sim.get("speed_rpm", 3050.0)
    seconds = ONSET_S + ramp + AFTER_S
    cycles = int(seconds * speed / 120.0)
    tag = name.replace(" ", "_")
    log = os.path.join(work, tag + ".lcmlog")
    toml = os.path.join(work, tag + ".toml")
    with open(toml, "w") as f:
        f.write(daemon_config_head(log))
        for k, v in sim.items():
            f.write(f"{k} = {v}\n")
        f.write(f'[[sim.effects]]\neffect = "{effect}"\nonset_s = {ONSET_S}\nramp_s = {ramp}\n')
    run_daemon(build, toml, cycles)
    found = run_gapwatch(build, log, os.path.join(work, tag + ".jsonl"), REFERENCE_S)
    if not (os.environ.get("KEEP")):
        os.remove(log)
    return speed, found


def report(name, effect, truth, speed, events):
    expected = effect.split("=")[0]
    early = [e for e in events if e["onset_s"] < ONSET_S - 5.0 and e["detected_s"] < ONSET_S]
    after = [e for e in events if e["detected_s"] >= ONSET_S - 1.0]
    cycle_s = 120.0 / speed
    if not after:
        return f"{name:24s} {'not detected':>18s} {'':>14s} {'':>9s}  false alarms {len(early)}", False
    e = after[0]
    delay_s = e["detected_s"] - ONSET_S
    onset_error = (e["onset_s"] - ONSET_S) / cycle_s
    params = " ".join(f"{k}={v:.4g}" for k, v in e["params"].items() if v is not None)
    versus = " ".join(f"{k}={v:g}" for k, v in truth.items())
    ok = e["effect"] == expected
    line = (f"{name:24s} {e['effect']:>18s} {delay_s / cycle_s:7.0f} cyc {delay_s:5.1f} s {onset_error:+7.0f} cyc  "
            f"conf {e['confidence']:.2f}  {params}  (truth {versus})  false alarms {len(early)}")
    return line, ok


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("build")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default="")
    args = ap.parse_args()
    chosen = [s for s in SCENARIOS if not args.only or any(o in s[0] for o in args.only.split(","))]
    work = tempfile.mkdtemp(prefix="gapwatch-effects-")
    print(f"reference {REFERENCE_S:g} s, onset {ONSET_S:g} s, {AFTER_S:g} s after (a ramp: after its end); unpaced, 0.5 deg encoder")
    print(f"{'scenario':24s} {'named':>18s} {'delay':>14s} {'onset err':>9s}")
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run, args.build, n, e, dict(s), work) for n, e, s, t in chosen]
        right = 0
        for (n, e, s, t), fut in zip(chosen, futures):
            speed, events = fut.result()
            line, ok = report(n, e, t, speed, events)
            right += ok
            print(line, flush=True)
    print(f"right effect named: {right} of {len(chosen)}")


if __name__ == "__main__":
    sys.exit(main())
