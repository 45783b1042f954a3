#!/usr/bin/env python3
"""The LCM tools on a log the project writes: `noisemon sim` -> `import` -> `replay --out reports.lcmlog --csv`,
then scripts/read_lcm_log.py (no lcm Python module) and scripts/ReadCycles.java must give the CSV's numbers, and
scripts/lcm-spy.sh must start lcm-spy on this Java with the message types found.

  test_lcm_tools.py --noisemon BIN --jar NOISEMON_MSGS_JAR --python-path GEN_PYTHON --source SOURCE_DIR

Exit 0 when all pass, 1 on a failure, 77 (skipped) when Java is missing outside CI.
"""
import argparse
import csv
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile


def run(args, **kw):
    return subprocess.run(args, check=True, capture_output=True, text=True, timeout=120, **kw)


def make_reports(noisemon, work):
    """A short simulated run through the daemon's own pipeline: reports.lcmlog and its CSV."""
    run([noisemon, "sim", "--condition", "idle_mi18", "--cycles", "12", "-o", f"{work}/sim", "--no-progress"])
    run([noisemon, "import", f"{work}/sim/idle_mi18", "-o", f"{work}/raw.lcmlog", "--no-progress"])
    run([noisemon, "replay", f"{work}/raw.lcmlog", "--out", f"{work}/reports.lcmlog", "--csv", f"{work}/cycles.csv", "--no-progress"])
    with open(f"{work}/cycles.csv") as f:
        return list(csv.DictReader(f))


def check(condition, message, failures):
    if not condition:
        failures.append(message)


def check_python_reader(a, work, rows, failures):
    out = run([sys.executable, f"{a.source}/scripts/read_lcm_log.py", f"{work}/reports.lcmlog", "--json",
               "--python-path", a.python_path]).stdout.splitlines()
    reports = [json.loads(line) for line in out]
    check(len(reports) == len(rows) and len(rows) >= 5, f"python: {len(reports)} reports, CSV {len(rows)} rows", failures)
    for r, row in zip(reports, rows):
        check(r["cycle"] == int(row["cycle"]) and r["utime"] == int(row["utime"]), f"python: cycle {r['cycle']} != {row['cycle']}", failures)
        for key in ("lpa_measured_db", "lpa_predicted_db", "lwa_measured_db", "lwa_predicted_db"):
            check(abs(r[key] - float(row[key])) <= 5.1e-5, f"python: cycle {r['cycle']} {key} {r[key]} != {row[key]}", failures)
        check(r["flags"] == int(row["flags"]) and r["nmics"] == 10 and r["nbands"] > 20, f"python: cycle {r['cycle']} flags/sizes", failures)
    # A log cut mid-event (a recorder killed while writing): the complete events are read, no error.
    with open(f"{work}/reports.lcmlog", "rb") as f:
        data = f.read()
    with open(f"{work}/cut.lcmlog", "wb") as f:
        f.write(data[: len(data) - 100])
    cut = run([sys.executable, f"{a.source}/scripts/read_lcm_log.py", f"{work}/cut.lcmlog", "--json", "--python-path", a.python_path])
    check(len(cut.stdout.splitlines()) == len(rows) - 1, "python: the cut log's complete events", failures)


def check_java(a, work, rows, failures):
    classpath = f"/usr/share/java/lcm.jar:{a.jar}"
    out = run(["java", "-cp", classpath, f"{a.source}/scripts/ReadCycles.java", "--log", f"{work}/reports.lcmlog"]).stdout.split("\n")
    lines = [line.split() for line in out if line]
    check(len(lines) == len(rows), f"java: {len(lines)} reports, CSV {len(rows)} rows", failures)
    for fields, row in zip(lines, rows):
        check(fields[0] == row["cycle"] and fields[1] == row["utime"] and fields[2] == row["lpa_measured_db"]
              and fields[3] == row["lpa_predicted_db"], f"java: {fields} != {row['cycle']} {row['lpa_measured_db']}", failures)
    spy = [f"{a.source}/scripts/lcm-spy.sh", "--jar", a.jar]
    types = run(spy + ["--list-types"]).stdout
    message_types = sorted(os.path.basename(p)[:-4] for p in glob.glob(f"{a.source}/msgs/*.lcm"))
    for t in message_types:
        check(f"noisemon.{t}" in types, f"lcm-spy.sh --list-types: noisemon.{t} missing", failures)
    # No display here: lcm-spy must get as far as opening its window (the JVM accepted the options, every class
    # loaded, the types were found) and stop there.
    env = dict(os.environ, JAVA_OPTS="-Djava.awt.headless=true")
    started = subprocess.run(spy, capture_output=True, text=True, timeout=60, env=env)
    log = started.stdout + started.stderr
    check(f"Found {len(message_types)} LCM types" in log and "HeadlessException" in log,
          f"lcm-spy did not start: {log[:400]}", failures)
    check("Unrecognized option" not in log and "NoClassDefFoundError" not in log, f"lcm-spy: {log[:400]}", failures)


def main():
    p = argparse.ArgumentParser()
    for name in ("--noisemon", "--jar", "--python-path", "--source"):
        p.add_argument(name, required=True)
    a = p.parse_args()
    failures = []
    with tempfile.TemporaryDirectory() as work:
        rows = make_reports(a.noisemon, work)
        check_python_reader(a, work, rows, failures)
        if shutil.which("java") and os.path.exists(a.jar):
            check_java(a, work, rows, failures)
        elif os.environ.get("CI", "") not in ("", "0", "false"):  # the suite's one rule for CI
            failures.append("java or the message jar missing (default-jdk-headless, liblcm-java)")
        else:
            print("SKIPPED the Java checks: java or the message jar missing")
            return 77 if not failures else 1
    for f in failures:
        print("FAIL:", f)
    print("lcm tools:", "ok" if not failures else f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
