#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""quadnoise.py IN.obj NAME - spot and car, whose PLY from `mcf convert` scale_mesh.py
refuses ("not a triangle mesh"): the OBJ's polygons split into fans, then
scale_mesh.py's law (Gaussian noise along the area-weighted vertex normals, sigma =
rho x the mean edge, seed 1) at rho 0.1, 0.25, 0.5 into in/NAME_nRHO.ply, and the
clean mesh into in/NAME_clean.ply."""
import sys
import os
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "bench"))
import numpy as np, scale_mesh as sm
def read_obj(p):
    V, F = [], []
    for l in open(p):
        t = l.split()
        if not t: continue
        if t[0] == "v": V.append([float(x) for x in t[1:4]])
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) - 1 for x in t[1:]]
            for k in range(1, len(idx) - 1): F.append([idx[0], idx[k], idx[k + 1]])
    return np.array(V), np.array(F, dtype=np.int64)
X, F = read_obj(sys.argv[1]); b = sys.argv[2]
n, h = sm.normals_and_edge(X, F)
sm.write_ply("in/%s_clean.ply" % b, X, F)
for r in (0.1, 0.25, 0.5):
    rng = np.random.default_rng(1)
    sm.write_ply("in/%s_n%s.ply" % (b, r), X + n * rng.normal(0.0, r * h, len(X))[:, None], F)
