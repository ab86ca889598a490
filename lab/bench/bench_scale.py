#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""bench_scale.py - the scale table (issue 27): the default request
(`mcf smooth IN OUT`, no option) against Open3D's filter_smooth_taubin at
its best pass count, from 43k to 7M vertices.

    bench_scale.py --mcf build/mcf --meshes ../shared/meshes [--reps 2] [--big]
                   [--work DIR] [--rows a,b] [--keep]

Rows: armadillo.obj (43,243 vertices) and dragon_vrip.drc (435,545) with
Gaussian noise of 0.25 mean edges along the normals, and the dragon split
into four at its edges' midpoints once (1.74M) and, with --big, twice
(6.96M), noise 0.25 of the split mesh's mean edge (scale_mesh.py: generated
here into --work, never committed). Every mesh is binary PLY, so both sides
read the same bytes.

Per row and repetition, interleaved: mcf with --threads 1, mcf with
--threads 2, Open3D (OMP_NUM_THREADS=1) with its best pass count, each a
child process, then the 1-thread dgemm rate; CPU = user + sys of the
child (wait4), wall, peak RSS (ru_maxrss). Open3D's CPU is its filter_smooth_taubin call alone
(time.process_time around it: the adjacency it builds included, the PLY
read and the Python start excluded); its pass count is an oracle, the
best of 1..40 against the clean mesh (found once before the timed runs).
Error: the area-weighted RMS distance to the clean mesh (barycentric
mass of the clean mesh, as mcf_compare's rms_m), over the input's. The
medians of the repetitions are printed, each row with the median of the
1-thread dgemm rates measured between its repetitions (absolute times mean
nothing without it: the machine is shared). About 25 minutes with two
repetitions on 2 shared cores (load 16, 2026-11-28), 18 more with --big at
one repetition (the 7M row: about 4-6 GB per process). The 7M row's files
(about 1.4 GB) are removed after its row unless --keep (regenerated in
about 15 s).
"""
import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from scale_mesh import read_ply  # noqa: E402

PASSES = [1, 2, 3, 4, 5, 6, 8, 10, 12, 15, 20, 25, 30, 40]

O3D_CHILD = r"""
import sys, time, numpy as np, open3d as o3d
sys.path.insert(0, %r)
from scale_mesh import read_ply, write_ply
X, F = read_ply(sys.argv[1])
m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(X), o3d.utility.Vector3iVector(F.astype(np.int32)))
t0 = time.process_time()
o = m.filter_smooth_taubin(number_of_iterations=int(sys.argv[2]))
cpu = time.process_time() - t0
Y = np.asarray(o.vertices)
write_ply(sys.argv[3], np.where(np.isfinite(Y), Y, X), F)
print(cpu)
""" % HERE

ORACLE_CHILD = r"""
import sys, numpy as np, open3d as o3d
sys.path.insert(0, %r)
from scale_mesh import read_ply
X, F = read_ply(sys.argv[1]); C, _ = read_ply(sys.argv[2])
a = np.linalg.norm(np.cross(C[F[:,1]]-C[F[:,0]], C[F[:,2]]-C[F[:,0]]), axis=1) / 6
w = np.zeros(len(C))
for k in range(3): np.add.at(w, F[:,k], a)
def rms(Y):
    Y = np.where(np.isfinite(Y), Y, X)
    return float(np.sqrt(np.sum(w * np.sum((Y - C) ** 2, 1)) / np.sum(w)))
cur, have, best, bp = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(X), o3d.utility.Vector3iVector(F.astype(np.int32))), 0, np.inf, 0
for p in %r:
    cur = cur.filter_smooth_taubin(number_of_iterations=p - have); have = p
    e = rms(np.asarray(cur.vertices))
    if e < best: best, bp = e, p
    elif e > 1.05 * best and p >= 2 * bp: break
print(bp)
""" % (HERE, PASSES)


def dgemm_rate():
    """GFLOP/s of a 1536 x 1536 dgemm on one OpenBLAS thread, best of 3."""
    code = ("import numpy as np, time\n"
            "a = np.random.rand(1536, 1536); b = np.random.rand(1536, 1536); best = 1e9\n"
            "for _ in range(3):\n"
            "    t = time.perf_counter(); a @ b; best = min(best, time.perf_counter() - t)\n"
            "print(2 * 1536 ** 3 / best / 1e9)\n")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    return float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                text=True, check=True).stdout)


def cpu_model():
    """The CPU's model name (/proc/cpuinfo), else the machine type."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def run(argv, env=None):
    """(stdout, CPU s, wall s, peak RSS bytes) of a child process."""
    t0 = time.perf_counter()
    p = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    out, err = p.stdout.read().decode(), p.stderr.read().decode()
    p.stdout.close()
    p.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit("bench_scale: %s failed: %s" % (argv[0], err.strip()))
    return out, ru.ru_utime + ru.ru_stime, wall, ru.ru_maxrss * 1024


def weights(C, F):
    a = np.linalg.norm(np.cross(C[F[:, 1]] - C[F[:, 0]], C[F[:, 2]] - C[F[:, 0]]), axis=1) / 6
    w = np.zeros(len(C))
    for k in range(3):
        np.add.at(w, F[:, k], a)
    return w


