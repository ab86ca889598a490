#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""follow_lag.py - how late a follower on replica B sees the steps of a run
on replica A (two mcfd replicas sharing one redis-server, one worker each).

Each round submits one job and follows its SSE stream
(GET /v1/jobs/ID/events) on A and on B at once, from two threads that
stamp every progress event with time.perf_counter() as its bytes arrive.
Either replica's worker may take the job (one shared queue): the
runner's stream is fed from its own memory, so the other's stamp minus
the runner's, per step, is what following through Redis adds (the runner
is the consumer named in the job's record, host:pid:nonce). Also
reported: the done event's lag. Medians and p99 over all steps of all
rounds. Then --cancels rounds of a long job canceled on the replica that
does not run it (DELETE): the time from its 202 to the done event on the
runner's stream (the run stopped there).

  /usr/bin/python3 lab/bench/follow_lag.py [--mcfd build/mcfd] [--rounds 3]
      [--iterations 150] [--cancels 10] [--mesh tests/data/meshes/bunny.drc]
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import tempfile
import threading
import time
import urllib.request

from bench_store import http, start_mcfd, start_redis, stop_all   # this folder's

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MESH = os.path.join(ROOT, "tests", "data", "meshes", "bunny.drc")


def follow(url, jid, out):
    """SSE of job jid: out[step] = arrival time, out['done'] too."""
    with urllib.request.urlopen("%s/v1/jobs/%s/events" % (url, jid), timeout=120) as r:
        buf = b""
        while True:
            chunk = r.read1(65536)
            now = time.perf_counter()
            if not chunk:
                return
            buf += chunk
            while b"\n\n" in buf:
                ev, buf = buf.split(b"\n\n", 1)
                ev = ev.decode()
                kind = re.search(r"^event: (\w+)$", ev, re.M)
                data = re.search(r"^data: (.*)$", ev, re.M)
                if kind and kind.group(1) == "progress":
                    out.setdefault(json.loads(data.group(1))["step"], now)
                elif kind and kind.group(1) == "done":
                    out["done"] = now
                    return


def runner_of(rport, jid, procs):
    """Which of procs (Popen) runs job jid, from its record's consumer."""
    for _ in range(500):
        who = subprocess.run(["redis-cli", "-p", str(rport), "HGET", "mcfd:job:" + jid, "runner"],
                             capture_output=True, text=True).stdout
        for i, p in enumerate(procs):
            if ":%d:" % p.pid in who:
                return i
        time.sleep(0.01)
    raise SystemExit("no replica runs %s" % jid)


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mcfd", default=os.path.join(ROOT, "build", "mcfd"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--iterations", type=int, default=150)
    ap.add_argument("--mesh", default=MESH)
    ap.add_argument("--cancels", type=int, default=10)
    a = ap.parse_args()
    with open(a.mesh, "rb") as f:
        mesh = f.read()
    tmp = tempfile.mkdtemp(prefix="mcfd-follow-lag-")
    procs = []
    try:
        rd, rport = start_redis(tmp)
        procs.append(rd)
        store = "redis://127.0.0.1:%d" % rport
        (pa, ua), (pb, ub) = [start_mcfd(a.mcfd, tmp, n, "--store", store) for n in ("a", "b")]
        procs += [pa, pb]
        lags, done = [], []
        for _ in range(a.rounds):
            st, body, _ = http("POST", ua + "/v1/jobs?scheme=desbrun2&iterations=%d" % a.iterations, mesh)
            assert st == 202, st
            jid = json.loads(body)["id"]
            got = [{}, {}]
            ts = [threading.Thread(target=follow, args=(u, jid, g)) for u, g in zip((ua, ub), got)]
            for t in ts:
                t.start()
            r = runner_of(rport, jid, [pa, pb])   # while it runs
            for t in ts:
                t.join(180)
            ga, gb = got[r], got[1 - r]            # the runner's, the follower's
            steps = [k for k in ga if k != "done" and k in gb]
            assert len(steps) == a.iterations, (len(steps), a.iterations)
            lags += [gb[k] - ga[k] for k in steps]
            done.append(gb["done"] - ga["done"])
            http("DELETE", "%s/v1/jobs/%s" % (ua, jid))
        print("follow_lag: %d rounds of %s, %d steps each (%d step lags), the follower's SSE "
              "minus the runner's, "
              "%s, %d cores" % (a.rounds, os.path.basename(a.mesh), a.iterations, len(lags),
                                os.path.basename(a.mcfd), os.cpu_count()))
        print("step lag: median %.1f ms, p99 %.1f ms, max %.1f ms; done lag: median %.1f ms, max %.1f ms"
              % (1e3 * statistics.median(lags), 1e3 * pct(lags, .99), 1e3 * max(lags),
                 1e3 * statistics.median(done), 1e3 * max(done)))
        cancel = []
        for _ in range(a.cancels):
            st, body, _ = http("POST", ua + "/v1/jobs?scheme=desbrun2&iterations=100000", mesh)
            jid = json.loads(body)["id"]
            r = runner_of(rport, jid, [pa, pb])
            urun, uother = (ua, ub) if r == 0 else (ub, ua)
            got = {}
            t = threading.Thread(target=follow, args=(urun, jid, got))
            t.start()
            while len(got) < 3:               # running, a few steps in
                time.sleep(0.01)
            req = urllib.request.Request("%s/v1/jobs/%s" % (uother, jid), method="DELETE")
            with urllib.request.urlopen(req, timeout=60) as r:
                t0 = time.perf_counter()
                assert r.status == 202, r.status
            t.join(60)
            cancel.append(got["done"] - t0)
            http("DELETE", "%s/v1/jobs/%s" % (ua, jid))
        if cancel:
            print("cancel on the other replica to the run's end: median %.1f ms, max %.1f ms (%d runs)"
                  % (1e3 * statistics.median(cancel), 1e3 * max(cancel), len(cancel)))
    finally:
        stop_all(procs, tmp)


if __name__ == "__main__":
    main()
