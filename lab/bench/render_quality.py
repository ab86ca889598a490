#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""render_quality.py - side-by-side renders of make quality's cases (matplotlib).

    render_quality.py --out FILE.png --title TEXT MESH=LABEL [MESH=LABEL ...]

Each MESH is a raw mesh as bench_quality writes them (int32 nv, int32 nf,
nv*3 float64 positions, nf*3 int32 indices), all with the same faces; the
first is the clean one. Row 1: every mesh whole; row 2: a zoom on the same
window, centred where the third mesh (the default's result; the second when
there are two) is farthest from the clean one, a square of 12% of the
clean mesh's extent. The view looks along the clean mesh's axis of least
spread (its broad side), tilted 30 degrees, flat-shaded faces (two-sided Lambert from a fixed
light), painter-sorted. bench_quality calls it for the worst case per
model and for --render cases; it also renders any such files by hand.
Debian's /usr/bin/python3 with numpy and matplotlib (Agg).
"""
import argparse

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402


def read_raw(path):
    with open(path, "rb") as f:
        nv, nf = np.frombuffer(f.read(8), dtype=np.int32)
        X = np.frombuffer(f.read(24 * int(nv)), dtype=np.float64).reshape(-1, 3)
        F = np.frombuffer(f.read(12 * int(nf)), dtype=np.int32).reshape(-1, 3)
    return X.copy(), F.copy()


def view_frame(X, F):
    """Rows: the clean mesh's principal axes, largest spread first, then
    turned 30 degrees about the first: the view looks along the least
    spread axis, a little from above."""
    used = np.unique(F)
    P = X[used] - X[used].mean(axis=0)
    _, _, vt = np.linalg.svd(P, full_matrices=False)
    R = vt.copy()
    if np.linalg.det(R) < 0:
        R[2] = -R[2]
    a = np.radians(30.0)  # tilted 30 degrees about the first axis: some depth to the shading
    tilt = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    return tilt @ R


def draw(ax, X, F, R, window=None):
    P = X @ R.T
    T = P[F]  # nf x 3 x 3
    if window is not None:
        (x0, x1), (y0, y1) = window
        c = T.mean(axis=1)
        keep = (c[:, 0] >= x0) & (c[:, 0] <= x1) & (c[:, 1] >= y0) & (c[:, 1] <= y1)
        T = T[keep]
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    ln = np.linalg.norm(n, axis=1)
    ok = ln > 0
    T, n, ln = T[ok], n[ok], ln[ok]
    light = np.array([0.35, 0.45, 0.82])
    light /= np.linalg.norm(light)
    lam = np.abs(n @ light) / ln
    g = 0.15 + 0.85 * lam
    g = np.where(n[:, 2] < 0, 0.7 * g, g)  # back-facing: darker
    order = np.argsort(T[:, :, 2].mean(axis=1))  # far first (viewer at +z)
    cols = np.stack([0.93 * g, 0.88 * g, 0.80 * g, np.ones_like(g)], axis=1)[order]
    pc = PolyCollection(T[order][:, :, :2], facecolors=cols, edgecolors="none", antialiased=False)
    ax.add_collection(pc)
    ax.set_aspect("equal")
    ax.set_axis_off()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--title", default="")
    ap.add_argument("meshes", nargs="+", help="PATH=LABEL")
    a = ap.parse_args()
    items = [m.split("=", 1) if "=" in m else (m, m) for m in a.meshes]
    meshes = [read_raw(p) for p, _ in items]
    Xc, F = meshes[0]
    R = view_frame(Xc, F)
    Pc = Xc[np.unique(F)] @ R.T
    lo, hi = Pc.min(axis=0), Pc.max(axis=0)
    pick = meshes[2][0] if len(meshes) > 2 else meshes[-1][0]
    d = np.linalg.norm(pick - Xc, axis=1)
    centre = (Xc[int(np.argmax(d))] @ R.T)[:2]
    half = 0.06 * max(hi[0] - lo[0], hi[1] - lo[1])
    window = ((centre[0] - half, centre[0] + half), (centre[1] - half, centre[1] + half))
    n = len(meshes)
    fig, axes = plt.subplots(2, n, figsize=(3.6 * n, 7.6), squeeze=False)
    for i, ((X, Fm), (_, label)) in enumerate(zip(meshes, items)):
        draw(axes[0][i], X, Fm, R)
        axes[0][i].set_xlim(lo[0], hi[0])
        axes[0][i].set_ylim(lo[1], hi[1])
        axes[0][i].set_title(label, fontsize=8)
        draw(axes[1][i], X, Fm, R, window)
        axes[1][i].set_xlim(*window[0])
        axes[1][i].set_ylim(*window[1])
        if i == 0:
            r = plt.Rectangle((window[0][0], window[1][0]), 2 * half, 2 * half, fill=False, ec="red", lw=0.8)
            axes[0][0].add_patch(r)
    fig.suptitle(a.title + "  (row 2: zoom on the red square)", fontsize=10)
    fig.tight_layout()
    fig.savefig(a.out, dpi=90)


if __name__ == "__main__":
    main()
