#!/usr/bin/env python3
"""The paper's SOM tracker as a tracker outside linksight: a reference client of the
external-tracker protocol (docs/protocol.md, version 1).

    linksight run scenes/static.yaml --tracker som='python3 tools/trackers/som.py' \\
        --compare paper,som

Per frame: LSQ `pca` initialization on the first frame (a cubic in the cloud's principal
axes, nodes at the component pitch), then 4 association/mean iterations (Eqs. 11-12); a
node whose neighbourhood is empty re-initializes by LSQ, oriented by the last nodes
(Sec. IV.C). The same algorithm as linksight's `paper` mode, in numpy (float64 where the
built-in mode sums in fixed point), so their scores agree to a small fraction of a mm.
Needs Debian's python3-numpy.
"""
import json
import sys

import numpy as np

ITERATIONS = 4
POLY_ORDER = 3
MAX_POINTS = 4000  # the LSQ init thins the cloud to at most this many points


def thin(p):
    stride = 1 if len(p) <= MAX_POINTS else -(-len(p) // MAX_POINTS)
    return p[::stride]


def fit_polynomial(u, v, order):
    """v(u) by least squares in a centred, scaled abscissa (Eq. 10)."""
    u0 = u.mean()
    spread = np.abs(u - u0).max()
    scale = spread if spread > 0 else 1.0
    m = min(order, len(u) - 1) if spread > 0 else 0
    t = (u - u0) / scale
    coeffs = np.linalg.lstsq(np.vander(t, m + 1, increasing=True), v, rcond=None)[0]
    return lambda x: np.polynomial.polynomial.polyval((x - u0) / scale, coeffs)


def orient(nodes, previous):
    """Node 0 at the end nearer the previous node 0; first frame: the end with the smaller
    coordinate along the camera axis the link extends most in."""
    a, b = nodes[0], nodes[-1]
    if previous is not None:
        pa, pb = previous[0], previous[-1]
        flip = np.linalg.norm(a - pb) + np.linalg.norm(b - pa) < \
            np.linalg.norm(a - pa) + np.linalg.norm(b - pb)
    else:
        axis = int(np.argmax(np.abs(b - a)))
        flip = b[axis] < a[axis]
    return nodes[::-1].copy() if flip else nodes


def lsq_init(points, n_nodes, pitch, previous):
    """LSQ init, `pca` variant: a polynomial curve in the principal-axis frame, sampled
    at the pitch along its arc length, centred on the seen part."""
    t = thin(points).astype(np.float64)
    c = t.mean(axis=0)
    d = t - c
    _, vecs = np.linalg.eigh(d.T @ d)
    e = vecs[:, ::-1]  # largest variance first
    u, v, w = d @ e[:, 0], d @ e[:, 1], d @ e[:, 2]
    pv, pw = fit_polynomial(u, v, POLY_ORDER), fit_polynomial(u, w, POLY_ORDER)
    uu = np.linspace(u.min(), u.max(), 256)
    curve = c + np.outer(uu, e[:, 0]) + np.outer(pv(uu), e[:, 1]) + np.outer(pw(uu), e[:, 2])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(curve, axis=0), axis=1))])
    length = s[-1]
    nodes = np.empty((n_nodes, 3))
    for k in range(n_nodes):
        sk = length / 2 + (k - (n_nodes - 1) / 2.0) * pitch
        if length <= 0:
            nodes[k] = curve[0] + (sk - length / 2) * e[:, 0]
        elif sk <= 0:
            tan = curve[1] - curve[0]
            nodes[k] = curve[0] + sk * tan / np.linalg.norm(tan)
        elif sk >= length:
            tan = curve[-1] - curve[-2]
            nodes[k] = curve[-1] + (sk - length) * tan / np.linalg.norm(tan)
        else:
            j = int(np.searchsorted(s, sk, side="right"))
            seg = s[j] - s[j - 1]
            f = (sk - s[j - 1]) / seg if seg > 0 else 0.0
            nodes[k] = curve[j - 1] + f * (curve[j] - curve[j - 1])
    return orient(nodes, previous)


def track(points, nodes, pitch, n_nodes):
    """One frame of Algorithm 1: returns (nodes, reinit)."""
    initialized_now = nodes is None
    if initialized_now:
        nodes = lsq_init(points, n_nodes, pitch, None)
    reinit = False
    remaining = ITERATIONS
    d2, t = np.empty((len(points), n_nodes)), np.empty((len(points), n_nodes))
    while remaining > 0:
        remaining -= 1
        # Squared distances axis by axis into two reused arrays: the same sum, in the same
        # order, as summing an (n, M, 3) array over its last axis, at a third of the time
        # and without a fresh (page-faulting) allocation per term.
        for a in range(3):
            np.subtract(points[:, a, None], nodes[None, :, a], out=t)
            np.multiply(t, t, out=t if a else d2)
            if a:
                np.add(d2, t, out=d2)
        winner = np.argmin(d2, axis=1)  # Eq. (11); ties to the lower index
        count = np.bincount(winner, minlength=n_nodes)
        if not initialized_now and (count == 0).any():  # Sec. IV.C
            nodes = lsq_init(points, n_nodes, pitch, nodes)
            reinit = initialized_now = True
            remaining = ITERATIONS
            continue
        for a in range(3):  # Eq. (12): each node to the mean of its neighbourhood
            s = np.bincount(winner, weights=points[:, a], minlength=n_nodes)
            nodes[count > 0, a] = s[count > 0] / count[count > 0]
    return nodes, reinit


def main():
    stdin, stdout = sys.stdin.buffer, sys.stdout
    nodes, pitch = None, 0.045
    while True:
        line = stdin.readline()
        if not line:
            return 0  # the episode is over
        h = json.loads(line)
        if h.get("linksight") != 1:
            print("som.py: protocol version %r, expected 1" % h.get("linksight"), file=sys.stderr)
            return 2
        if "chain" in h:
            pitch = h["chain"]["pitch_m"]
        n = h["points"]
        raw = stdin.read(12 * n)
        if len(raw) != 12 * n:
            return 0
        if "depth" in h:  # scene key external.send_depth: not used here
            stdin.read(2 * h["depth"]["width"] * h["depth"]["height"])
        points = np.frombuffer(raw, dtype="<f4").reshape(n, 3).astype(np.float64)
        points = points[np.isfinite(points).all(axis=1) & (np.abs(points) <= 100).all(axis=1)]
        if len(points) < h["nodes"]:
            answer = {"frame": h["frame"], "lost": True, "reason": "fewer points than nodes"}
        else:
            nodes, reinit = track(points, None if nodes is None else nodes.copy(), pitch,
                                  h["nodes"])
            answer = {"frame": h["frame"], "nodes": nodes.tolist(), "reinit": bool(reinit)}
        stdout.write(json.dumps(answer) + "\n")
        stdout.flush()


if __name__ == "__main__":
    sys.exit(main())
