#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_store_redis.py - mcfd with its jobs in Redis (--store redis://...),
end to end: a real redis-server (Debian's, installed by `make deps`) on a
free loopback port with its append-only file on, in a folder of its own,
and the real daemon, both stopped by the test whatever happens.

Checks: an async job's records, queue entry and result live in Redis and
the result is the bytes POST /smooth gives; Redis killed (-9): /readyz and
submissions answer 503 (Retry-After), and once Redis is back from its AOF
everything works again with what was acknowledged kept; a job running
while Redis is down succeeds once it is back; mcfd killed (-9)
while a job runs: the restarted mcfd finishes it under the same ID (after
MCFD_REDIS_CLAIM_IDLE, 3 s here, without heartbeat). With --blob-dir: the
mesh bytes are files in that directory, none in Redis, the result the
same bytes, DELETE removes the files; a missing directory stops mcfd at
start (a kill -9 taken over with the bytes in files: test_replicas.py). Several replicas on one store:
tests/test_replicas.py.
"""
import json
import os
import signal
import socket
import subprocess
import time
import urllib.error
import urllib.request

import testlib
from testlib import DATA, TMP, Daemon, run_tests, track

BUNNY = os.path.join(DATA, "meshes", "bunny.drc")
REDIS = {}
# a running job whose replica stopped heartbeating is taken over after 3 s
# (the least store_redis.c accepts; 30 s by default)
os.environ["MCFD_REDIS_CLAIM_IDLE"] = "3"


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def redis_start():
    d = os.path.join(TMP, "redis")
    os.makedirs(d, exist_ok=True)
    REDIS.setdefault("port", free_port())
    REDIS["p"] = track(subprocess.Popen(
        ["redis-server", "--port", str(REDIS["port"]), "--bind", "127.0.0.1", "--dir", d,
         "--appendonly", "yes", "--appendfsync", "always", "--save", "",
         "--logfile", os.path.join(d, "log"), "--daemonize", "no"],
        start_new_session=True))
    end = time.time() + 20
    while time.time() < end:
        if cli("PING") == "PONG":
            return
        time.sleep(0.05)
    raise AssertionError("redis-server did not answer within 20 s")


def redis_kill():
    os.killpg(REDIS["p"].pid, signal.SIGKILL)
    REDIS["p"].wait()


def cli(*args):
    r = subprocess.run(["redis-cli", "-p", str(REDIS["port"]), *args],
                       capture_output=True, text=True, timeout=10)
    return r.stdout.strip()


def store_url():
    return "redis://127.0.0.1:%d" % REDIS["port"]


def daemon(name, *flags):
    return Daemon(name, "--store", store_url(), "--workers", "1", *flags)


def http(method, url, body=None, headers=None):
    req = urllib.request.Request(url, data=body, method=method, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as e:
        return e.code, dict(e.headers), e.read()


def submit(d, query):
    with open(BUNNY, "rb") as f:
        mesh = f.read()
    st, _, body = http("POST", d.url + "/v1/jobs?" + query, mesh,
                       {"Content-Type": "application/octet-stream"})
    assert st == 202, (st, body[:300])
    return json.loads(body)["id"]


def wait_status(d, jid, want, timeout):
    end, last = time.time() + timeout, None
    while time.time() < end:
        st, _, body = http("GET", "%s/v1/jobs/%s" % (d.url, jid))
        if st == 200:
            last = json.loads(body)["status"]
            if last == want:
                return
        time.sleep(0.1)
    raise AssertionError("job %s: %s after %d s, not %s" % (jid, last, timeout, want))


def result_of(d, jid):
    """The job's result bytes (it succeeded: 200 and a mesh)."""
    st, _, res = http("GET", "%s/v1/jobs/%s/result" % (d.url, jid))
    assert st == 200 and len(res) > 1000, (st, len(res))
    return res


def smooth_sync(d, query):
    """POST /smooth of the bunny with query: the result bytes (200)."""
    with open(BUNNY, "rb") as f:
        st, _, body = http("POST", d.url + "/smooth?" + query, f.read(),
                           {"Content-Type": "application/octet-stream"})
    assert st == 200, (st, body[:300])
    return body


def test_jobs_live_in_redis():
    d = daemon("one")
    try:
        q = "scheme=desbrun2&iterations=5"
        jid = submit(d, q)
        assert cli("EXISTS", "mcfd:job:" + jid) == "1"
        assert cli("SISMEMBER", "mcfd:jobs", jid) == "1"
        wait_status(d, jid, "succeeded", 60)
        res = result_of(d, jid)
        sync = smooth_sync(d, q)
        assert res == sync, (len(res), len(sync))
        names = cli("KEYS", "mcfd:blob:%s:*" % jid).split()
        assert any(n.endswith(":input") for n in names), names
        assert any(":result." in n for n in names), names
        # acknowledged: the queue holds nothing of it
        assert cli("XLEN", "mcfd:queue") == "0"
        ttl = int(cli("PTTL", "mcfd:job:" + jid))
        assert ttl > 3600 * 1000, ttl            # above --result-ttl (1 h)
    finally:
        d.stop()


def test_redis_down_then_back():
    d = daemon("down")
    try:
        jid = submit(d, "scheme=desbrun2&iterations=2")
        wait_status(d, jid, "succeeded", 60)
        before = result_of(d, jid)
        redis_kill()
        st, _, body = http("GET", d.url + "/readyz")
        assert st == 503 and b"redis 127.0.0.1" in body, (st, body)
        with open(BUNNY, "rb") as f:
            st, hdr, body = http("POST", d.url + "/v1/jobs?scheme=desbrun2", f.read(),
                                 {"Content-Type": "application/octet-stream"})
        assert st == 503 and hdr.get("Retry-After"), (st, hdr, body[:300])
        redis_start()                        # the same folder: its AOF
        end = time.time() + 15               # rds's backoff is at most 2 s
        while http("GET", d.url + "/readyz")[0] != 200:
            assert time.time() < end, "/readyz stayed red with Redis back"
            time.sleep(0.1)
        assert result_of(d, jid) == before
        jid2 = submit(d, "scheme=desbrun2&iterations=2")
        wait_status(d, jid2, "succeeded", 60)
    finally:
        d.stop()


def test_redis_down_while_a_job_runs():
    """A running job keeps its result until Redis is back (its writes are
    retried for about 37 s: svc__retry's backoff) and succeeds."""
    d = daemon("during")
    try:
        jid = submit(d, "scheme=desbrun2&iterations=10")   # about 1.5 s
        wait_status(d, jid, "running", 30)
        redis_kill()
        # Redis stays down until the run has tried to write and is waiting
        # (its log says "; try "): 4 s of sleep was not always enough under
        # ASan on a loaded machine; 120 s is a guard against a hang
        end = time.time() + 120
        while True:
            with open(d.logpath, "rb") as f:
                if b"; try " in f.read():
                    break
            assert time.time() < end, "no write waited for Redis in 120 s"
            time.sleep(0.2)
        redis_start()
        wait_status(d, jid, "succeeded", 90)
        result_of(d, jid)
    finally:
        d.stop()


def test_result_over_proto_max_bulk_len_fails():
    """A result larger than Redis takes in one argument (proto-max-bulk-len,
    1 MiB here, its least; 512 MiB by default) fails the job, saying why,
    once: never parked and run again."""
    cli("CONFIG", "SET", "proto-max-bulk-len", "1mb")
    d = daemon("big")
    try:
        # bunny as OBJ text: about 3 MB, the 96 kB input fits
        jid = submit(d, "scheme=desbrun2&iterations=1&format=obj")
        wait_status(d, jid, "failed", 60)
        time.sleep(3)                        # past a park's first 2 s delay
        st, _, body = http("GET", "%s/v1/jobs/%s" % (d.url, jid))
        job = json.loads(body)
        assert st == 200 and job["status"] == "failed", (st, job)
        detail = job["error"]["detail"]
        assert "proto-max-bulk-len" in detail and "result.obj" in detail, job
        assert cli("HGET", "mcfd:job:" + jid, "runs") == "1"
        assert cli("XPENDING", "mcfd:queue", "workers")[:1] == "0", "not acknowledged"
        st, _, body = http("GET", d.url + "/metrics")
        assert b'mcfd_jobs_total{scheme="desbrun2",status="failed"} 1' in body
        # an input over it is refused at once: 413, not a storage error
        with open(os.path.join(DATA, "meshes", "knot1.obj"), "rb") as f:
            big = f.read() + b"#" * (1 << 20) + b"\n"
        st, _, body = http("POST", d.url + "/v1/jobs?scheme=desbrun2", big,
                           {"Content-Type": "application/octet-stream"})
        assert st == 413 and b"proto-max-bulk-len" in body, (st, body[:300])
    finally:
        d.stop()
        cli("CONFIG", "SET", "proto-max-bulk-len", "512mb")


def test_kill9_then_restart_finishes_the_job():
    d = daemon("crash")
    jid = submit(d, "scheme=desbrun2&iterations=60")
    wait_status(d, jid, "running", 30)
    d.kill()
    d = daemon("crash")                      # takes it over after 3 s
    try:
        wait_status(d, jid, "succeeded", 90)
        result_of(d, jid)
        with open(d.logpath, "rb") as f:     # the restart took it over
            assert b"taken over" in f.read()
    finally:
        d.stop()


def blob_files(d, jid):
    jd = os.path.join(d, "mcfd", jid)
    return sorted(os.listdir(jd)) if os.path.isdir(jd) else []


def test_blob_dir_holds_the_bytes():
    bd = os.path.join(TMP, "blobs")
    os.makedirs(bd, exist_ok=True)
    d = daemon("files", "--blob-dir", bd)
    try:
        q = "scheme=desbrun2&iterations=5"
        jid = submit(d, q)
        wait_status(d, jid, "succeeded", 60)
        res = result_of(d, jid)
        sync = smooth_sync(d, q)
        assert res == sync, (len(res), len(sync))
        assert cli("KEYS", "mcfd:blob:%s:*" % jid) == "", "bytes in Redis"
        files = blob_files(bd, jid)
        assert [n for n in files if n.startswith("input.")], files
        res_files = [n for n in files if n.startswith("result.")]
        assert len(res_files) == 1, files
        with open(os.path.join(bd, "mcfd", jid, res_files[0]), "rb") as f:
            assert f.read() == res
        assert not [n for n in files if n.endswith(".tmp")], files
        # DELETE removes the job's files with its records
        st, _, _ = http("DELETE", "%s/v1/jobs/%s" % (d.url, jid))
        assert st in (200, 202, 204), st
        end = time.time() + 10
        while blob_files(bd, jid) and time.time() < end:
            time.sleep(0.1)
        assert blob_files(bd, jid) == [], blob_files(bd, jid)
    finally:
        d.stop()


def mount_small(path, size):
    """A tmpfs of size (mount's syntax) at path: True, or False when this
    machine cannot mount one (not root, no mount(8), a container without
    CAP_SYS_ADMIN)."""
    os.makedirs(path, exist_ok=True)
    if os.geteuid() != 0:
        return False
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=" + size, "tmpfs", path],
                       capture_output=True, timeout=30)
    return r.returncode == 0


