#!/usr/bin/python3
"""Figures for `linksight fidelity` (real against simulated, overlaid) and for
`linksight calibrate-noise --report` (the recording against the fitted model).

Reads DIR/fidelity.json or DIR/calibration.json ({"series": {label: statistics}}), writes
DIR/figures/{sigma_depth,sigma_angle,shadow_band,holes}.png; a series without a statistic
is left out of that figure.
Usage: plot_fidelity.py DIR
"""
import json
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def save(fig, path):
    """Write to a temporary file beside `path`, then rename: no half-written PNG."""
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".png.partial")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=120, format="png")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    plt.close(fig)


def main(out_dir):
    name = "fidelity.json" if os.path.exists(os.path.join(out_dir, "fidelity.json")) else "calibration.json"
    with open(os.path.join(out_dir, name)) as f:
        j = json.load(f)
    series = list(j["series"].items())
    figures = os.path.join(out_dir, "figures")
    os.makedirs(figures, exist_ok=True)
    looks = [dict(color="black", marker="o"), dict(color="tab:orange", marker="s")]
    style = {label: looks[i % len(looks)] for i, (label, _) in enumerate(series)}

    def sigma(key, xlabel, name, title):
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for label, s in series:
            pts = s.get(key, [])
            ax.plot([p["centre"] for p in pts], [p["sigma_mm"] for p in pts], label=label, **style[label])
        ax.set_xlabel(xlabel)
        ax.set_ylabel("plane-fit sigma [mm]")
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        save(fig, os.path.join(figures, name))

    sigma("sigma_by_depth", "depth [m] (bin median)", "sigma_depth.png",
          "Axial noise against depth (incidence < 30 deg)")
    sigma("sigma_by_angle", "incidence [deg] (bin median)", "sigma_angle.png",
          "Axial noise against incidence")

    fig, ax = plt.subplots(figsize=(5.5, 4))
    for label, s in series:
        if "shadow_gap_px" not in s:
            continue
        ax.scatter(s["shadow_gap_px"], s["shadow_width_px"], s=3, alpha=0.3, label=label,
                   color=style[label]["color"])
    ax.set_xlabel("f (1/z_near - 1/z_far) [px]")
    ax.set_ylabel("band width on the shadow side [px]")
    ax.set_title("Projector shadow: band width against depth gap")
    ax.grid(alpha=0.3)
    ax.legend(markerscale=4)
    fig.tight_layout()
    save(fig, os.path.join(figures, "shadow_band.png"))

    fig, ax = plt.subplots(figsize=(5.5, 4))
    bins = [1, 2, 3, 5, 8, 13, 21, 34, 55, 89, 144, 1001]
    for label, s in series:
        if s.get("hole_sizes_px"):
            ax.hist(s["hole_sizes_px"], bins=bins, histtype="step", linewidth=2, label=label,
                    color=style[label]["color"], density=True)
    ax.set_xscale("log")
    ax.set_xlabel("hole size [px]")
    ax.set_ylabel("density")
    ax.set_title("Interior holes")
    ax.legend()
    fig.tight_layout()
    save(fig, os.path.join(figures, "holes.png"))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
