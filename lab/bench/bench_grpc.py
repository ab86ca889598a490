#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""bench_grpc.py - `make bench`, the gRPC door's part (issue 10): gRPC Smooth
against REST POST /smooth and `mcf smooth` on the same meshes, measured in
the same run on one mcfd (--workers 1, loopback).

Per mesh (bunny.drc and armadillo.obj from MESHES, sphere_cgal.obj for the
fixed costs): one warm-up of each, then --reps rounds, the three
interleaved (the order rotating each round) so a load change on the shared
machine hits all alike; medians. Both doors are driven from this one
Python process: gRPC with examples/grpc_client.py's smooth() (Debian's
grpcio, a channel kept open as gRPC clients do), REST with urllib (raw body,
a new connection per request, as curl --data-binary). The flow is
scheme=desbrun2&iterations=10 everywhere, so the job is the same and the
difference is the door. Sanity: the three give the same bytes.
Goal: gRPC <= 1.1 x REST. Exit status 1 only when something cannot run or
the bytes differ; a goal marked FAIL is a result.
"""
import argparse
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "examples"))
import grpc  # noqa: E402
from grpc_client import smooth, stubs  # noqa: E402

GOAL = 1.10
QUERY = "scheme=desbrun2&iterations=10"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mcf", required=True)
    ap.add_argument("--mcfd", required=True)
    ap.add_argument("--meshes", default="")
    ap.add_argument("--testdata", default=os.path.join(os.path.dirname(HERE), "tests", "data", "meshes"))
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    pb, pb_grpc = stubs()
    meshes = []
    for name in ("bunny.drc", "armadillo.obj", "sphere_cgal.obj"):
        for d in (a.testdata, a.meshes):
            if d and os.path.exists(os.path.join(d, name)):
                meshes.append(os.path.join(d, name))
                break
        else:
            print("bench_grpc: %s not found (MESHES=%s): skipped" % (name, a.meshes))
    tmp = tempfile.mkdtemp(prefix="bench_grpc.")
    env = dict(os.environ, OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"),
               OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"),
               OMP_THREAD_LIMIT=os.environ.get("OMP_THREAD_LIMIT", "1"))
    p = subprocess.Popen([a.mcfd, "--bind", "127.0.0.1", "--port", "0", "--grpc-port", "0",
                          "--workers", "1", "--spool", os.path.join(tmp, "spool")],
                         stdout=subprocess.PIPE, stderr=open(os.path.join(tmp, "log"), "wb"),
                         env=env, start_new_session=True)
    try:
        port = int(p.stdout.readline().decode().rsplit(":", 1)[1])
        gport = int(p.stdout.readline().decode().rsplit(":", 1)[1])
        ch = grpc.insecure_channel("127.0.0.1:%d" % gport)
        stub = pb_grpc.SmootherStub(ch)
        params = pb.Params(scheme="desbrun2", iterations=10)
        print("bench_grpc: gRPC Smooth vs REST POST /smooth vs mcf smooth (%s), median of %d, "
              "mcfd --workers 1, loopback; grpcio %s" % (QUERY, a.reps, grpc.__version__))
        print("  %-16s %9s %9s %9s | %10s %10s | %-6s | %s" %
              ("mesh", "gRPC ms", "REST ms", "mcf ms", "gRPC/REST", "gRPC/mcf", "goal", "same bytes"))
        ok = True
        for path in meshes:
            with open(path, "rb") as f:
                data = f.read()
            ext = os.path.splitext(path)[1]
            out = os.path.join(tmp, "out" + ext)

            def run_grpc():
                return smooth(stub, pb, data, params)[0]

            def run_rest():
                req = urllib.request.Request("http://127.0.0.1:%d/smooth?%s" % (port, QUERY), data=data,
                                             headers={"Content-Type": "application/octet-stream"})
                with urllib.request.urlopen(req, timeout=600) as r:
                    return r.read()

            def run_mcf():
                subprocess.check_call([a.mcf, "smooth", path, out, "--scheme", "desbrun2",
                                       "--iterations", "10", "--quiet"], env=env)
                with open(out, "rb") as f:
                    return f.read()

            runs = [("grpc", run_grpc), ("rest", run_rest), ("mcf", run_mcf)]
            times = {k: [] for k, _ in runs}
            outs = {k: fn() for k, fn in runs}      # warm-up, and the bytes
            for r in range(a.reps):
                for k, fn in runs[r % 3:] + runs[:r % 3]:
                    t0 = time.perf_counter()
                    fn()
                    times[k].append(time.perf_counter() - t0)
            m = {k: statistics.median(v) for k, v in times.items()}
            same = outs["grpc"] == outs["rest"] == outs["mcf"]
            ok &= same
            print("  %-16s %9.1f %9.1f %9.1f | %9.3fx %9.3fx | %-6s | %s" %
                  (os.path.basename(path), m["grpc"] * 1e3, m["rest"] * 1e3, m["mcf"] * 1e3,
                   m["grpc"] / m["rest"], m["grpc"] / m["mcf"],
                   "ok" if m["grpc"] <= GOAL * m["rest"] else "FAIL", "yes" if same else "NO"))
        print("  goal: gRPC Smooth <= %.2f x REST /smooth" % GOAL)
        ch.close()
        p.send_signal(signal.SIGTERM)
        p.wait(30)
        return 0 if ok else 1
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
