#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_upload_limits.py - uploads over --max-upload on the REST door
(issue 28, item 6): whatever their size and framing, the client hears a
413 ELIMIT, never a dropped connection without a status. The bodies are
generated as they are sent (nothing of their size is kept in memory or on
disk) by a raw socket client that reads while it sends, as curl does.

- a 300 MB multipart body with Content-Length and Expect: 100-continue
  under the default --max-upload (256 MiB): its head is within what a
  multipart body may hold (a mesh and a target of up to --max-upload
  each), its mesh part is not. Before: 100 Continue, then the connection
  dropped 16 MiB past the mesh's limit, no status (MHD: "Application
  reported internal error");
- the same without Expect, as a client that sends before it reads;
- a chunked multipart body of 300 MB under --max-upload 8M: no
  Content-Length, so no bound but the stream's; before: dropped 16 MiB
  past the limit, no status.
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
            while view:
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


def test_multipart_300mb_over_default_max_upload():
    d = Daemon("big")
    try:
        t0 = time.time()
        st, body, sent = multipart_upload(d.port, 300 * MB, chunked=False, expect=True)
        check_413(st, body, "300 MB multipart, Expect: 100-continue")
        print("    300 MB multipart with Content-Length, Expect: 100-continue: 413 after "
              "%.0f MB sent, %.1f s" % (sent / MB, time.time() - t0))
        st, body, sent = multipart_upload(d.port, 300 * MB, chunked=False, expect=False)
        check_413(st, body, "300 MB multipart, sent before read")
        print("    the same sent before read: 413 after %.0f MB sent" % (sent / MB))
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
        assert sent < 100 * MB, sent       # cut early: the rest is never read
        print("    300 MB chunked multipart over --max-upload 8M: 413 after %.0f MB sent, "
              "%.1f s" % (sent / MB, time.time() - t0))
        # a raw chunked body over it, as well
        line = b"v 0 0 0\n" * 8192
        st, body, sent = send_upload(d.port, [("Content-Type", "application/octet-stream")],
                                     (line for _ in range(300 * MB // len(line))), True)
        check_413(st, body, "300 MB chunked raw body")
        assert sent < 100 * MB, sent
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
        inp = os.path.join(TMP, "refused", "jobs", jid, "input")
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
