#!/usr/bin/python3
"""The independent reference for noisemon's DBC reader: Debian's canmatrix decodes random payloads of every message
of a DBC file. Prints one JSON object per frame: {"message", "id", "extended", "data" (hex), "values": {signal:
physical value}} with only the signals canmatrix says the frame carries (multiplexing applied).
Usage: dbc_reference.py FILE.dbc SEED FRAMES_PER_MESSAGE"""
import json
import random
import sys

import canmatrix.formats


def main():
    path, seed, count = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    rng = random.Random(seed)
    db = canmatrix.formats.loadp_flat(path)
    for frame in db.frames:
        for _ in range(count):
            data = bytes(rng.randrange(256) for _ in range(frame.size))  # the length the message declares
            decoded = frame.decode(data)
            values = {name: float(d.phys_value) for name, d in decoded.items()}
            print(json.dumps({"message": frame.name, "id": frame.arbitration_id.id,
                              "extended": bool(frame.arbitration_id.extended), "data": data.hex(),
                              "values": values}))


if __name__ == "__main__":
    main()
