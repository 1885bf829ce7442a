#!/usr/bin/env python3
"""A tracker that breaks the external-tracker protocol in one way, for the CLI tests.

    broken_tracker.py HOW [FRAME [TAG]]

Answers every frame with 12 nodes along x (a straight link), except at FRAME (default 3):
  crash     prints to stderr and exits with status 3
  exit      exits with status 0 without answering
  hang      stops answering (sleeps)
  deaf      stops reading its input (sleeps after answering FRAME - 1; a frame of more
            than 64 KiB, 5.5k points, then fills the pipe)
  garbage   answers 'hello, linksight' (not JSON), then goes on
  count     answers 11 nodes, then goes on
  far       answers a coordinate 1e300, then goes on
  nan       answers a coordinate NaN (json.dumps writes a bare NaN, not JSON), then goes on
  other     answers for another frame, then goes on
  lost      answers "lost" with a reason, then goes on
  stray     prints a stray line before its answer, then goes on
  orphan    starts `sleep 3600.TAG` (holding its stdout open) and exits with status 3
TAG (digits) marks its processes, for a test to look for what is left.
"""
import subprocess
import json
import sys
import time

how = sys.argv[1]
at = int(sys.argv[2]) if len(sys.argv) > 2 else 3
tag = sys.argv[3] if len(sys.argv) > 3 else "0"
stdin = sys.stdin.buffer
while True:
    line = stdin.readline()
    if not line:
        sys.exit(0)
    h = json.loads(line)
    f = h["frame"]
    stdin.read(12 * h["points"])
    if "depth" in h:
        stdin.read(2 * h["depth"]["width"] * h["depth"]["height"])
    nodes = [[0.045 * j, 0.0, 0.6] for j in range(h["nodes"])]
    answer = {"frame": f, "nodes": nodes}
    if f == at:
        if how == "crash":
            print("broken_tracker: giving up at frame %d" % f, file=sys.stderr)
            sys.exit(3)
        if how == "exit":
            sys.exit(0)
        if how == "orphan":
            subprocess.Popen(["sleep", "3600." + tag])
            sys.exit(3)
        if how == "stray":
            sys.stdout.write("debug: frame %d\n" % f)
        if how == "hang":
            time.sleep(3600)
        if how == "garbage":
            sys.stdout.write("hello, linksight\n")
            sys.stdout.flush()
            continue
        if how == "count":
            answer["nodes"] = nodes[:11]
        if how == "far":
            answer["nodes"][5][1] = 1e300
        if how == "nan":
            answer["nodes"][5][1] = float("nan")  # json.dumps writes a bare NaN: not JSON
        if how == "other":
            answer["frame"] = f + 7
        if how == "lost":
            answer = {"frame": f, "lost": True, "reason": "the link left my view"}
    sys.stdout.write(json.dumps(answer) + "\n")
    sys.stdout.flush()
    if f == at - 1 and how == "deaf":
        time.sleep(3600)  # before reading the next frame's header: its bytes fill the pipe
