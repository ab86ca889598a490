#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""scale_mesh.py - the scale table's big scans (bench_scale.py), generated, not committed.

    scale_mesh.py IN.ply LEVELS RHO SEED NOISY.ply CLEAN.ply

Reads a binary little-endian PLY (what `mcf convert X.drc X.ply` writes),
splits every triangle into four at its edges' midpoints LEVELS times (the
435,545-vertex dragon: 1,740,274 vertices once, 6,956,572 twice), and adds
Gaussian noise along the subdivided mesh's area-weighted vertex normals,
sigma = RHO x its mean edge, from SEED (the law of tests/noisy.py and the
C tests' tl_write_noisy). Writes the noisy mesh and the clean one as binary
PLY (float64 positions, int32 faces). Debian's /usr/bin/python3 and numpy;
about 15 s and 3 GB for two levels of the dragon.
"""
import sys

import numpy as np


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    head = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in head:
        raise SystemExit("scale_mesh: %s: not a binary little-endian PLY" % path)
    nv = nf = 0
    vprops, cur, flist = [], None, None
    types = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
             "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
             "uchar": "u1", "uint8": "u1", "char": "i1", "int8": "i1",
             "short": "<i2", "ushort": "<u2"}
    for line in head:
        t = line.split()
        if t[:2] == ["element", "vertex"]:
            nv, cur = int(t[2]), "v"
        elif t[:2] == ["element", "face"]:
            nf, cur = int(t[2]), "f"
        elif t[:1] == ["element"]:
            cur = "other"
        elif t[:1] == ["property"] and cur == "v":
            vprops.append((t[2], types[t[1]]))
        elif t[:2] == ["property", "list"] and cur == "f":
            flist = (types[t[2]], types[t[3]])
    vdt = np.dtype(vprops)
    V = np.frombuffer(data, dtype=vdt, count=nv, offset=end)
    X = np.stack([V["x"], V["y"], V["z"]], axis=1).astype(np.float64)
    fdt = np.dtype([("n", flist[0]), ("i", flist[1], (3,))])
    Fr = np.frombuffer(data, dtype=fdt, count=nf, offset=end + vdt.itemsize * nv)
    if np.any(Fr["n"] != 3):
        raise SystemExit("scale_mesh: %s: not a triangle mesh" % path)
    return X, Fr["i"].astype(np.int64)


def subdivide(X, F):
    """Each triangle into four at its edges' midpoints (shared edges once)."""
    nv = len(X)
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = np.minimum(e[:, 0], e[:, 1]) * nv + np.maximum(e[:, 0], e[:, 1])
    uk, inv = np.unique(key, return_inverse=True)
    a, b = uk // nv, uk % nv
    X2 = np.concatenate([X, 0.5 * (X[a] + X[b])])
    m = (inv + nv).reshape(3, -1).T  # midpoints of edges 01, 12, 20
    v0, v1, v2 = F[:, 0], F[:, 1], F[:, 2]
    m01, m12, m20 = m[:, 0], m[:, 1], m[:, 2]
    F2 = np.concatenate([np.stack([v0, m01, m20], 1), np.stack([v1, m12, m01], 1),
                         np.stack([v2, m20, m12], 1), np.stack([m01, m12, m20], 1)])
    return X2, F2


def normals_and_edge(X, F):
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    fn = np.cross(b - a, c - a)
    n = np.zeros_like(X)
    for k in range(3):
        np.add.at(n, F[:, k], fn)
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    h = np.mean([np.linalg.norm(b - a, axis=1).mean(), np.linalg.norm(c - b, axis=1).mean(),
                 np.linalg.norm(a - c, axis=1).mean()])
    return n, h


def write_ply(path, X, F):
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
            "property double x\nproperty double y\nproperty double z\n"
            "element face %d\nproperty list uchar int vertex_indices\nend_header\n"
            % (len(X), len(F))).encode()
    fr = np.empty(len(F), dtype=np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    fr["n"] = 3
    fr["i"] = F
    with open(path, "wb") as f:
        f.write(head)
        f.write(np.ascontiguousarray(X, dtype="<f8").tobytes())
        f.write(fr.tobytes())


def main():
    if len(sys.argv) != 7:
        raise SystemExit(__doc__)
    X, F = read_ply(sys.argv[1])
    for _ in range(int(sys.argv[2])):
        X, F = subdivide(X, F)
    n, h = normals_and_edge(X, F)
    rng = np.random.default_rng(int(sys.argv[4]))
    Xn = X + n * rng.normal(0.0, float(sys.argv[3]) * h, len(X))[:, None]
    write_ply(sys.argv[5], Xn, F)
    write_ply(sys.argv[6], X, F)
    print("%s: %d vertices, %d faces, mean edge %.6g" % (sys.argv[5], len(X), len(F), h))


if __name__ == "__main__":
    main()