def fill_leaving(filler, leave):
    """filler grown or cut so that about leave bytes stay free on its
    filesystem."""
    with open(filler, "ab") as f:
        sv = os.statvfs(filler)
        want = int(f.tell() + sv.f_bavail * sv.f_frsize - leave)
        if want < f.tell():
            f.truncate(max(0, want))
            return
        zeros = bytes(65536)
        while f.tell() < want:
            try:
                f.write(zeros[:min(len(zeros), want - f.tell())])
                f.flush()
            except OSError:           # full: as close as it gets
                break


def tree_files(root):
    return sorted(os.path.relpath(os.path.join(d, n), root)
                  for d, _, names in os.walk(root) for n in names)


def test_blob_dir_full():
    """--blob-dir on a full disk (a 1 MiB tmpfs): a submission with no
    room for its input is a 503 ESPOOLFULL with Retry-After that leaves
    no file and no record; a job whose result finds no room stays
    running, its write retried (docs/scale-out.md), with no partial or
    result file visible, and succeeds once space returns; the replica
    takes new jobs again."""
    bd = os.path.join(TMP, "fullblobs")
    if not mount_small(bd, "1m"):
        raise testlib.SkipTest("test_blob_dir_full", "cannot mount a small tmpfs here "
                               "(needs root and mount(8))")
    filler = os.path.join(bd, "filler")
    d = None
    try:
        d = daemon("blobfull", "--blob-dir", bd)
        q = "scheme=desbrun2&iterations=40"
        with open(BUNNY, "rb") as f:
            mesh = f.read()                  # 96 kB
        jobs = cli("SCARD", "mcfd:jobs")
        # no room for the input
        fill_leaving(filler, 40e3)
        st, hdr, body = http("POST", d.url + "/v1/jobs?" + q, mesh,
                             {"Content-Type": "application/octet-stream"})
        assert st == 503, (st, body[:300])
        prob = json.loads(body)
        assert prob["code"] == "ESPOOLFULL" and "no room" in prob["detail"], prob
        assert bd in prob["detail"], prob           # it names the directory
        assert int(hdr["Retry-After"]) > 0, hdr
        assert tree_files(bd) == ["filler"], tree_files(bd)
        assert os.listdir(os.path.join(bd, "mcfd")) == [], os.listdir(os.path.join(bd, "mcfd"))
        assert cli("SCARD", "mcfd:jobs") == jobs
        # room for the input, not for the result: retried, nothing shown
        fill_leaving(filler, 130e3)
        jid = submit(d, q)
        end = time.time() + 60
        while time.time() < end and b"recording its outcome" not in open(d.logpath, "rb").read():
            time.sleep(0.1)
        assert b"recording its outcome" in open(d.logpath, "rb").read(), d.log_tail()
        st, _, body = http("GET", "%s/v1/jobs/%s" % (d.url, jid))
        assert st == 200 and json.loads(body)["status"] == "running", body[:300]
        files = tree_files(bd)
        assert not [n for n in files if "result." in n or n.endswith(".tmp")], files
        assert http("GET", "%s/v1/jobs/%s/result" % (d.url, jid))[0] != 200
        # space returns: the retry writes it, the job succeeds
        os.unlink(filler)
        wait_status(d, jid, "succeeded", 45)
        res = result_of(d, jid)
        assert smooth_sync(d, q) == res
        files = tree_files(bd)
        assert not [n for n in files if n.endswith(".tmp")], files
        assert len([n for n in blob_files(bd, jid) if n.startswith("result.")]) == 1, files
        wait_status(d, submit(d, q), "succeeded", 60)
        fds = "/proc/%d/fd" % d.p.pid               # no descriptor left open there
        assert not [n for n in os.listdir(fds) if os.readlink(os.path.join(fds, n)).startswith(bd)]
    finally:
        if d:
            d.stop()                       # exit 0: under ASan, no leak
        subprocess.run(["umount", bd], capture_output=True, timeout=30)


def test_blob_dir_missing_is_a_startup_error():
    r = subprocess.run([os.path.join(testlib.BUILD, "mcfd"), "--port", "0",
                        "--grpc-port", "off", "--store", store_url(),
                        "--blob-dir", os.path.join(TMP, "no", "such")],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode != 0, r
    assert "--blob-dir" in r.stderr and "No such file" in r.stderr, r.stderr


if __name__ == "__main__":
    raise SystemExit(run_tests(
        [test_jobs_live_in_redis, test_redis_down_then_back, test_redis_down_while_a_job_runs,
         test_result_over_proto_max_bulk_len_fails, test_kill9_then_restart_finishes_the_job,
         test_blob_dir_holds_the_bytes, test_blob_dir_full,
         test_blob_dir_missing_is_a_startup_error],
        setup=redis_start))
