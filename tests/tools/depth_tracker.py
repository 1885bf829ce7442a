#!/usr/bin/env python3
"""A client for the depth image of the external-tracker protocol (scene key
external.send_depth), for the CLI tests: it reads each frame's depth image and answers
"lost" with the image's size, valid pixel count and sum of units, which the test compares
with the rendered depth PNG of the same frame."""
import json
import sys

import numpy as np

stdin = sys.stdin.buffer
for line in stdin:
    h = json.loads(line)
    stdin.read(12 * h["points"])
    if "depth" not in h:
        print(json.dumps({"frame": h["frame"], "lost": True, "reason": "no depth"}), flush=True)
        continue
    w, hh = h["depth"]["width"], h["depth"]["height"]
    d = np.frombuffer(stdin.read(2 * w * hh), dtype="<u2")
    reason = "%dx%d valid=%d sum=%d" % (w, hh, int((d > 0).sum()), int(d.astype(np.int64).sum()))
    print(json.dumps({"frame": h["frame"], "lost": True, "reason": reason}), flush=True)