def rms(Y, C, w):
    return float(np.sqrt(np.sum(w * np.sum((Y - C) ** 2, 1)) / np.sum(w)))


def make_rows(args):
    os.makedirs(args.work, exist_ok=True)
    rows = []
    src = [("armadillo", "armadillo.obj", 0), ("dragon", "dragon_vrip.drc", 0),
           ("dragon x4", "dragon_vrip.drc", 1)]
    if args.big:
        src.append(("dragon x16", "dragon_vrip.drc", 2))
    for name, f, lv in src:
        if args.rows and name.replace(" ", "") not in args.rows.split(","):
            continue
        base = os.path.join(args.work, os.path.splitext(f)[0] + ".ply")
        if not os.path.exists(base):
            subprocess.run([args.mcf, "convert", os.path.join(args.meshes, f), base], check=True)
        noisy = os.path.join(args.work, "%s-l%d-noisy.ply" % (os.path.splitext(f)[0], lv))
        clean = noisy.replace("-noisy", "-clean")
        if not os.path.exists(noisy):
            subprocess.run([sys.executable, os.path.join(HERE, "scale_mesh.py"), base, str(lv),
                            "0.25", "1", noisy, clean], check=True, stdout=subprocess.DEVNULL)
        rows.append((name, noisy, clean))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mcf", required=True)
    ap.add_argument("--meshes", required=True)
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--big", action="store_true", help="the 7M row too")
    ap.add_argument("--work", default="build/lab/bench/scale")
    ap.add_argument("--rows", default="", help="e.g. armadillo,dragon: those rows only")
    ap.add_argument("--keep", action="store_true", help="keep the 7M row's generated files")
    args = ap.parse_args()
    o3d_env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    rate = dgemm_rate()
    print("scale table: %s, %d cores, %s UTC, load %.1f; 1-thread dgemm %.1f GFLOP/s"
          % (cpu_model(), os.cpu_count(),
             time.strftime("%Y-%m-%d %H:%M", time.gmtime()), os.getloadavg()[0], rate),
          flush=True)
    print("the default request (`mcf smooth IN OUT`) vs Open3D filter_smooth_taubin at its best "
          "pass count (OMP_NUM_THREADS=1); medians of %d interleaved repetitions" % args.reps)
    hdr = ("%-11s %9s | %8s %8s %8s %8s %7s %6s %6s | %6s %8s %8s %7s %6s | %7s %7s | %6s %5s"
           % ("mesh", "vertices", "CPU 1t", "wall 1t", "CPU 2t", "wall 2t", "RSS MB", "B/vtx",
              "err", "passes", "o3d CPU", "o3d wall", "RSS MB", "err", "CPU x", "err x",
              "dgemm", "load"))
    print(hdr)
    for name, noisy, clean in make_rows(args):
        C, F = read_ply(clean)
        X, _ = read_ply(noisy)
        w = weights(C, F)
        e_in = rms(X, C, w)
        passes = int(run([sys.executable, "-c", ORACLE_CHILD, noisy, clean], env=o3d_env)[0])
        out = noisy.replace("-noisy", "-out")
        o3d_out = noisy.replace("-noisy", "-o3d")
        m1, m2, o3, dg = [], [], [], []
        for _ in range(args.reps):
            _, cpu, wall, rss = run([args.mcf, "smooth", noisy, out, "--threads", "1", "--quiet"])
            m1.append((cpu, wall, rss))
            _, cpu, wall, rss = run([args.mcf, "smooth", noisy, out, "--threads", "2", "--quiet"])
            m2.append((cpu, wall, rss))
            s, _, wall, rss = run([sys.executable, "-c", O3D_CHILD, noisy, str(passes), o3d_out],
                                  env=o3d_env)
            o3.append((float(s), wall, rss))
            dg.append(dgemm_rate())
        e_m = rms(read_ply(out)[0], C, w) / e_in
        e_o = rms(read_ply(o3d_out)[0], C, w) / e_in
        med = lambda v, k: statistics.median(x[k] for x in v)  # noqa: E731
        cpu1, rss1, cpuo = med(m1, 0), max(x[2] for x in m1 + m2), med(o3, 0)
        print("%-11s %9d | %8.2f %8.2f %8.2f %8.2f %7.0f %6.0f %6.3f | %6d %8.2f %8.2f %7.0f "
              "%6.3f | %7.2f %7.2f | %6.1f %5.1f"
              % (name, len(X), cpu1, med(m1, 1), med(m2, 0), med(m2, 1), rss1 / 1e6,
                 rss1 / len(X), e_m, passes, cpuo, med(o3, 1), max(x[2] for x in o3) / 1e6,
                 e_o, cpu1 / cpuo, e_m / e_o, statistics.median(dg), os.getloadavg()[0]),
              flush=True)
        if name == "dragon x16" and not args.keep:
            for f in (noisy, clean, out, o3d_out):
                os.remove(f)
    print("CPU x, err x: mcf's CPU (1 thread) and error over Open3D's; err: over the input's; "
          "RSS: the peak of the process (B/vtx: mcf's over the vertices); dgemm: the 1-thread "
          "GFLOP/s measured between the row's repetitions (median), %.1f before the first row; "
          "load: the 1-minute load average at the row's end" % rate)


if __name__ == "__main__":
    main()
