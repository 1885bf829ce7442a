#!/usr/bin/env python3
"""A 3-D view of a `linksight run` (or `linksight score`) directory, in the spirit of the
paper's Fig. 6: one self-contained, offline HTML file.

    python3 tools/plot_view.py OUT_DIR

reads OUT_DIR/nodes.csv (estimates beside the truth), frames.csv, summary.json and
view/cloud.csv (each frame's cloud, thinned by linksight), and writes OUT_DIR/view.html:
per frame the cloud, the true nodes and each mode's estimate as a 3-D scene to rotate and
zoom, a frame slider and a play button, the link's occluded fraction and each mode's error
for the frame shown. Camera frame, millimetres; the first view is from beside and behind
the camera, with the camera's up. Open it from disk: no server, no network (plotly.js is inside).
Needs Debian's python3-plotly. `linksight run` and `score` call it unless --no-figures.
"""
import csv
import json
import os
import re
import sys

import plotly.graph_objects as go
from matplotlib.colors import to_hex

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_run import mode_colour as mpl_colour  # noqa: E402  (one colour per mode, everywhere)


def mode_colour(mode):
    return to_hex(mpl_colour(mode))

# Caught before plotly.js loads: an error or console.error in the page marks the body, so a
# headless browser's DOM dump shows it (tests/tools: Cli.RunViewIsA3DSceneInABrowser).
ERROR_HOOK = """<script>
window.linksightErrors = [];
window.addEventListener("error", function (e) { window.linksightErrors.push(String(e.message)); });
window.addEventListener("unhandledrejection", function (e) { window.linksightErrors.push(String(e.reason)); });
(function () { var ce = console.error; console.error = function () {
  window.linksightErrors.push(Array.prototype.join.call(arguments, " ")); ce.apply(console, arguments); }; })();
</script>"""
# After the plot is drawn: the sentinel the test reads, and the errors so far.
POST_SCRIPT = """document.body.setAttribute("data-linksight-view", "rendered");
document.body.setAttribute("data-linksight-errors", String(window.linksightErrors.length));
window.linksightErrors.forEach(function (m) { var p = document.createElement("pre");
  p.className = "linksight-error"; p.textContent = m; document.body.appendChild(p); });"""


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def mm(values):
    return [round(1e3 * float(v), 1) for v in values]


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    run_dir = argv[1]
    try:
        nodes = read_csv(os.path.join(run_dir, "nodes.csv"))
        frames = read_csv(os.path.join(run_dir, "frames.csv"))
        cloud = read_csv(os.path.join(run_dir, "view", "cloud.csv"))
        with open(os.path.join(run_dir, "summary.json")) as f:
            summary = json.load(f)
    except (OSError, ValueError, KeyError) as e:
        print("plot_view.py: %s: %s" % (run_dir, e), file=sys.stderr)
        return 2
    modes = list(summary["modes"].keys())
    frame_ids = sorted({int(r["frame"]) for r in frames})
    if not frame_ids:
        print("plot_view.py: %s: no frames" % run_dir, file=sys.stderr)
        return 2
    by_frame = {f: {"cloud": [[], [], []], "truth": {}, "modes": {m: {} for m in modes},
                    "info": {}} for f in frame_ids}
    for r in cloud:
        c = by_frame.get(int(r["frame"]))
        if c is not None:
            for a, k in enumerate(("x_m", "y_m", "z_m")):
                c["cloud"][a].append(r[k])
    for r in nodes:
        f = by_frame.get(int(r["frame"]))
        if f is None or r["mode"] not in f["modes"]:
            continue
        j = int(r["node"])
        f["modes"][r["mode"]][j] = (r["x_m"], r["y_m"], r["z_m"])
        f["truth"][j] = (r["true_x_m"], r["true_y_m"], r["true_z_m"])
    for r in frames:
        f = by_frame.get(int(r["frame"]))
        if f is not None:
            f["info"][r["mode"]] = r
    # One box for every frame, so the scene does not jump while it plays.
    lo, hi = [float("inf")] * 3, [float("-inf")] * 3

    def grow(xyz):
        for a in range(3):
            for v in xyz[a]:
                lo[a], hi[a] = min(lo[a], v), max(hi[a], v)

    def traces(f):
        d = by_frame[f]
        out = []
        c = [mm(d["cloud"][a]) for a in range(3)]
        grow(c)
        out.append(go.Scatter3d(x=c[0], y=c[1], z=c[2], mode="markers", name="cloud",
                                marker=dict(size=1.5, color="rgb(150,150,150)")))
        t = [mm([d["truth"][j][a] for j in sorted(d["truth"])]) for a in range(3)]
        grow(t)
        out.append(go.Scatter3d(x=t[0], y=t[1], z=t[2], mode="markers+lines", name="truth",
                                line=dict(color="black", width=2),
                                marker=dict(size=5, color="black", symbol="circle-open")))
        for m in modes:
            e = d["modes"][m]
            xyz = [mm([e[j][a] for j in sorted(e)]) for a in range(3)]
            grow(xyz)
            out.append(go.Scatter3d(x=xyz[0], y=xyz[1], z=xyz[2], mode="markers+lines", name=m,
                                    line=dict(color=mode_colour(m), width=4),
                                    marker=dict(size=3, color=mode_colour(m))))
        return out

    def title(f):
        info = by_frame[f]["info"]
        first = next(iter(info.values()))
        parts = ["frame %d (t = %s s), link %.0f%% hidden" %
                 (f, first["t_s"], 100 * float(first["occluded_fraction"]))]
        for m in modes:
            r = info.get(m)
            if r is None:
                continue
            parts.append("%s: %s" % (m, "lost" if r["lost"] == "1" else
                                     "%s mm mean, %s mm max" % (r["mean_err_mm"], r["max_err_mm"])))
        return " | ".join(parts)

    frame_traces = {f: traces(f) for f in frame_ids}
    pad = [0.05 * (hi[a] - lo[a]) + 5 for a in range(3)]
    scene = dict(xaxis=dict(title="x [mm]", range=[lo[0] - pad[0], hi[0] + pad[0]]),
                 yaxis=dict(title="y [mm]", range=[lo[1] - pad[1], hi[1] + pad[1]]),
                 zaxis=dict(title="z [mm]", range=[lo[2] - pad[2], hi[2] + pad[2]]),
                 aspectmode="data",
                 # Camera frame: y down, z forward. The first view is from beside and
                 # behind the camera, up as the camera's up.
                 camera=dict(up=dict(x=0, y=-1, z=0), eye=dict(x=1.4, y=-1.7, z=-2.0)))
    first = frame_ids[0]
    fig = go.Figure(
        data=frame_traces[first],
        frames=[go.Frame(data=frame_traces[f], name=str(f),
                         layout=dict(title=dict(text=title(f)))) for f in frame_ids])
    steps = [dict(method="animate", label=str(f),
                  args=[[str(f)], dict(mode="immediate", frame=dict(duration=0, redraw=True),
                                       transition=dict(duration=0))]) for f in frame_ids]
    fps = float(summary.get("fps", 30))
    fig.update_layout(
        title=dict(text=title(first), font=dict(size=13)),
        scene=scene, height=760, margin=dict(l=0, r=0, t=60, b=0),
        legend=dict(itemsizing="constant"),
        sliders=[dict(active=0, steps=steps, currentvalue=dict(prefix="frame "), pad=dict(t=30),
                      x=0.12, len=0.88)],
        updatemenus=[dict(type="buttons", direction="left", x=0.0, y=0.0, xanchor="left",
                          yanchor="top", pad=dict(t=40), buttons=[
                              dict(label="play", method="animate",
                                   args=[None, dict(frame=dict(duration=1000 / fps, redraw=True),
                                                    fromcurrent=True, transition=dict(duration=0))]),
                              dict(label="pause", method="animate",
                                   args=[[None], dict(mode="immediate", frame=dict(duration=0),
                                                      transition=dict(duration=0))])])])
    html = fig.to_html(include_plotlyjs=True, full_html=True, post_script=POST_SCRIPT,
                       config=dict(responsive=True), auto_play=False)
    # A fixed element id: the same run gives the same file.
    ids = set(re.findall(r'id="([0-9a-f-]{36})"', html))
    for i in ids:
        html = html.replace(i, "linksight-view")
    html = html.replace("<head>", "<head>\n" + ERROR_HOOK, 1)
    out = os.path.join(run_dir, "view.html")
    tmp = out + ".partial"
    with open(tmp, "w") as f:
        f.write(html)
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
