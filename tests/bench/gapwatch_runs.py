"""The steps both gap-watch proofs take (gapwatch_effects.py, gapwatch_false_alarms.py): a noisemond configuration
for an unpaced virtual engine logging its reports, the daemon run for a number of cycles, and `noisemon gapwatch`
over the log with its events read back."""
import json
import os
import subprocess
import sys

ENCODER_STEP_DEG = 0.5


def daemon_config_head(log):
    """[lcm] logging to `log` (reports only) and the start of an unpaced [sim] with the realistic 0.5 deg encoder."""
    return (f'[lcm]\nurl = "file://{log}?mode=w"\npublish_raw = false\n'
            f"[sim]\npaced = false\nencoder_resolution_deg = {ENCODER_STEP_DEG}\n")


def run_daemon(build, toml, cycles):
    subprocess.run([f"{build}/daemon/noisemond", "--config", toml, "--cycles", str(cycles), "--log-level", "error"],
                   check=True, stdout=subprocess.DEVNULL)


def run_gapwatch(build, log, events, reference_s):
    """The events `noisemon gapwatch --log` finds (its JSON lines, as dicts)."""
    if os.path.exists(events):
        os.remove(events)
    command = [f"{build}/daemon/noisemon", "gapwatch", "--log", log, "--json", events, "--no-progress",
               "--reference-s", str(reference_s), "--encoder-step-deg", str(ENCODER_STEP_DEG)]
    # Its messages only when it fails: the effects bench runs several at once.
    done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        sys.stderr.write(done.stderr)
        raise subprocess.CalledProcessError(done.returncode, command)
    if not os.path.exists(events):
        return []
    with open(events) as f:
        return [json.loads(line) for line in f if line.strip()]
