#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""evidence.py - issue 31's scanner noise on a real scan, end to end.

    evidence.py MESH OUTDIR [--mcfd URL]

Injects two of make quality's noise models into MESH (an OBJ: the clean
scan), seed 1, h its mean edge over the unique edges, only the interior
vertices moved: `out` (Gaussian 0.1 h along the clean area-weighted
vertex normals, then 1% of the moved vertices pushed 3-5 h along theirs,
random sign) and `view` (Gaussian 0.5 h along one unit vector). Each noisy
mesh goes through `build/mcf smooth` with the defaults (and, with --mcfd,
through the daemon's POST /smooth with no parameter, the result compared
with the CLI's); prints the error (area-weighted RMS distance to the clean
vertices, the clean mesh's barycentric areas) over the input's, the faces
turned against the clean mesh's, and the metrics' reading; writes
OUTDIR/MODEL.png (clean, noisy, default: lab/bench/render_quality.py).
Debian's /usr/bin/python3 (numpy, matplotlib, PIL).
"""
import json
import os
import subprocess
import sys
import urllib.request
import uuid

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))
MCF = os.path.join(ROOT, "build", "mcf")
RENDER = os.path.join(ROOT, "lab", "bench", "render_quality.py")


def read_obj(path):
    V, F = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                V.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("f "):
                F.append([int(x.split("/")[0]) - 1 for x in line.split()[1:4]])
    return np.array(V), np.array(F, dtype=np.int64)


def write_obj(path, V, F):
    with open(path, "w") as f:
        f.write("".join("v %.17g %.17g %.17g\n" % tuple(v) for v in V))
        f.write("".join("f %d %d %d\n" % tuple(t + 1) for t in F))


def write_raw(path, V, F):
    with open(path, "wb") as f:
        f.write(np.array([len(V), len(F)], dtype=np.int32).tobytes())
        f.write(np.ascontiguousarray(V, dtype=np.float64).tobytes())
        f.write(np.ascontiguousarray(F, dtype=np.int32).tobytes())


def face_normals(V, F):
    return np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])


def geometry(V, F):
    fn = face_normals(V, F)
    area = 0.5 * np.linalg.norm(fn, axis=1)
    w = np.zeros(len(V))
    N = np.zeros_like(V)
    for k in range(3):
        np.add.at(w, F[:, k], area / 3)
        np.add.at(N, F[:, k], fn)
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    ue, cnt = np.unique(e, axis=0, return_counts=True)
    h = np.linalg.norm(V[ue[:, 0]] - V[ue[:, 1]], axis=1).mean()
    moved = np.zeros(len(V), bool)
    moved[np.unique(F)] = True
    moved[ue[cnt == 1].ravel()] = False  # the boundary stays
    return w, N, h, moved


def noisy(model, V, N, h, moved, seed=1):
    rng = np.random.default_rng(seed)
    X = V.copy()
    idx = np.flatnonzero(moved)
    if model == "out":
        X[idx] += (0.1 * h * rng.standard_normal(len(idx)))[:, None] * N[idx]
        k = max(1, round(0.01 * len(idx)))
        pick = rng.choice(idx, size=k, replace=False)
        a = rng.uniform(3.0, 5.0, k) * h * rng.choice([-1.0, 1.0], k)
        X[pick] += a[:, None] * N[pick]
    else:
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        X[idx] += (0.5 * h * rng.standard_normal(len(idx)))[:, None] * u[None, :]
    return X


def post_smooth(url, path):
    boundary = uuid.uuid4().hex
    with open(path, "rb") as f:
        data = f.read()
    body = (("--%s\r\nContent-Disposition: form-data; name=\"mesh\"; filename=\"in.obj\"\r\n"
             "Content-Type: application/octet-stream\r\n\r\n" % boundary).encode() + data +
            ("\r\n--%s--\r\n" % boundary).encode())
    req = urllib.request.Request(url.rstrip("/") + "/smooth", data=body, method="POST",
                                 headers={"Content-Type": "multipart/form-data; boundary=" + boundary})
    with urllib.request.urlopen(req, timeout=600) as r:
        return r.read()


def main():
    mesh, out = sys.argv[1], sys.argv[2]
    url = sys.argv[sys.argv.index("--mcfd") + 1] if "--mcfd" in sys.argv else None
    os.makedirs(out, exist_ok=True)
    tmp = os.path.join(out, "tmp")
    os.makedirs(tmp, exist_ok=True)
    V, F = read_obj(mesh)
    w, N, h, moved = geometry(V, F)
    fc = face_normals(V, F)
    name = os.path.basename(mesh)

    def err(X):
        return np.sqrt((w * ((X - V) ** 2).sum(1)).sum() / w.sum())

    def flips(X):
        return int(((face_normals(X, F) * fc).sum(1) < 0).sum())

    for model in ("out", "view"):
        X = noisy(model, V, N, h, moved)
        pin, pout, pm = (os.path.join(tmp, model + s) for s in (".in.obj", ".out.obj", ".json"))
        write_obj(pin, X, F)
        r = subprocess.run([MCF, "smooth", pin, pout, "--quiet", "--metrics", pm], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        Y, _ = read_obj(pout)
        fl = json.load(open(pm))["flow"]
        line = ("%s %s: %d vertices, h %.4g; input error %.4g, default %.4g = %.3f of the input's; "
                "flipped faces %d -> %d; metrics: noise %.3f h (%s), tangential %.3f h, share %s, "
                "direction %s, spikes_repaired %d, filter %s, steps %d"
                % (name, model, len(V), h, err(X), err(Y), err(Y) / err(X), flips(X), flips(Y),
                   fl["noise"], fl["noise_kind"], fl["noise_tangential"],
                   "%.3f" % fl["noise_share"] if fl["noise_share"] is not None else "null",
                   "null" if fl["noise_direction"] is None else
                   "(%s)" % ", ".join("%.3f" % c for c in fl["noise_direction"]),
                   fl["spikes_repaired"], fl["filter"], fl["steps"]))
        if url:
            pd = os.path.join(tmp, model + ".mcfd.obj")
            with open(pd, "wb") as f:
                f.write(post_smooth(url, pin))
            Z, _ = read_obj(pd)
            line += "; mcfd POST /smooth: error %.4g, max |mcfd - mcf| %.3g" % (err(Z), np.abs(Z - Y).max())
        print(line, flush=True)
        raws = []
        for tag, M in (("clean", V), ("noisy", X), ("default", Y)):
            p = os.path.join(tmp, "%s.%s.raw" % (model, tag))
            write_raw(p, M, F)
            raws.append("%s=%s" % (p, tag))
        title = "%s, %s noise: input error %.3g, default %.3f of it" % (name, model, err(X), err(Y) / err(X))
        r = subprocess.run(["/usr/bin/python3", RENDER, "--out", os.path.join(out, model + ".png"),
                            "--title", title] + raws, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        shrink(os.path.join(out, model + ".png"))


def shrink(path):
    """3/4 the size, 64 colours: a few hundred KB down to about 110."""
    from PIL import Image
    im = Image.open(path).convert("RGB")
    im = im.resize((im.width * 3 // 4, im.height * 3 // 4), Image.LANCZOS).quantize(colors=64)
    im.save(path, optimize=True)


if __name__ == "__main__":
    main()
