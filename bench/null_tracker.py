#!/usr/bin/env python3
"""A tracker that does nothing but answer (docs/protocol.md): reads each frame whole and
answers the same nodes. What bench_protocol times is then the protocol's own cost: the
pipe, the copy, a JSON header and answer, and a Python loop around them."""
import json
import sys

stdin = sys.stdin.buffer
nodes = None
for line in stdin:
    h = json.loads(line)
    stdin.read(12 * h["points"])
    if "depth" in h:
        stdin.read(2 * h["depth"]["width"] * h["depth"]["height"])
    if nodes is None:
        nodes = [[0.045 * j, 0.0, 0.6] for j in range(h["nodes"])]
    sys.stdout.write(json.dumps({"frame": h["frame"], "nodes": nodes}) + "\n")
    sys.stdout.flush()
