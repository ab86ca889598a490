#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_upload_limits.py - uploads over --max-upload on the REST door
(issues 27 and 28): whatever their size and framing, the client hears a
413 ELIMIT as soon as the daemon can know, never a dropped connection
without a status, and nothing of the body stays on the spool. The bodies
are generated as they are sent (nothing of their size is kept in memory
or on disk) by a raw socket client that reads while it sends, as curl
does, and stops sending at the answer: its count of bytes sent bounds
what the daemon read.

--max-upload bounds a request's body: a raw mesh, or a multipart body's
mesh and target together (plus the parameters and the framing, at most
2 x 64 KiB + 1 MiB more).

- a 300 MB multipart body with Content-Length under the default
  --max-upload (256 MiB), with Expect: 100-continue (answered before the
  100, nothing sent) and without it (answered from the head while the
  client sends). Before: read whole (a mesh and a target of up to
  --max-upload each fit its head), then 413, 1.9 s; before that, 100
  Continue, then the connection dropped and no status (MHD: "Application
  reported internal error");
- a 300 MB raw body, the same;
- a chunked multipart body of 300 MB under --max-upload 8M: no
  Content-Length, so the limit is met on the way; answered at once, on the
  socket (libmicrohttpd 0.9.75 queues no answer in the middle of a body),
  then up to 16 MiB more discarded before the close. Before: answered
  only 16 MiB past the limit (28 MB sent);
- a multipart body within its declared length whose mesh and target
  together pass the limit: answered at the part that passes it.
"""
import json
import os
import select
import socket
import time
import urllib.request

from testlib import DATA, TMP, Daemon, run_tests

MB = 1000 * 1000
BOUNDARY = "mcfdtrust0123456789"


def multipart_parts(mesh_bytes):
    """(head, body generator, tail) of a multipart body whose mesh part
    holds mesh_bytes of OBJ-like text."""
    head = ("--%s\r\nContent-Disposition: form-data; name=\"mesh\"; filename=\"big.obj\"\r\n"
            "Content-Type: application/octet-stream\r\n\r\n" % BOUNDARY).encode()
    tail = ("\r\n--%s--\r\n" % BOUNDARY).encode()
    line = b"v 0.125 0.25 0.5\n" * 4096              # 69,632 bytes

    def body():
        left = mesh_bytes
        while left > 0:
            chunk = line[:min(len(line), left)]
            left -= len(chunk)
            yield chunk
    return head, body, tail


def send_upload(port, headers, pieces, chunked, total=None, expect=False):
    """Sends a POST /v1/jobs with headers, its body from pieces (an
    iterator of bytes), reading whenever the daemon has something to say.
    Returns (status, body bytes of the answer, bytes of body sent)."""
    s = socket.create_connection(("127.0.0.1", port), timeout=60)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 16)
    head = "POST /v1/jobs?scheme=desbrun2 HTTP/1.1\r\nHost: x\r\n" + \
        "".join("%s: %s\r\n" % kv for kv in headers)
    if chunked:
        head += "Transfer-Encoding: chunked\r\n"
    else:
        head += "Content-Length: %d\r\n" % total
    if expect:
        head += "Expect: 100-continue\r\n"
    s.sendall((head + "\r\n").encode())
    got, sent = b"", 0

    def answered():
        return b"\r\n\r\n" in got and not got.startswith(b"HTTP/1.1 100")

    if expect:                               # wait for 100 or the answer
        while b"\r\n\r\n" not in got:
            d = s.recv(65536)
            assert d, "closed before any answer"
            got += d
        if got.startswith(b"HTTP/1.1 100"):
            got = got[got.index(b"\r\n\r\n") + 4:]
    s.setblocking(False)
    try:
        for p in pieces:
            data = b"%x\r\n%s\r\n" % (len(p), p) if chunked else p
            view = memoryview(data)
            while view and not answered():   # never a byte past the answer
                r, w, _ = select.select([s], [s], [], 30)
                if r:
                    d = s.recv(65536)
                    if not d:
                        break
                    got += d
                    if got.startswith(b"HTTP/1.1 100") and b"\r\n\r\n" in got:
                        got = got[got.index(b"\r\n\r\n") + 4:]
                    if answered():
                        break
                if w:
                    n = s.send(view[:1 << 16])
                    view = view[n:]
                    sent += n
            if answered():
                break
        else:
            if chunked:
                s.sendall(b"0\r\n\r\n")
    except (BrokenPipeError, ConnectionResetError):
        pass                                 # read what was said before it
    s.setblocking(True)
    s.settimeout(30)
    try:
        while True:
            if answered():
                hdr, _, rest = got.partition(b"\r\n\r\n")
                m = [ln for ln in hdr.split(b"\r\n") if ln.lower().startswith(b"content-length:")]
                if m and len(rest) >= int(m[0].split(b":")[1]):
                    break
            d = s.recv(65536)
            if not d:
                break
            got += d
    except (ConnectionResetError, socket.timeout):
        pass
    s.close()
    if not got.startswith(b"HTTP/1.1 "):
        return None, got, sent
    hdr, _, rest = got.partition(b"\r\n\r\n")
    return int(hdr.split()[1]), rest, sent


def multipart_upload(port, mesh_bytes, chunked, expect):
    head, body, tail = multipart_parts(mesh_bytes)

    def pieces():
        yield head
        yield from body()
        yield tail
    total = len(head) + mesh_bytes + len(tail)
    return send_upload(port, [("Content-Type", "multipart/form-data; boundary=" + BOUNDARY)],
                       pieces(), chunked, total, expect)


def check_413(st, body, what):
    assert st == 413, "%s: status %r, %r" % (what, st, body[:300])
    prob = json.loads(body)
    assert prob["code"] == "ELIMIT" and "--max-upload" in prob["detail"], prob
    return prob["detail"]


def spool_leftovers(name):
    """What a refused upload could have left on the daemon's spool: job
    directories, temporary files."""
    root = os.path.join(TMP, name)
    jobs = os.path.join(root, "jobs")
    left = [j for j in os.listdir(jobs) if not j.startswith(".")] if os.path.isdir(jobs) else []
    for dp, _, fs in os.walk(root):
        left += [os.path.join(dp, f) for f in fs if f.endswith(".tmp")]
    return left


# What the daemon may read of a refused body is bounded by what the
# client sends before it reads the answer: the loopback sockets' buffers
# (the client's send buffer and the daemon's receive buffer, each up to a
# few MB as Linux tunes them) and the send loop's 64 KiB pieces. 32 MB is
# far below the 300 MB bodies and above any buffering measured (at most
# 10 MB past what the daemon had read when it answered).
BUFFERED = 32 * MB


def test_multipart_300mb_over_default_max_upload():
    d = Daemon("big")
    try:
        t0 = time.time()
        st, body, sent = multipart_upload(d.port, 300 * MB, chunked=False, expect=True)
        detail = check_413(st, body, "300 MB multipart, Expect: 100-continue")
        assert "Content-Length" in detail, detail  # from the head
        assert sent == 0, sent                     # before the 100
        print("    300 MB multipart with Content-Length, Expect: 100-continue: 413 from the "
              "head, %d bytes sent, %.2f s" % (sent, time.time() - t0))
        t0 = time.time()
        st, body, sent = multipart_upload(d.port, 300 * MB, chunked=False, expect=False)
        check_413(st, body, "300 MB multipart, sent before read")
        assert sent < BUFFERED, sent
        print("    the same sent before read: 413 from the head after %.1f MB sent, %.2f s"
              % (sent / MB, time.time() - t0))
        line = b"v 0 0 0\n" * 8192
        st, body, sent = send_upload(d.port, [("Content-Type", "application/octet-stream")],
                                     (line for _ in range(300 * MB // len(line))), False,
                                     300 * MB // len(line) * len(line))
        check_413(st, body, "300 MB raw body")
        assert sent < BUFFERED, sent
        assert spool_leftovers("big") == [], spool_leftovers("big")
        # the daemon goes on: a small upload is accepted (its job fails
        # later: "v" lines and no faces)
        st, body, _ = multipart_upload(d.port, 100, chunked=False, expect=False)
        assert st == 202, (st, body[:300])
    finally:
        d.stop()


def test_chunked_multipart_over_max_upload():
    d = Daemon("chunked", "--max-upload", "8M")
    try:
        t0 = time.time()
        st, body, sent = multipart_upload(d.port, 300 * MB, chunked=True, expect=False)
        check_413(st, body, "300 MB chunked multipart")
        assert sent < 8 * 1048576 + BUFFERED, sent   # cut at the limit
        print("    300 MB chunked multipart over --max-upload 8M: 413 after %.1f MB sent, "
              "%.2f s (before: 28 MB)" % (sent / MB, time.time() - t0))
        # a raw chunked body over it, as well
        line = b"v 0 0 0\n" * 8192
        st, body, sent = send_upload(d.port, [("Content-Type", "application/octet-stream")],
                                     (line for _ in range(300 * MB // len(line))), True)
        check_413(st, body, "300 MB chunked raw body")
        assert sent < 8 * 1048576 + BUFFERED, sent
        print("    300 MB chunked raw body: 413 after %.1f MB sent" % (sent / MB))
        # within its declared length (so past the head, which allows a
        # body of 8 MiB + 1.125 MiB), a mesh and a target of 4.5 MB each:
        # 413 at the target's part
        head, mesh, _ = multipart_parts(4500 * 1000)
        thead = ("\r\n--%s\r\nContent-Disposition: form-data; name=\"target\"; "
                 "filename=\"t.obj\"\r\n\r\n" % BOUNDARY).encode()
        tail = ("\r\n--%s--\r\n" % BOUNDARY).encode()

        def pieces():
            yield head
            yield from mesh()
            yield thead
            yield from mesh()
            yield tail
        total = len(head) + len(thead) + len(tail) + 9 * MB
        st, body, sent = send_upload(
            d.port, [("Content-Type", "multipart/form-data; boundary=" + BOUNDARY)],
            pieces(), False, total)
        detail = check_413(st, body, "a mesh and a target of 4.5 MB under 8M")
        assert "target" in detail, detail
        print("    a 4.5 MB mesh and a 4.5 MB target under --max-upload 8M: 413 after %.1f MB "
              "sent (%s)" % (sent / MB, detail))
        assert spool_leftovers("chunked") == [], spool_leftovers("chunked")
    finally:
        d.stop()


def test_refused_at_decode_leaves_its_input_off_the_spool():
    """A job refused at decode (413 for its vertex count) never runs
    again: its input leaves the spool at once (before: kept until the
    result TTL, so 15 uploads of 265 MB filled the default 4G quota for an
    hour); its state and error stay."""
    d = Daemon("refused", "--max-vertices", "1000")
    try:
        with open(os.path.join(DATA, "meshes", "bunny.drc"), "rb") as f:
            mesh = f.read()                           # 96 kB, 34,834 vertices
        st, body, _ = send_upload(d.port, [("Content-Type", "application/octet-stream")],
                                  iter([mesh]), False, len(mesh))
        assert st == 202, (st, body[:300])
        jid = json.loads(body)["id"]
        end, job = time.time() + 60, {}
        while time.time() < end and job.get("status") not in ("failed", "succeeded"):
            time.sleep(0.1)
            with urllib.request.urlopen("%s/v1/jobs/%s" % (d.url, jid), timeout=30) as r:
                job = json.loads(r.read())
        assert job["status"] == "failed" and job["error"]["code"] == "ELIMIT", job
        # emptied just after the outcome is published (svc_job.c: the
        # state is recorded first, so a crash in between cannot leave a
        # queued job without its input): a moment later, not at the TTL;
        # 10 s bounds that moment under any load
        inp = os.path.join(TMP, "refused", "jobs", jid, "input")
        end = time.time() + 10
        while os.path.getsize(inp) != 0 and time.time() < end:
            time.sleep(0.05)
        assert os.path.getsize(inp) == 0, os.path.getsize(inp)
        assert os.path.getsize(os.path.join(TMP, "refused", "jobs", jid, "state.json")) > 0
        print("    a job refused at decode: its 96 kB input emptied at its end (before: "
              "kept until the result TTL)", flush=True)
    finally:
        d.stop()


if __name__ == "__main__":
    raise SystemExit(run_tests([test_multipart_300mb_over_default_max_upload,
                                test_chunked_multipart_over_max_upload,
                                test_refused_at_decode_leaves_its_input_off_the_spool]))
