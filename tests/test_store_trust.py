#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_store_trust.py - mcfd trusts nothing of the Redis it does not own
(issue 28): a real redis-server (Debian's, `make deps`) on a free loopback
port, misconfigured or tampered with by the test through redis-cli, and
the real daemon; both stopped by the test whatever happens.

Checks, one attack each (docs/scale-out.md, "What breaks these promises"):
- a Redis whose maxmemory-policy may evict mcfd's keys (anything but
  noeviction: every key of a job has a TTL, so volatile-* evict them too)
  stops mcfd at start, naming the policy, unless --redis-allow-eviction;
- at start mcfd says what a restart of this Redis loses (appendonly,
  save); a running job whose records vanish (Redis restarted without
  persistence) is logged as such, never as "another replica took it over";
- /readyz is 503 while Redis refuses writes (noeviction, maxmemory full),
  200 again once it takes them;
- a job that cannot be queued (the queue key replaced by a string) is not
  acknowledged: 503 with Retry-After, no record left; once the key is
  repaired, jobs run again;
- a queued job whose request record is garbage is quarantined, logged and
  counted, and leaves the queue (before: it vanished, 404, 0 log lines).
"""
import json
import os
import re
import signal
import socket
import subprocess
import time

import testlib
from testlib import DATA, TMP, Daemon, run_tests, track
from test_store_redis import http, wait_status

BUNNY = os.path.join(DATA, "meshes", "bunny.drc")
REDIS = {}
# a running job whose replica stopped heartbeating is taken over after 3 s
os.environ["MCFD_REDIS_CLAIM_IDLE"] = "3"


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def redis_start(name="redis", persist=True):
    """A redis-server on loopback; persist: AOF with appendfsync always
    (the deployments' setting), else neither AOF nor snapshots."""
    d = os.path.join(TMP, name)
    os.makedirs(d, exist_ok=True)
    port = REDIS.setdefault(name + ".port", free_port())
    keep = (["--appendonly", "yes", "--appendfsync", "always"] if persist
            else ["--appendonly", "no"])
    REDIS[name] = track(subprocess.Popen(
        ["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--dir", d,
         *keep, "--save", "", "--logfile", os.path.join(d, "log"), "--daemonize", "no"],
        start_new_session=True))
    end = time.time() + 20
    while time.time() < end:
        if cli("PING", port=port) == "PONG":
            return port
        time.sleep(0.05)
    raise AssertionError("redis-server did not answer within 20 s")


def redis_kill(name="redis"):
    os.killpg(REDIS[name].pid, signal.SIGKILL)
    REDIS[name].wait()


def cli(*args, port=None):
    r = subprocess.run(["redis-cli", "-p", str(port or REDIS["redis.port"]), *args],
                       capture_output=True, text=True, timeout=10)
    return r.stdout.strip()


def url_of(port=None):
    return "redis://127.0.0.1:%d" % (port or REDIS["redis.port"])


def daemon(name, *flags, port=None):
    return Daemon(name, "--store", url_of(port), "--workers", "1", *flags)


def post_job(d, query):
    with open(BUNNY, "rb") as f:
        return http("POST", d.url + "/v1/jobs?" + query, f.read(),
                    {"Content-Type": "application/octet-stream"})


def submit(d, query):
    st, _, body = post_job(d, query)
    assert st == 202, (st, body[:300])
    return json.loads(body)["id"]


def wait_log(d, pattern, timeout):
    """The daemon's log once it matches pattern (bytes regex)."""
    end = time.time() + timeout
    while time.time() < end:
        with open(d.logpath, "rb") as f:
            log = f.read()
        if re.search(pattern, log):
            return log
        time.sleep(0.1)
    raise AssertionError("no %r in the log within %d s: %s" % (pattern, timeout, d.log_tail()))


def metric(d, name):
    st, _, body = http("GET", d.url + "/metrics")
    assert st == 200, st
    m = re.search(rb"^" + re.escape(name.encode()) + rb" (\S+)$", body, re.M)
    return float(m.group(1)) if m else 0.0


def start_fails(*flags, timeout=15):
    """mcfd with flags: its exit status and stderr, or an AssertionError
    when it starts (prints its listening line) instead of stopping."""
    p = track(subprocess.Popen(
        [os.path.join(testlib.BUILD, "mcfd"), "--bind", "127.0.0.1", "--port", "0",
         "--grpc-port", "off", "--spool", os.path.join(TMP, "refused"), *flags],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True))
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        raise AssertionError("mcfd started (%s) instead of refusing: %s" % (out.strip(), err[-600:]))
    return p.returncode, err


def test_evicting_redis_is_refused():
    """Before: mcfd read proto-max-bulk-len at start, not the eviction
    policy, and on allkeys-lru accepted jobs that failed or became 404."""
    try:
        for policy in ("allkeys-lru", "volatile-ttl"):
            assert cli("CONFIG", "SET", "maxmemory-policy", policy) == "OK"
            rc, err = start_fails("--store", url_of())
            assert rc != 0, rc
            assert "maxmemory-policy" in err and policy in err, err
            assert "--redis-allow-eviction" in err, err       # says the way out
            print("    maxmemory-policy %s: mcfd stops at start, exit %d (before: started)"
                  % (policy, rc), flush=True)
        # the explicit flag: it starts, and says what it risks
        d = daemon("evict", "--redis-allow-eviction")
        try:
            log = wait_log(d, rb"maxmemory-policy volatile-ttl", 10)
            assert b"evict" in log, log[-600:]
            wait_status(d, submit(d, "scheme=desbrun2&iterations=1"), "succeeded", 60)
        finally:
            d.stop()
    finally:
        cli("CONFIG", "SET", "maxmemory-policy", "noeviction")


def test_what_a_restart_loses():
    """A Redis without persistence: mcfd says at start that a restart loses
    every job; a job running when that happens is logged as lost from the
    store, not as taken over by another replica (before: "another replica
    took it over" when nothing did). With AOF + appendfsync always it says
    a restart keeps them."""
    d = daemon("aof")
    try:
        log = wait_log(d, rb"appendonly yes", 10)
        assert b"appendfsync always" in log, log[-800:]
    finally:
        d.stop()
    port = redis_start("bare", persist=False)
    d = daemon("bare", port=port)
    try:
        log = wait_log(d, rb"appendonly no", 10)
        # (JSON-escaped in the log: save "")
        assert rb'save \"\"' in log and b"a restart of this Redis loses" in log, log[-800:]
        jid = submit(d, "scheme=desbrun2&iterations=80")
        wait_status(d, jid, "running", 30)
        redis_kill("bare")
        redis_start("bare", persist=False)          # empty: nothing kept
        log = wait_log(d, rb"job " + jid.encode() + rb": its records are gone", 30)
        assert b"took it over" not in log and b"taken over" not in log, log[-1500:]
        print("    a running job's records lost in a Redis restart: logged as gone, 404 "
              "(before: \"another replica took it over\")", flush=True)
        # the client is told the same: no such job, on any replica
        end = time.time() + 30
        while http("GET", "%s/v1/jobs/%s" % (d.url, jid))[0] != 404:
            assert time.time() < end, http("GET", "%s/v1/jobs/%s" % (d.url, jid))
            time.sleep(0.2)
        # and the replica goes on: a new job runs
        wait_status(d, submit(d, "scheme=desbrun2&iterations=1"), "succeeded", 60)
    finally:
        d.stop()
        redis_kill("bare")


def test_readyz_while_redis_refuses_writes():
    """noeviction with maxmemory reached: every write is refused (OOM).
    Before: /readyz 200 to every probe while submissions got 503."""
    d = daemon("oom")
    try:
        assert http("GET", d.url + "/readyz")[0] == 200
        assert cli("CONFIG", "SET", "maxmemory", "1") == "OK"
        for _ in range(5):
            st, _, body = http("GET", d.url + "/readyz")
            assert st == 503, (st, body)
            assert b"refuses writes" in body and b"maxmemory" in body, body
            time.sleep(0.1)
        print("    /readyz while Redis refuses writes: 503 to 5 of 5 probes (before: 200 "
              "to 60 of 60)", flush=True)
        st, hdr, body = post_job(d, "scheme=desbrun2&iterations=1")
        assert st == 503 and int(hdr["Retry-After"]) > 0, (st, hdr, body[:300])
        assert cli("CONFIG", "SET", "maxmemory", "0") == "OK"
        end = time.time() + 10
        while http("GET", d.url + "/readyz")[0] != 200:
            assert time.time() < end, "/readyz stayed 503 with Redis taking writes"
            time.sleep(0.1)
        wait_status(d, submit(d, "scheme=desbrun2&iterations=1"), "succeeded", 60)
    finally:
        cli("CONFIG", "SET", "maxmemory", "0")
        d.stop()


def test_unqueueable_job_is_not_acknowledged():
    """The queue key replaced by a string: before, 202 for a job never
    queued ("it runs after the next start") that stayed queued after the
    key was repaired."""
    d = daemon("wrongtype")
    try:
        jobs = cli("SCARD", "mcfd:jobs")
        keys = set(cli("KEYS", "mcfd:job:*").split())
        cli("DEL", "mcfd:queue")
        assert cli("SET", "mcfd:queue", "not a stream") == "OK"
        st, hdr, body = post_job(d, "scheme=desbrun2&iterations=1")
        assert st == 503 and int(hdr["Retry-After"]) > 0, (st, hdr, body[:300])
        prob = json.loads(body)
        assert "cannot queue" in prob["detail"] and "mcfd:queue" in prob["detail"], prob
        assert cli("SCARD", "mcfd:jobs") == jobs, "a record left behind"
        assert set(cli("KEYS", "mcfd:job:*").split()) == keys, "a record left behind"
        print("    a submission with mcfd:queue a string: 503, no record left (before: "
              "202 for a job never queued)", flush=True)
        st, _, body = http("GET", d.url + "/readyz")
        assert st == 503 and b"mcfd:queue" in body, (st, body)
        cli("DEL", "mcfd:queue")                # repaired: jobs run again
        end = time.time() + 10
        while http("GET", d.url + "/readyz")[0] != 200:
            assert time.time() < end, "/readyz stayed 503 after the repair"
            time.sleep(0.1)
        wait_status(d, submit(d, "scheme=desbrun2&iterations=1"), "succeeded", 60)
    finally:
        cli("DEL", "mcfd:queue")
        d.stop()


def test_garbage_request_record_is_quarantined():
    """A job queued by one replica whose request record is garbage when
    another replica takes it: before, it vanished (404 on every replica,
    acknowledged, 0 log lines)."""
    a = daemon("garbage-a")
    first = submit(a, "scheme=desbrun2&iterations=80")   # holds a's worker
    wait_status(a, first, "running", 30)
    jid = submit(a, "scheme=desbrun2&iterations=1")      # queued behind it
    a.kill()
    assert cli("HSET", "mcfd:job:" + jid, "b:request.json", "{not json") == "0"
    b = daemon("garbage-b")
    try:
        log = wait_log(b, rb"job " + jid.encode() + rb".*quarantine", 30)
        assert b"request.json" in log, log[-800:]
        assert metric(b, "mcfd_spool_quarantined_total") == 1
        assert cli("EXISTS", "mcfd:quarantine:mcfd:job:" + jid) == "1"
        assert cli("SISMEMBER", "mcfd:jobs", jid) == "0"
        entries = cli("XRANGE", "mcfd:queue", "-", "+")
        assert jid not in entries, entries                  # left the queue
        st, _, body = http("GET", "%s/v1/jobs/%s" % (b.url, jid))
        assert st == 404, (st, body)
        print("    a queued job with a garbage request.json: quarantined, logged, counted "
              "(before: 404, 0 log lines)", flush=True)
    finally:
        b.stop()


if __name__ == "__main__":
    raise SystemExit(run_tests(
        [test_evicting_redis_is_refused, test_what_a_restart_loses,
         test_readyz_while_redis_refuses_writes, test_unqueueable_job_is_not_acknowledged,
         test_garbage_request_record_is_quarantined],
        setup=redis_start))
