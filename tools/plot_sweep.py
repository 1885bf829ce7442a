#!/usr/bin/python3
"""Heatmaps of a merged sweep: DIR/cells.csv and DIR/sweep.json -> DIR/figures/heatmap_<metric>.png.

One PNG per metric, one panel per tracker mode. The first two axes of the grid (other than
`tracker.mode`) are the heatmap's x and y; any further axes (seeds, say) are averaged over.
A grid of one axis gives a one-row heatmap. Debian's python3-matplotlib; no network.
"""
import csv
import json
import math
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

METRICS = {
    "node_err_mean_mm": "mean node error [mm]",
    "node_err_p95_mm": "p95 node error [mm]",
    "node_err_max_mm": "max node error [mm]",
    "sdf_err_mean_mm": "mean SDF error [mm]",
    "pct_frames_under_5mm": "frames under 5 mm [%]",
    "swaps": "topology swaps",
    "reinit_count": "re-initializations",
    "occluded_fraction_mean": "mean occluded fraction",
}


def number(text):
    try:
        return float(text)
    except ValueError:
        return math.nan


def main(directory):
    with open(os.path.join(directory, "sweep.json")) as f:
        manifest = json.load(f)
    with open(os.path.join(directory, "cells.csv")) as f:
        rows = list(csv.DictReader(f))
    axes = [a for a in manifest["axes"] if a["key"] != "tracker.mode"]
    # The mode column is the mode that ran, whether from --compare or a tracker.mode axis.
    modes = list(dict.fromkeys(r["mode"] for r in rows))
    x_axis = axes[0] if axes else None
    y_axis = axes[1] if len(axes) > 1 else None
    xs = x_axis["values"] if x_axis else ["all"]
    ys = y_axis["values"] if y_axis else [""]
    out_dir = os.path.join(directory, "figures")
    os.makedirs(out_dir, exist_ok=True)
    for metric, label in METRICS.items():
        fig, panels = plt.subplots(1, len(modes), figsize=(4.2 * len(modes) + 1, 3.6),
                                   squeeze=False, constrained_layout=True)
        grids = []
        for mode in modes:
            sums = [[0.0] * len(xs) for _ in ys]
            counts = [[0] * len(xs) for _ in ys]
            for r in rows:
                if r["mode"] != mode:
                    continue
                xi = xs.index(r[x_axis["key"]]) if x_axis else 0
                yi = ys.index(r[y_axis["key"]]) if y_axis else 0
                v = number(r[metric])
                if math.isnan(v):
                    continue
                sums[yi][xi] += v
                counts[yi][xi] += 1
            grids.append([[s / c if c else math.nan for s, c in zip(sr, cr)]
                          for sr, cr in zip(sums, counts)])
        finite = [v for g in grids for row in g for v in row if not math.isnan(v)]
        lo, hi = (min(finite), max(finite)) if finite else (0.0, 1.0)
        if hi <= lo:
            hi = lo + 1.0
        for k, mode in enumerate(modes):
            ax = panels[0][k]
            im = ax.imshow(grids[k], origin="lower", aspect="auto", cmap="viridis",
                           vmin=lo, vmax=hi)
            for yi, row in enumerate(grids[k]):
                for xi, v in enumerate(row):
                    if not math.isnan(v):
                        ax.text(xi, yi, f"{v:.3g}", ha="center", va="center", fontsize=7,
                                color="white" if v < (lo + hi) / 2 else "black")
            ax.set_xticks(range(len(xs)))
            ax.set_xticklabels(xs, rotation=30 if max(len(x) for x in xs) > 5 else 0)
            ax.set_yticks(range(len(ys)))
            ax.set_yticklabels(ys)
            ax.set_xlabel(x_axis["key"] if x_axis else "")
            ax.set_ylabel(y_axis["key"] if y_axis else "")
            ax.set_title(mode)
        fig.colorbar(im, ax=panels[0].tolist(), label=label)
        fig.suptitle(label + (f" (mean over {', '.join(a['key'] for a in axes[2:])})"
                              if len(axes) > 2 else ""))
        target = os.path.join(out_dir, f"heatmap_{metric}.png")
        fd, tmp = tempfile.mkstemp(suffix=".png", dir=out_dir)
        os.close(fd)
        fig.savefig(tmp, dpi=110)
        plt.close(fig)
        os.replace(tmp, target)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: plot_sweep.py SWEEP_DIR")
    main(sys.argv[1])
