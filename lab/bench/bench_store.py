#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""bench_store.py - what keeping jobs in Redis (mcfd --store redis://) costs
per async job against the local spool, and how 1, 2 and 3 replicas sharing
one Redis store do (issue 22), on this machine, measured in the same run,
interleaved and repeated.

Four setups: one mcfd on the local spool, and 1, 2, 3 mcfd replicas on one
redis-server (each setup its own database, so that their queues stay
apart), one worker per mcfd. Each round sends the same batch of small
async jobs (POST /v1/jobs; the job's own work is small beside the
store's) to each setup in rotating order, job i submitted to replica
i % N, its status polled on the next replica and its result read on the
one after, and waits for all of them to succeed. Reported per setup
(medians over the rounds): jobs/s of the batch, p50/p99 of the submission
(202) latency and of GET .../result, the CPU seconds per job of the mcfds
and of redis-server (/proc, utime+stime), then the ratios against the
spool. redis-server runs with the AOF on and appendfsync always, as
docker/kubernetes-redis.yaml deploys it.

  /usr/bin/python3 lab/bench/bench_store.py --mcfd build/mcfd [--jobs 40] [--reps 5]
      [--mesh tests/data/meshes/bunny.drc --iterations 10]   (jobs whose own work dominates)
"""
import argparse
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import tempfile
import time
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MESH = os.path.join(ROOT, "tests", "data", "meshes", "test_nm.obj")
TICK = os.sysconf("SC_CLK_TCK")


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def cpu_s(pid):
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def http(method, url, body=None):
    req = urllib.request.Request(url, data=body, method=method,
                                 headers={"Content-Type": "application/octet-stream"})
    t0 = time.perf_counter()
    with urllib.request.urlopen(req, timeout=60) as r:
        data = r.read()
        return r.status, data, time.perf_counter() - t0


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def start_mcfd(mcfd, tmp, name, *flags):
    port = free_port()
    p = subprocess.Popen([mcfd, "--bind", "127.0.0.1", "--port", str(port), "--grpc-port", "off",
                          "--workers", "1", "--spool", os.path.join(tmp, name), *flags],
                         stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, name + ".log"), "w"),
                         start_new_session=True)
    url = "http://127.0.0.1:%d" % port
    for _ in range(300):
        try:
            if http("GET", url + "/readyz")[0] == 200:
                return p, url
        except OSError:
            pass
        time.sleep(0.05)
    raise SystemExit("%s did not start (see %s.log)" % (name, name))


def start_redis(tmp):
    """A redis-server on a free loopback port, its files in tmp, AOF on with
    appendfsync always (as docker/kubernetes-redis.yaml deploys it):
    (Popen, port)."""
    port = free_port()
    p = subprocess.Popen(["redis-server", "--port", str(port), "--bind", "127.0.0.1",
                          "--dir", tmp, "--appendonly", "yes", "--appendfsync", "always",
                          "--save", "", "--logfile", os.path.join(tmp, "redis.log")],
                         start_new_session=True)
    time.sleep(0.5)
    return p, port


def stop_all(procs, tmp):
    """SIGTERM (then SIGKILL) to each process group, tmp removed."""
    for p in procs:
        try:
            os.killpg(p.pid, signal.SIGTERM)
            p.wait(30)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            os.killpg(p.pid, signal.SIGKILL)
    shutil.rmtree(tmp, ignore_errors=True)


def batch(urls, mesh, n, iterations=1):
    ids, sub, get, k = [], [], [], len(urls)
    t0 = time.perf_counter()
    for i in range(n):
        st, body, dt = http("POST", urls[i % k] + "/v1/jobs?scheme=desbrun2&iterations=%d" % iterations, mesh)
        assert st == 202
        ids.append(json.loads(body)["id"])
        sub.append(dt)
    for i, jid in enumerate(ids):
        url = urls[(i + 1) % k]
        while json.loads(http("GET", "%s/v1/jobs/%s" % (url, jid))[1])["status"] != "succeeded":
            time.sleep(0.005)
    wall = time.perf_counter() - t0
    for i, jid in enumerate(ids):
        url = urls[(i + 2) % k]
        get.append(http("GET", "%s/v1/jobs/%s/result" % (url, jid))[2])
        http("DELETE", "%s/v1/jobs/%s" % (url, jid))
    return n / wall, sub, get


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mcfd", default=os.path.join(ROOT, "build", "mcfd"))
    ap.add_argument("--jobs", type=int, default=40)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--mesh", default=MESH)
    ap.add_argument("--iterations", type=int, default=1)
    a = ap.parse_args()
    with open(a.mesh, "rb") as f:
        mesh = f.read()
    tmp = tempfile.mkdtemp(prefix="mcfd-bench-store-")
    procs = []
    try:
        rd, rport = start_redis(tmp)
        procs.append(rd)
        setups = [("spool", [start_mcfd(a.mcfd, tmp, "spool")])]
        for n in (1, 2, 3):                   # database n: its own queue
            store = "redis://127.0.0.1:%d/%d" % (rport, n)
            setups.append(("redis x%d" % n, [start_mcfd(a.mcfd, tmp, "r%d-%d" % (n, i), "--store", store)
                                             for i in range(n)]))
        for _, ds in setups:
            procs += [p for p, _ in ds]
        res = {name: [] for name, _ in setups}
        for name, ds in setups:               # warm each
            batch([u for _, u in ds], mesh, 5)
        for rep in range(a.reps):
            order = setups[rep % len(setups):] + setups[:rep % len(setups)]
            for name, ds in order:
                pids = [p.pid for p, _ in ds]
                c0, r0 = sum(cpu_s(x) for x in pids), cpu_s(rd.pid)
                rate, sub, get = batch([u for _, u in ds], mesh, a.jobs, a.iterations)
                res[name].append(dict(rate=rate, sub=sub, get=get,
                                      cpu=(sum(cpu_s(x) for x in pids) - c0) / a.jobs,
                                      rcpu=(cpu_s(rd.pid) - r0) / a.jobs))
        print("bench_store: %d async jobs of %s (iterations=%d, one worker per mcfd) x %d rounds, "
              "rotating order; medians over the rounds; %d cores" % (
                  a.jobs, os.path.basename(a.mesh), a.iterations, a.reps, os.cpu_count()))
        print("%-9s %8s %10s %10s %10s %10s %12s %14s" % (
            "setup", "jobs/s", "POST p50", "POST p99", "GET p50", "GET p99",
            "mcfd CPU/job", "redis CPU/job"))
        med = {}
        for name, _ in setups:
            r = res[name]
            m = dict(rate=statistics.median(x["rate"] for x in r),
                     sp50=statistics.median(pct(x["sub"], .5) for x in r),
                     sp99=statistics.median(pct(x["sub"], .99) for x in r),
                     gp50=statistics.median(pct(x["get"], .5) for x in r),
                     gp99=statistics.median(pct(x["get"], .99) for x in r),
                     cpu=statistics.median(x["cpu"] for x in r),
                     rcpu=statistics.median(x["rcpu"] for x in r))
            med[name] = m
            print("%-9s %8.1f %8.2f ms %8.2f ms %8.2f ms %8.2f ms %9.2f ms %11.2f ms" % (
                name, m["rate"], 1e3 * m["sp50"], 1e3 * m["sp99"], 1e3 * m["gp50"],
                1e3 * m["gp99"], 1e3 * m["cpu"], 1e3 * m["rcpu"] if name != "spool" else 0))
        s = med["spool"]
        for name, _ in setups[1:]:
            r = med[name]
            print("%s/spool: jobs/s %.2f, POST p50 %.2f, GET p50 %.2f, mcfd CPU/job %.2f; "
                  "Redis adds %.2f ms of its own CPU per job" % (
                      name, r["rate"] / s["rate"], r["sp50"] / s["sp50"], r["gp50"] / s["gp50"],
                      r["cpu"] / s["cpu"], 1e3 * r["rcpu"]))
    finally:
        stop_all(procs, tmp)


if __name__ == "__main__":
    main()
