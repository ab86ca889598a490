# SPDX-License-Identifier: MIT
"""noisy.py - a noisy copy of a test mesh, for the Python tests (the C
tests have testlib's tl_write_noisy). Debian's /usr/bin/python3 and numpy."""
import numpy as np


def noisy_obj(path, rho, seed):
    """The OBJ bytes of the triangle mesh at path (v and f lines only) with
    Gaussian noise along the area-weighted vertex normals, sigma = rho x
    the mean edge length, from seed: what a client that tests denoising
    sends, now that injecting noise is the lab's and not a job parameter
    (the C tests' tl_write_noisy; another generator, the same law)."""
    V, F = [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if t[:1] == ["v"]:
                V.append([float(x) for x in t[1:4]])
            elif t[:1] == ["f"]:
                F.append([int(x.split("/")[0]) - 1 for x in t[1:4]])
    V, F = np.array(V), np.array(F)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    fn = np.cross(b - a, c - a)  # twice the area times the unit normal
    n = np.zeros_like(V)
    for k in range(3):
        np.add.at(n, F[:, k], fn)
    n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
    h = np.mean([np.linalg.norm(b - a, axis=1).mean(), np.linalg.norm(c - b, axis=1).mean(),
                 np.linalg.norm(a - c, axis=1).mean()])
    V = V + n * np.random.default_rng(seed).normal(0.0, rho * h, len(V))[:, None]
    out = ["v %.17g %.17g %.17g" % tuple(v) for v in V] + ["f %d %d %d" % tuple(f + 1) for f in F]
    return ("\n".join(out) + "\n").encode()


if __name__ == "__main__":
    # python3 tests/noisy.py IN.obj RHO SEED OUT.obj (test_ui.mjs's noisy upload)
    import sys
    with open(sys.argv[4], "wb") as f:
        f.write(noisy_obj(sys.argv[1], float(sys.argv[2]), int(sys.argv[3])))
