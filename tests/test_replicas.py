#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_replicas.py - several mcfd replicas sharing one Redis store (issue
22), end to end: a real redis-server on a free loopback port (AOF on, its
own folder: test_store_redis.py's) and up to three real daemons on it, all
stopped by the test whatever happens.

Checks: a job submitted to A is watched from B (SSE and gRPC WatchJob,
every step) and fetched from C, the bytes POST /smooth gives; a cancel
asked on B stops the run on A; kill -9 of the replica running a job:
another finishes it under the same ID, and a job whose replica stops in
each of its runs is failed with the reason; Redis restarted mid-run: the job
ends with one result; 32 clients spread over three replicas: every job
succeeds once (counted in Redis and in the replicas' /metrics), and the
same load on the local-spool default (one replica) too; Redis down: every
replica's /readyz and submissions answer 503, and all recovers when it
returns. A replica that stops heartbeating loses its jobs after 3 s here
(MCFD_REDIS_CLAIM_IDLE; 30 s by default), which keeps this file short.
"""
import json
import os
import re
import subprocess
import sys
import threading
import time

import test_store_redis as rs  # noqa: E402  (sets MCFD_REDIS_CLAIM_IDLE)
from testlib import TMP, Daemon, run_tests

from test_store_redis import BUNNY, cli, http, redis_kill, redis_start, result_of, submit, wait_status

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRPC_PROTO = "/usr/share/grpc-proto/grpc"


def stubs():
    """mcfd's gRPC stubs (Debian's protoc and gRPC plugin, as test_grpc.py)."""
    out = os.path.join(TMP, "stubs")
    if not os.path.isdir(out):
        os.mkdir(out)
        subprocess.check_call(["protoc", "--plugin=protoc-gen-grpc_python=/usr/bin/grpc_python_plugin",
                               "-I" + os.path.join(ROOT, "api"), "--python_out=" + out,
                               "--grpc_python_out=" + out, "mcfd.proto"])
        sys.path.insert(0, out)
    import grpc
    import mcfd_pb2
    import mcfd_pb2_grpc
    return grpc, mcfd_pb2, mcfd_pb2_grpc


def replicas(n, tag, workers=1, *flags):
    ds = []
    try:
        for i in range(n):
            ds.append(Daemon("%s%d" % (tag, i), "--store", rs.store_url(),
                             "--workers", str(workers), *flags))
        end = time.time() + 30          # connected to Redis: ready for jobs
        for d in ds:
            while http("GET", d.url + "/readyz")[0] != 200:
                assert time.time() < end, "%s: /readyz not 200 in 30 s" % d.url
                time.sleep(0.1)
    except BaseException:
        stop(ds)
        raise
    return ds


def stop(ds):
    for d in ds:
        if d.p.poll() is None:
            d.stop()


def succeeded_count(d):
    """mcfd_jobs_total of desbrun2 jobs that succeeded, in d's /metrics."""
    st, _, body = http("GET", d.url + "/metrics")
    assert st == 200
    m = re.search(rb'mcfd_jobs_total\{scheme="desbrun2",status="succeeded"\} (\d+)', body)
    return int(m.group(1)) if m else 0


def sse(d, jid):
    """The SSE stream of job jid from d, to its end: (progress steps, the
    done event's job)."""
    st, _, body = http("GET", "%s/v1/jobs/%s/events" % (d.url, jid))
    assert st == 200, (st, body[:300])
    steps, done = [], None
    for ev in body.decode().split("\n\n"):
        kind = re.search(r"^event: (\w+)$", ev, re.M)
        data = re.search(r"^data: (.*)$", ev, re.M)
        if kind and kind.group(1) == "progress":
            steps.append(json.loads(data.group(1))["step"])
        elif kind and kind.group(1) == "done":
            done = json.loads(data.group(1))
    return steps, done


def test_submit_a_watch_b_fetch_c():
    grpc, pb, pbg = stubs()
    a, b, c = ds = replicas(3, "abc")
    try:
        q = "scheme=desbrun2&iterations=20"
        jid = submit(a, q)
        got = {}

        def watch():
            with grpc.insecure_channel("127.0.0.1:%d" % b.gport) as ch:
                parts = list(pbg.SmootherStub(ch).WatchJob(pb.WatchJobRequest(id=jid), timeout=90))
            got["steps"] = [p.progress.step for p in parts if p.WhichOneof("part") == "progress"]
            got["result"] = b"".join(p.result_chunk for p in parts
                                     if p.WhichOneof("part") == "result_chunk")
        t = threading.Thread(target=watch)
        t.start()
        steps, done = sse(b, jid)
        t.join(120)
        assert steps == list(range(1, 21)), steps
        assert done and done["status"] == "succeeded", done
        assert got.get("steps") == list(range(1, 21)), got.get("steps")
        res = result_of(c, jid)
        assert got["result"] == res, (len(got["result"]), len(res))
        with open(BUNNY, "rb") as f:
            st, _, sync = http("POST", a.url + "/smooth?" + q, f.read(),
                               {"Content-Type": "application/octet-stream"})
        assert st == 200 and sync == res
        # deleted on C: gone on A and B too
        assert http("DELETE", "%s/v1/jobs/%s" % (c.url, jid))[0] in (200, 204)
        for d in ds:
            assert http("GET", "%s/v1/jobs/%s" % (d.url, jid))[0] == 404
    finally:
        stop(ds)


def test_cancel_on_b_stops_the_run_on_a():
    a, b = ds = replicas(2, "cancel")
    try:
        jid = submit(a, "scheme=desbrun2&iterations=50000")      # minutes
        wait_status(b, jid, "running", 30)
        st, _, body = http("DELETE", "%s/v1/jobs/%s" % (b.url, jid))
        assert st == 202, (st, body[:300])
        for d in ds:                       # the runner's sweep sees it
            wait_status(d, jid, "canceled", 15)
        # the worker is free again
        jid2 = submit(b, "scheme=desbrun2&iterations=2")
        wait_status(a, jid2, "succeeded", 60)
    finally:
        stop(ds)


def kill_runner(ds, query):
    """A job submitted with query, killed (-9) with the replica whose
    consumer runs it (host:pid:nonce in its record): (its id, the replica
    left)."""
    jid = submit(ds[0], query)
    wait_status(ds[1], jid, "running", 30)
    end = time.time() + 30
    while True:
        who = cli("HGET", "mcfd:job:" + jid, "runner")
        dead = [d for d in ds if ":%d:" % d.p.pid in who]
        if dead or time.time() > end:
            break
        time.sleep(0.1)
    assert len(dead) == 1, "no replica runs %s (runner %r)" % (jid, who)
    dead[0].kill()
    return jid, [d for d in ds if d is not dead[0]][0]


def test_kill9_of_the_runner():
    ds = replicas(2, "kill")
    try:
        jid, alive = kill_runner(ds, "scheme=desbrun2&iterations=60")
        wait_status(alive, jid, "succeeded", 90)
        result_of(alive, jid)
        assert cli("HGET", "mcfd:job:" + jid, "runs") == "2"
        with open(alive.logpath, "rb") as f:
            assert b"taken over" in f.read()
    finally:
        stop(ds)


def test_dead_letter_is_failed():
    """A job whose replica stops during each of its runs (here one:
    MCFD_REDIS_MAX_RUNS=1) is written failed with the reason, not run."""
    os.environ["MCFD_REDIS_MAX_RUNS"] = "1"
    try:
        ds = replicas(2, "dead")
    finally:
        del os.environ["MCFD_REDIS_MAX_RUNS"]
    try:
        jid, alive = kill_runner(ds, "scheme=desbrun2&iterations=50000")
        wait_status(alive, jid, "failed", 30)
        st, _, body = http("GET", "%s/v1/jobs/%s" % (alive.url, jid))
        assert b"replica running it stopped" in body, body[:500]
        assert cli("XLEN", "mcfd:dead") == "1"
    finally:
        stop(ds)


def test_redis_restart_mid_run():
    """Redis killed and started again while A runs a job that B's SSE
    follows (B's follower thread, blocked in XREAD, reconnects): B's
    stream still carries every step in order and ends succeeded."""
    ds = replicas(2, "rr")
    try:
        jid = submit(ds[0], "scheme=desbrun2&iterations=60")
        got = {}
        t = threading.Thread(target=lambda: got.update(zip(("steps", "done"), sse(ds[1], jid))))
        t.start()
        wait_status(ds[1], jid, "running", 30)
        end = time.time() + 30                 # B's stream is open before Redis goes
        while b"mcfd_followers 1" not in http("GET", ds[1].url + "/metrics")[2] and time.time() < end:
            time.sleep(0.05)
        redis_kill()
        time.sleep(1)
        redis_start()                      # the same folder: its AOF
        for d in ds:
            wait_status(d, jid, "succeeded", 90)
        t.join(60)
        assert got.get("steps") == list(range(1, 61)), got.get("steps")
        assert got["done"]["status"] == "succeeded", got["done"]
        assert result_of(ds[0], jid) == result_of(ds[1], jid)
        names = cli("KEYS", "mcfd:blob:%s:result.*" % jid).split()
        assert len(names) == 1, names
    finally:
        stop(ds)


def load(ds, n=32):
    """n clients at once, client i submitting to ds[i % len], watching from
    the next and fetching from the one after: their job IDs (each job
    succeeded with the same bytes)."""
    ids, results, errors = [None] * n, [None] * n, []

    def client(i):
        try:
            k = len(ds)
            ids[i] = submit(ds[i % k], "scheme=desbrun2&iterations=2")
            # a guard against a hang, not a speed bound: 32 jobs on one
            # replica's two workers under ASan on a loaded machine took
            # over 120 s
            wait_status(ds[(i + 1) % k], ids[i], "succeeded", 600)
            results[i] = result_of(ds[(i + 2) % k], ids[i])
        except BaseException as e:  # noqa: BLE001 (reported below)
            errors.append("client %d: %r" % (i, e))
    ts = [threading.Thread(target=client, args=(i,)) for i in range(n)]
    for t in ts:
        t.start()
    for t in ts:
        t.join(660)
    assert not errors, errors[:3]
    assert len(set(ids)) == n and len(set(results)) == 1
    return ids


def test_32_clients_over_three_replicas():
    ds = replicas(3, "many")
    try:
        before = sum(succeeded_count(d) for d in ds)
        ids = load(ds)
        # counted once over the replicas' /metrics, run once in Redis, one
        # result each, nothing left in the queue
        assert sum(succeeded_count(d) for d in ds) - before == len(ids)
        for jid in ids:
            assert cli("HGET", "mcfd:job:" + jid, "runs") == "1", jid
            assert len(cli("KEYS", "mcfd:blob:%s:result.*" % jid).split()) == 1
        assert cli("XLEN", "mcfd:queue") == "0"
        assert cli("XPENDING", "mcfd:queue", "workers").split()[0] == "0"
    finally:
        stop(ds)


def test_32_clients_on_the_local_spool():
    d = Daemon("spool32", "--workers", "2")
    try:
        before = succeeded_count(d)
        ids = load([d])
        assert succeeded_count(d) - before == len(ids)
    finally:
        d.stop()


def test_redis_down_every_replica_503():
    grpc, pb, pbg = stubs()
    ds = replicas(2, "down")
    try:
        old = submit(ds[0], "scheme=desbrun2&iterations=1")
        wait_status(ds[0], old, "succeeded", 60)
        redis_kill()
        for d in ds:
            st, _, body = http("GET", d.url + "/readyz")
            assert st == 503, (st, body)
            with open(BUNNY, "rb") as f:
                st, hdr, body = http("POST", d.url + "/v1/jobs?scheme=desbrun2", f.read(),
                                     {"Content-Type": "application/octet-stream"})
            assert st == 503 and hdr.get("Retry-After"), (st, hdr, body[:300])
        # an ID nobody used: the store cannot say it does not exist, so 503,
        # not 404, on both doors
        jid = "0" * 32
        st, hdr, body = http("GET", "%s/v1/jobs/%s" % (ds[1].url, jid))
        assert st == 503 and hdr.get("Retry-After"), (st, hdr, body[:300])
        assert json.loads(body)["code"] == "ESPOOL", body[:300]
        with grpc.insecure_channel("127.0.0.1:%d" % ds[1].gport) as ch:
            try:
                pbg.SmootherStub(ch).GetJob(pb.GetJobRequest(id=jid), timeout=10)
                raise AssertionError("GetJob answered with Redis down")
            except grpc.RpcError as e:
                assert e.code() == grpc.StatusCode.UNAVAILABLE, (e.code(), e.details())
                md = dict(e.trailing_metadata() or ())
                assert md.get("retry-after-ms"), md
        # the job that ran: a replica answers from what it holds (the one
        # that ran it, or one that loaded its record meanwhile, which the
        # shared queue's timing decides: under ASan either replica may claim
        # it), 503 otherwise, never 404
        held = [http("GET", "%s/v1/jobs/%s" % (d.url, old))[0] for d in ds]
        assert 200 in held and set(held) <= {200, 503}, held
        redis_start()
        end = time.time() + 15             # rds's backoff is at most 2 s
        for d in ds:
            while http("GET", d.url + "/readyz")[0] != 200:
                assert time.time() < end, "/readyz stayed red with Redis back"
                time.sleep(0.1)
        jid = submit(ds[0], "scheme=desbrun2&iterations=2")
        wait_status(ds[1], jid, "succeeded", 60)
    finally:
        stop(ds)


def test_kill9_of_the_runner_with_blob_dir():
    """The mesh bytes in a directory the replicas share (--blob-dir): the
    runner killed (-9), the other finishes the job; one result file, the
    bytes fetched from either replica, none in Redis."""
    bd = os.path.join(TMP, "shared-blobs")
    os.makedirs(bd, exist_ok=True)
    ds = replicas(2, "killfiles", 1, "--blob-dir", bd)
    try:
        jid, alive = kill_runner(ds, "scheme=desbrun2&iterations=60")
        wait_status(alive, jid, "succeeded", 90)
        res = result_of(alive, jid)
        assert cli("HGET", "mcfd:job:" + jid, "runs") == "2"
        assert cli("KEYS", "mcfd:blob:%s:*" % jid) == ""
        jd = os.path.join(bd, "mcfd", jid)
        files = [n for n in os.listdir(jd) if n.startswith("result.")]
        assert len(files) == 1, os.listdir(jd)
        with open(os.path.join(jd, files[0]), "rb") as f:
            assert f.read() == res
    finally:
        stop(ds)


if __name__ == "__main__":
    raise SystemExit(run_tests(
        [test_submit_a_watch_b_fetch_c, test_cancel_on_b_stops_the_run_on_a,
         test_kill9_of_the_runner, test_kill9_of_the_runner_with_blob_dir,
         test_dead_letter_is_failed, test_redis_restart_mid_run,
         test_32_clients_over_three_replicas, test_32_clients_on_the_local_spool,
         test_redis_down_every_replica_503],
        setup=redis_start))
