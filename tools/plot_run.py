#!/usr/bin/env python3
"""Figures of a `linksight run` directory, in the style of the paper's Figs. 4-6.

    python3 tools/plot_run.py OUT_DIR

reads OUT_DIR/frames.csv, OUT_DIR/summary.json and OUT_DIR/overlays/, and writes
OUT_DIR/figures/:
  node_error.png      mean node error against time, one line per tracker mode (Fig. 4),
                      with the occlusion and fast-motion events shaded;
  tracker_time.png    tracker time per frame, one line per mode (Fig. 5);
  overlay_NNNNNN.png  the depth image in false colour with the true and estimated nodes
                      projected onto it (Fig. 6), one per overlay frame.
`linksight run` calls it; run it by hand to regenerate the figures.
Needs Debian's python3-matplotlib (numpy and PIL come with it).
"""
import csv
import hashlib
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display: files only
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

# Mode names come from the data; each gets a colour from its name alone, so a mode keeps
# its colour in every figure whatever else is compared (the first byte of the name's SHA-1
# picks one of matplotlib's ten; today's modes get different ones).
PALETTE = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
           "tab:pink", "tab:gray", "tab:olive", "tab:cyan"]


def mode_colour(mode):
    return PALETTE[hashlib.sha1(mode.encode()).digest()[0] % len(PALETTE)]


EVENT_COLOURS = {"occlusion": "0.85", "fast_motion": "mistyrose"}


def read_frames(path):
    rows = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            rows.setdefault(r["mode"], []).append(r)
    return rows


def number(text):
    try:
        return float(text)
    except ValueError:
        return float("nan")


def shade_events(ax, summary, fps):
    shown = set()
    for mode in summary["modes"].values():
        for e in mode["event_list"]:
            key = (e["kind"], e["start_frame"], e["end_frame"])
            if key in shown:
                continue
            label = e["kind"].replace("_", " ") if e["kind"] not in {k[0] for k in shown} else None
            shown.add(key)
            ax.axvspan(e["start_frame"] / fps, e["end_frame"] / fps,
                       color=EVENT_COLOURS.get(e["kind"], "0.9"), zorder=0, label=label)


def save(fig, path):
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, path)  # no half-written figure


def plot_lines(frames, summary, column, ylabel, title, path, log=False):
    fig, ax = plt.subplots(figsize=(7.0, 3.6), layout="constrained")
    shade_events(ax, summary, summary["fps"])
    for mode, rows in frames.items():
        t = np.array([number(r["t_s"]) for r in rows])
        y = np.array([number(r[column]) for r in rows])
        ax.plot(t, y, label=mode, color=mode_colour(mode), linewidth=1.2)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if log:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    save(fig, path)


def plot_overlays(run_dir, out_dir, summary):
    overlay_dir = os.path.join(run_dir, "overlays")
    px_path = os.path.join(overlay_dir, "nodes_px.csv")
    if not os.path.exists(px_path):
        return
    nodes = {}
    with open(px_path, newline="") as f:
        for r in csv.DictReader(f):
            nodes.setdefault(int(r["frame"]), {}).setdefault(r["who"], []).append(
                (float(r["u_px"]), float(r["v_px"])))
    for frame, who in sorted(nodes.items()):
        png = os.path.join(overlay_dir, "depth_%06d.png" % frame)
        if not os.path.exists(png):
            continue
        depth_mm = np.array(Image.open(png), dtype=np.float64) * 0.125  # SR300 unit: 1/8 mm
        depth_mm[depth_mm == 0] = np.nan
        fig, ax = plt.subplots(figsize=(6.4, 5.0), layout="constrained")
        im = ax.imshow(depth_mm, cmap="turbo")
        fig.colorbar(im, ax=ax, label="depth [mm]", shrink=0.8)
        for name, pts in who.items():
            pts = np.array(pts)
            if name == "truth":
                ax.plot(pts[:, 0], pts[:, 1], "o", mfc="none", mec="white", ms=8, mew=1.5,
                        label="true nodes")
            else:
                ax.plot(pts[:, 0], pts[:, 1], "x-", color=mode_colour(name), ms=6,
                        lw=1.0, label=name + " estimate")
        ax.set_xlabel("u [px]")
        ax.set_ylabel("v [px]")
        ax.set_title("frame %d (t = %.2f s)" % (frame, frame / summary["fps"]))
        ax.legend(loc="lower right", fontsize="small")
        save(fig, os.path.join(out_dir, "overlay_%06d.png" % frame))


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    run_dir = argv[1]
    try:
        frames = read_frames(os.path.join(run_dir, "frames.csv"))
        with open(os.path.join(run_dir, "summary.json")) as f:
            summary = json.load(f)
    except (OSError, ValueError, KeyError) as e:
        print("plot_run.py: %s: %s" % (run_dir, e), file=sys.stderr)
        return 2
    out_dir = os.path.join(run_dir, "figures")
    os.makedirs(out_dir, exist_ok=True)
    plot_lines(frames, summary, "mean_err_mm", "mean node error [mm]",
               "Node error against the true sphere centres", os.path.join(out_dir, "node_error.png"),
               log=True)
    plot_lines(frames, summary, "time_ms", "tracker time [ms/frame]", "Tracker time per frame",
               os.path.join(out_dir, "tracker_time.png"))
    plot_overlays(run_dir, out_dir, summary)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
