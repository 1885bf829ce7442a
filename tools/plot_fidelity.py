#!/usr/bin/python3
"""Figures for `linksight fidelity` (real against simulated, overlaid) and for
`linksight calibrate-noise --report` (the recording against the fitted model).

Reads DIR/fidelity.json or DIR/calibration.json ({"series": {label: statistics}}), writes
DIR/figures/{sigma_depth,sigma_angle,shadow_band,holes,structure}.png; a series without a
statistic is left out of that figure (structure.png is not drawn when no series has its
statistics).
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
    looks = [dict(color="black", marker="o"), dict(color="tab:orange", marker="s"),
             dict(color="tab:blue", marker="^"), dict(color="tab:green", marker="v")]
    style = {label: looks[i % len(looks)] for i, (label, _) in enumerate(series)}

    def sigma(key, xlabel, name, title, ylabel="plane-fit sigma [mm]"):
        fig, ax = plt.subplots(figsize=(5.5, 4))
        for label, s in series:
            pts = s.get(key, [])
            ax.plot([p["centre"] for p in pts], [p["sigma_mm"] for p in pts], label=label, **style[label])
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        save(fig, os.path.join(figures, name))

    sigma("sigma_by_depth", "depth [m] (bin median)", "sigma_depth.png",
          "Axial noise against depth (incidence < 30 deg)")
    sigma("sigma_by_angle", "incidence [deg] (bin median)", "sigma_angle.png",
          "Axial noise against incidence")
    # The pixel-scale noise against depth (issue 20): what a quadratic leaves.
    if any("sigma_quad_by_depth" in s for _, s in series):
        sigma("sigma_quad_by_depth", "depth [m] (bin median)", "sigma_quad_depth.png",
              "What a quadratic leaves, by depth (< 30 deg)",
              "quadratic-fit sigma [mm]")

    # The structure (issue 20): what a quadratic leaves by incidence, and how far the
    # residual stays correlated along rows (solid) and columns (dashed).
    if any("sigma_quad_by_angle" in s or "correlation_rows" in s for _, s in series):
        fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
        for label, s in series:
            pts = s.get("sigma_quad_by_angle", [])
            if pts:
                left.plot([p["centre"] for p in pts], [p["sigma_mm"] for p in pts], label=label,
                          **style[label])
            for key, line in (("correlation_rows", "-"), ("correlation_cols", "--")):
                values = s.get(key)
                if not values:
                    continue
                lag = [i + 1 for i, v in enumerate(values) if v is not None]
                right.plot(lag, [v for v in values if v is not None], linestyle=line,
                           label=f"{label}, {key.split('_')[1]}", **style[label])
        left.set_xlabel("incidence [deg] (bin median)")
        left.set_ylabel("quadratic-fit sigma [mm]")
        left.set_title("What a quadratic leaves, 15 px windows")
        right.set_xlabel("lag [px]")
        right.set_ylabel("residual correlation")
        right.set_title("Correlation along rows (solid) and columns (dashed)")
        right.axhline(0, color="grey", linewidth=0.5)
        for ax in (left, right):
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        fig.tight_layout()
        save(fig, os.path.join(figures, "structure.png"))

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
