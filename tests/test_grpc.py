#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_grpc.py - the gRPC door of mcfd, end to end: the real daemon, a real
gRPC client (Debian's python3-grpcio on /usr/bin/python3).

Every daemon runs `$MCF_BUILD/mcfd --bind 127.0.0.1 --port 0 --grpc-port 0`
on a spool under a temporary folder, in a process group of its own that is
SIGKILLed whatever happens (atexit, signals, a failing test). The stubs of
api/mcfd.proto, grpc.health.v1 and grpc.reflection.v1alpha are generated at
start with Debian's protoc and grpc_python_plugin into that folder (the health and reflection
protos from Debian's grpc-proto, each with its own -I, so no generated
`grpc/` package shadows grpcio's).

Output is cmocka's format ([ RUN ], [ OK ], [ PASSED ] N test(s), ...), which
`make test` counts; MCF_TEST_FILTER=name runs one test. The REST side of a
comparison is urllib on the same daemon: the same parameters must give the
same bytes through either door.
"""
import atexit
import json
import os
import resource
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import urllib.error
import urllib.request

import grpc

import h2raw  # tests/h2raw.py: a raw HTTP/2 client for the attacks
from noisy import noisy_obj  # tests/noisy.py: a noisy copy of a test mesh

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.abspath(os.environ.get("MCF_BUILD") or os.path.join(ROOT, "build"))
MCFD = os.path.join(BUILD, "mcfd")
DATA = os.environ.get("MCF_TESTDATA") or os.path.join(ROOT, "tests", "data")
GRPC_PROTO = "/usr/share/grpc-proto/grpc"
# Debian's protoc (3.21) with gRPC's Python plugin (protobuf-compiler-grpc):
# python3-grpc-tools 1.14 bundles protoc 3.5.1, which predates proto3
# `optional` (the typed Params need it to tell "unset" from 0).
PROTOC = ["protoc", "--plugin=protoc-gen-grpc_python=/usr/bin/grpc_python_plugin"]
TMP = tempfile.mkdtemp(prefix="mcfd-grpc-test-")
CHILDREN = []
LONG = dict(scheme="desbrun2", iterations=50000)   # runs for minutes: cancelled


def kill_children():
    for p in CHILDREN:
        if p.poll() is None:
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.wait()


def cleanup():
    kill_children()
    shutil.rmtree(TMP, ignore_errors=True)


atexit.register(cleanup)

# The connection floods open over a thousand sockets from this process: its
# own descriptor limit up to the hard one (and to 4096 when root may raise it)
_soft, _hard = resource.getrlimit(resource.RLIMIT_NOFILE)
for _want in ((max(_hard, 4096), max(_hard, 4096)), (_hard, _hard)):
    try:
        resource.setrlimit(resource.RLIMIT_NOFILE, _want)
        break
    except (ValueError, OSError):
        pass
for _s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
    signal.signal(_s, lambda s, f: (cleanup(), os._exit(128 + s)))


def gen_stubs():
    out = os.path.join(TMP, "stubs")
    os.mkdir(out)
    for inc, proto in ((os.path.join(ROOT, "api"), "mcfd.proto"),
                       (GRPC_PROTO + "/health/v1", "health.proto"),
                       (GRPC_PROTO + "/reflection/v1alpha", "reflection.proto")):
        subprocess.check_call(PROTOC + ["-I" + inc, "--python_out=" + out,
                                        "--grpc_python_out=" + out, proto])
    sys.path.insert(0, out)


gen_stubs()
import health_pb2  # noqa: E402
import health_pb2_grpc  # noqa: E402
import mcfd_pb2 as pb  # noqa: E402
import mcfd_pb2_grpc  # noqa: E402
import reflection_pb2  # noqa: E402
import reflection_pb2_grpc  # noqa: E402


def mesh(name):
    with open(os.path.join(DATA, "meshes", name), "rb") as f:
        return f.read()


# ------------------------------------------------------------------ daemon

class Daemon:
    """One mcfd on loopback with free ports; stop() checks a clean exit."""

    def __init__(self, name, *flags, spool=None, nofile=None):
        """nofile: RLIMIT_NOFILE (soft and hard) to start it with, as a
        container's (the image's is 1024)"""
        self.name = name
        self.spool = spool or os.path.join(TMP, name)
        self.logpath = os.path.join(TMP, name + ".log")
        self.flags = flags
        self.nofile = nofile
        self.start()

    def start(self):
        log = open(self.logpath, "ab")
        limit = self.nofile
        self.p = subprocess.Popen(
            [MCFD, "--bind", "127.0.0.1", "--port", "0", "--grpc-port", "0",
             "--spool", self.spool, *self.flags],
            stdout=subprocess.PIPE, stderr=log, start_new_session=True,
            preexec_fn=(lambda: resource.setrlimit(resource.RLIMIT_NOFILE, (limit, limit)))
            if limit else None)
        log.close()
        CHILDREN.append(self.p)
        lines = self._lines(2, 20)
        try:
            self.port = int(lines[0].split(":")[-1])
            assert lines[1].startswith("mcfd grpc listening on 127.0.0.1:"), lines
            self.gport = int(lines[1].split(":")[-1])
        except (IndexError, ValueError, AssertionError):
            self.kill()
            raise AssertionError("%s did not start: stdout %r, log %s" %
                                 (self.name, lines, self.log_tail()))
        self.channel = grpc.insecure_channel("127.0.0.1:%d" % self.gport)
        self.stub = mcfd_pb2_grpc.SmootherStub(self.channel)

    def _lines(self, n, timeout):
        buf, end = b"", time.time() + timeout
        fd = self.p.stdout.fileno()
        while buf.count(b"\n") < n and time.time() < end:
            r, _, _ = select.select([fd], [], [], 0.2)
            if r:
                chunk = os.read(fd, 4096)
                if not chunk:
                    break
                buf += chunk
        return buf.decode(errors="replace").splitlines()

    def log_tail(self):
        with open(self.logpath, "rb") as f:
            return f.read()[-2000:].decode(errors="replace")

    def stop(self, timeout=40):
        self.channel.close()
        self.p.send_signal(signal.SIGTERM)
        try:
            rc = self.p.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError("%s did not exit within %d s of SIGTERM" % (self.name, timeout))
        assert rc == 0, "%s exited with %d after SIGTERM: %s" % (self.name, rc, self.log_tail())

    def kill(self):
        try:
            os.killpg(self.p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.p.wait()
        if hasattr(self, "channel"):
            self.channel.close()

    def rest(self, method, path, body=None, headers=None):
        req = urllib.request.Request("http://127.0.0.1:%d%s" % (self.port, path), data=body,
                                     method=method, headers=headers or {})
        if body is not None:
            req.add_header("Content-Type", "application/octet-stream")
        try:
            with urllib.request.urlopen(req, timeout=120) as r:
                return r.status, dict(r.headers), r.read()
        except urllib.error.HTTPError as e:
            return e.code, dict(e.headers), e.read()

    def rest_json(self, path):
        st, _, b = self.rest("GET", path)
        assert st == 200, (path, st, b[:300])
        return json.loads(b)

    def wait_job(self, jid, want, timeout=60):
        end = time.time() + timeout
        while time.time() < end:
            j = self.rest_json("/v1/jobs/" + jid)
            if j["status"] in want:
                return j
            time.sleep(0.05)
        raise AssertionError("job %s is %s, not %s after %d s" % (jid, j["status"], want, timeout))


def query(params):
    return "&".join("%s=%s" % (k, v) for k, v in params.items())


def upload(data, params=None, chunk=65536, total=True, target=None, **header):
    h = pb.SmoothHeader(params=pb.Params(**(params or {})), **header)
    if total:
        h.total_size = len(data)
    yield pb.SmoothRequest(header=h)
    for i in range(0, len(data), chunk):
        yield pb.SmoothRequest(chunk=data[i:i + chunk])
    if target:
        for i in range(0, len(target), chunk):
            yield pb.SmoothRequest(target_chunk=target[i:i + chunk])


class Smoothed:
    def __init__(self, responses):
        self.progress, self.metrics, self.header, self.chunks = [], None, None, []
        for r in responses:
            part = r.WhichOneof("part")
            if part == "progress":
                assert self.metrics is None, "progress after metrics"
                self.progress.append(r.progress)
            elif part == "metrics":
                assert self.metrics is None, "two metrics messages"
                self.metrics = json.loads(r.metrics)
            elif part == "result_header":
                assert self.metrics is not None and self.header is None
                self.header = r.result_header
            else:
                assert self.header is not None, "a chunk before the result header"
                assert 0 < len(r.result_chunk) <= 65536, len(r.result_chunk)
                self.chunks.append(r.result_chunk)
        self.result = b"".join(self.chunks)
        assert self.header is not None, "no result"
        assert self.header.size == len(self.result), (self.header.size, len(self.result))


def smooth(d, data, params=None, metadata=None, timeout=120, **kw):
    return Smoothed(d.stub.Smooth(upload(data, params, **kw), metadata=metadata, timeout=timeout))


def expect_rpc_error(fn, code, *needles):
    try:
        fn()
    except grpc.RpcError as e:
        assert e.code() == code, "got %s (%s), want %s" % (e.code(), e.details(), code)
        for n in needles:
            assert n in e.details(), "%r not in %r" % (n, e.details())
        return e
    raise AssertionError("no error; want %s" % code)


def smooth_err(d, data, params, code, *needles, **kw):
    return expect_rpc_error(lambda: smooth(d, data, params, **kw), code, *needles)


def trailing(e, key):
    return dict(e.trailing_metadata() or ()).get(key)


def wait_first_progress(call):
    it = iter(call)
    r = next(it)
    assert r.WhichOneof("part") == "progress", r
    return it


def job_id_of(call):
    return dict(call.initial_metadata())["mcf-job-id"]


# ------------------------------------------------------------------- tests

MAIN = None


def test_smooth_draco_same_bytes_as_rest():
    """Smooth on Draco: the same bytes as REST /smooth, one progress per step."""
    data = mesh("bunny.drc")
    params = dict(scheme="desbrun2", iterations=6)
    g = smooth(MAIN, data, params, filename="bunny.drc")
    # measures=true: gRPC Smooth's metrics are measured (its reply carries
    # them), REST's plain /smooth only when asked
    st, hdr, body = MAIN.rest("POST", "/smooth?" + query(params) + "&measures=true", data)
    assert st == 200, (st, body[:300])
    assert g.result == body, "gRPC and REST results differ (%d vs %d bytes)" % (len(g.result), len(body))
    assert g.header.format == "draco" and g.header.file_name == "result.drc", g.header
    assert [p.step for p in g.progress] == list(range(1, 7)), [p.step for p in g.progress]
    assert all(p.t > 0 and p.dt > 0 for p in g.progress)
    assert g.metrics["job"] == g.header.job_id
    assert g.metrics["input"]["path"] == "bunny.drc", g.metrics["input"]
    rest_metrics = MAIN.rest_json("/v1/jobs/%s/metrics" % hdr["X-Job-Id"])
    assert sorted(g.metrics) == sorted(rest_metrics), "metrics keys differ"
    assert g.metrics["output"]["volume"] == rest_metrics["output"]["volume"]


def test_smooth_obj_same_bytes_as_rest():
    """Smooth on OBJ with typed parameters (auto, booleans, enums, a list)."""
    data = mesh("sphere_cgal.obj")
    params = dict(scheme="taubin", iterations=9, boundary="free", rescale="volume",
                  normalize=False, fixed_vertices=[0, 5, 7])
    g = smooth(MAIN, data, params, output_format="ply")
    st, _, body = MAIN.rest("POST", "/smooth?scheme=taubin&iterations=9&boundary=free&"
                            "rescale=volume&normalize=false&fixed_vertices=0,5,7&format=ply", data)
    assert st == 200, (st, body[:300])
    assert g.result == body and g.header.format == "ply"
    assert len(g.progress) == 9
    p = g.metrics["params"]
    assert p["scheme"] == "taubin" and p["fixed_vertices"] == [0, 5, 7] and p["normalize"] is False
    # NumberOrAuto: dt auto with an explicit scheme, strength as a number
    g2 = smooth(MAIN, data, dict(scheme="euler", iterations=4, dt=pb.NumberOrAuto(auto=True)))
    st, _, body = MAIN.rest("POST", "/smooth?scheme=euler&iterations=4&dt=auto", data)
    assert g2.result == body and g2.metrics["params"]["dt"] == "auto"
    g3 = smooth(MAIN, data, dict(scheme="desbrun2", strength=pb.NumberOrAuto(number=0.5)))
    st, _, body = MAIN.rest("POST", "/smooth?scheme=desbrun2&strength=0.5", data)
    assert g3.result == body and len(g3.progress) == 10


def test_default_is_fairing():
    """Smooth without a scheme runs the fairing filter, as REST does: the
    same bytes, its metrics (noise estimate, SURE curve, guard)."""
    data = noisy_obj(os.path.join(DATA, "meshes", "sphere_cgal.obj"), 0.25, 1)
    g = smooth(MAIN, data, {})
    st, _, body = MAIN.rest("POST", "/smooth", data)
    assert st == 200, (st, body[:300])
    assert g.result == body, "gRPC and REST results differ"
    m = g.metrics
    assert m["scheme"] == "fairing" and m["params"]["scheme"] == "fairing", m["scheme"]
    f = m["flow"]
    assert 0.15 < f["noise"] < 0.3, f["noise"]
    assert f["sure"] and min(range(len(f["sure"])), key=f["sure"].__getitem__) == f["steps"] >= 1, f
    assert 0 <= f["guard_rounds"] <= 5
    assert len(g.progress) == len(f["sure"]) - 1, (len(g.progress), len(f["sure"]))
    assert all(not p.phase for p in g.progress), "milestones without phases=true"
    # asked for (SmoothHeader.phases): the core's milestones too, each
    # phase of the default request as it starts, their share never falling
    # and 1 at the output; the steps as before, the same result
    g2 = smooth(MAIN, data, {}, phases=True)
    assert g2.result == body
    work = [p for p in g2.progress if p.phase]
    steps = [p.step for p in g2.progress if not p.phase]
    assert steps == [p.step for p in g.progress], steps
    fr = [p.fraction for p in work]
    phases = {p.phase for p in work}
    assert fr == sorted(fr) and fr[-1] == 1.0 and 0 <= fr[0], fr
    assert {"spikes", "noise", "output"} <= phases, phases
    print("    the default request, phases=true: %d milestones (%s), %d steps"
          % (len(work), " ".join(sorted(phases)), len(steps)))


def gltf_file(name):
    with open(os.path.join(DATA, "gltf", name), "rb") as f:
        return f.read()


def assimp_counts(data, name):
    """Debian's assimp (a third-party reader) on the bytes: (vertices, faces)."""
    path = os.path.join(TMP, name)
    with open(path, "wb") as f:
        f.write(data)
    out = subprocess.run(["assimp", "info", path], capture_output=True, text=True)
    assert out.returncode == 0 and "ERROR" not in out.stdout, (name, out.stdout[-500:])
    got = {}
    for line in out.stdout.splitlines():
        k, _, v = line.partition(":")
        if k.strip() in ("Vertices", "Faces"):
            got[k.strip()] = int(v)
    return got["Vertices"], got["Faces"]


def test_gltf_both_doors():
    """GLB, .gltf and GLB+Draco through Smooth: the same bytes as REST, the
    scheme left to the default, the format field named or detected; assimp
    reads every answer."""
    for name, fmt, out_fmt, counts in (("sphere_2prims.glb", "glb", None, (966, 1670)),
                                       ("sphere_2prims.gltf", "gltf", "glb", (866, 1620)),
                                       ("car_draco.glb", None, None, (None, 1744))):
        data = gltf_file(name)
        kw = dict(filename=name)
        if fmt:
            kw["format"] = fmt
        if out_fmt:
            kw["output_format"] = out_fmt
        g = smooth(MAIN, data, dict(iterations=3), **kw)
        st, hdr, body = MAIN.rest("POST", "/smooth?iterations=3" +
                                  ("&format=" + out_fmt if out_fmt else ""), data)
        assert st == 200, (name, st, body[:300])
        assert g.result == body, "%s: gRPC and REST results differ" % name
        want = out_fmt or fmt or "glb"
        assert g.header.format == want and g.header.file_name == "result." + want, g.header
        assert hdr["Content-Type"] == {"glb": "model/gltf-binary",
                                       "gltf": "model/gltf+json"}[want], hdr
        v, f = assimp_counts(g.result, "grpc-" + name.replace(".gltf", ".glb"))
        assert f == counts[1] and (counts[0] is None or v == counts[0]), (name, v, f)
        assert g.metrics["input"]["format"] == (fmt or "glb"), g.metrics["input"]
    # Draco in, Draco out
    assert b'"KHR_draco_mesh_compression":{' in g.result
    # a named format must match the bytes
    smooth_err(MAIN, gltf_file("sphere_2prims.glb"), None, grpc.StatusCode.INVALID_ARGUMENT,
               "gltf", format="gltf")


def big_obj():
    """A 330 x 330 bumpy grid as OBJ text: 108,900 vertices, over 4 MiB."""
    n, lines = 330, []
    for i in range(n):
        for j in range(n):
            lines.append("v %.6f %.6f %.6f" % (i / n, j / n, 0.01 * (((i * 7 + j * 13) % 17) / 17.0)))
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j + 1
            lines.append("f %d %d %d" % (a, a + n, a + 1))
            lines.append("f %d %d %d" % (a + 1, a + n, a + n + 1))
    return ("\n".join(lines) + "\n").encode()


def test_large_mesh_in_chunks():
    """A mesh over 4 MiB in 64 KiB chunks (and again without total_size)."""
    data = big_obj()
    assert len(data) > 4 << 20, len(data)
    params = dict(scheme="desbrun2", iterations=1)
    g = smooth(MAIN, data, params)
    st, _, body = MAIN.rest("POST", "/smooth?" + query(params), data)
    assert st == 200 and g.result == body, (st, len(g.result), len(body))
    assert len(g.chunks) == (len(body) + 65535) // 65536
    g2 = smooth(MAIN, data, params, chunk=50000, total=False)
    assert g2.result == body


def test_invalid_argument_names_the_parameter():
    data = mesh("sphere_cgal.obj")
    e = smooth_err(MAIN, data, dict(dt=pb.NumberOrAuto(number=-1)), grpc.StatusCode.INVALID_ARGUMENT, "'dt'")
    st, _, body = MAIN.rest("POST", "/smooth?dt=-1", data)
    assert st == 400 and json.loads(body)["detail"] == e.details(), (body, e.details())
    assert trailing(e, "mcf-code") == "EINVAL", e.trailing_metadata()
    smooth_err(MAIN, data, dict(scheme="nope"), grpc.StatusCode.INVALID_ARGUMENT, "'scheme'")
    smooth_err(MAIN, data, dict(iterations=0), grpc.StatusCode.INVALID_ARGUMENT, "'iterations'")
    smooth_err(MAIN, data, dict(strength=pb.NumberOrAuto(auto=False)), grpc.StatusCode.INVALID_ARGUMENT,
               "'strength'")
    smooth_err(MAIN, data, dict(tol=0.01), grpc.StatusCode.INVALID_ARGUMENT, "tol")
    smooth_err(MAIN, data, None, grpc.StatusCode.INVALID_ARGUMENT, "'format'", output_format="xyz")
    smooth_err(MAIN, data, None, grpc.StatusCode.INVALID_ARGUMENT, "format", format="fbx")
    smooth_err(MAIN, data, None, grpc.StatusCode.INVALID_ARGUMENT, "draco", format="draco")
    # the stream's shape
    expect_rpc_error(lambda: list(MAIN.stub.Smooth(iter([pb.SmoothRequest(chunk=b"v 0 0 0\n")]))),
                     grpc.StatusCode.INVALID_ARGUMENT, "header")
    two = [pb.SmoothRequest(header=pb.SmoothHeader()), pb.SmoothRequest(header=pb.SmoothHeader())]
    expect_rpc_error(lambda: list(MAIN.stub.Smooth(iter(two))), grpc.StatusCode.INVALID_ARGUMENT, "second header")
    expect_rpc_error(lambda: list(MAIN.stub.Smooth(iter(two[:1]))), grpc.StatusCode.INVALID_ARGUMENT, "no mesh")
    smooth_err(MAIN, data[:1000], None, grpc.StatusCode.INVALID_ARGUMENT, "total_size",
               total=False, total_size=len(data))
    # bytes that are no mesh: the decoder's message, as REST's
    e = smooth_err(MAIN, b"v 1 2\nf 1 2 3\n", None, grpc.StatusCode.INVALID_ARGUMENT)
    st, _, body = MAIN.rest("POST", "/smooth", b"v 1 2\nf 1 2 3\n")
    assert json.loads(body)["detail"] == e.details(), (body, e.details())


def test_resource_exhausted_limits():
    data = mesh("sphere_cgal.obj")
    e = smooth_err(MAIN, data, None, grpc.StatusCode.RESOURCE_EXHAUSTED, "upload limit",
                   total=False, total_size=17 << 20)
    assert trailing(e, "mcf-code") == "ELIMIT"
    smooth_err(MAIN, data, None, grpc.StatusCode.RESOURCE_EXHAUSTED, "chunk limit", chunk=70000)
    # a message over the receive limit is refused by gRPC itself
    smooth_err(MAIN, data * 4, None, grpc.StatusCode.RESOURCE_EXHAUSTED, chunk=200000)
    # no total_size: refused when the bytes pass the limit, before any decode
    big = b"#" * (1 << 20)
    t0 = time.time()
    smooth_err(MAIN, big * 20, None, grpc.StatusCode.RESOURCE_EXHAUSTED, "upload limit", total=False)
    assert time.time() - t0 < 30
    # the mesh and a target share --max-upload (16M), as on REST: from
    # the declared sizes at the header, else at the chunk that passes it
    smooth_err(MAIN, data, None, grpc.StatusCode.RESOURCE_EXHAUSTED, "together", total=False,
               total_size=10 << 20, target_size=10 << 20)
    smooth_err(MAIN, big * 9, None, grpc.StatusCode.RESOURCE_EXHAUSTED, "together", total=False,
               target=big * 9)
    # a budget that needs the mesh: max_work through iterations
    e = smooth_err(MAIN, big_obj(), dict(iterations=100000), grpc.StatusCode.RESOURCE_EXHAUSTED,
                   "max_work")
    assert trailing(e, "mcf-code") == "ELIMIT"


def test_not_found_and_failed_precondition():
    for fn in (lambda: MAIN.stub.GetJob(pb.GetJobRequest(id="0" * 32)),
               lambda: MAIN.stub.CancelJob(pb.CancelJobRequest(id="0" * 32)),
               lambda: list(MAIN.stub.WatchJob(pb.WatchJobRequest(id="../../etc")))):
        e = expect_rpc_error(fn, grpc.StatusCode.NOT_FOUND, "no job")
        assert trailing(e, "mcf-code") == "ENOTFOUND"
    job = MAIN.stub.SubmitJob(upload(mesh("bunny.drc"), LONG))
    try:
        e = expect_rpc_error(lambda: list(MAIN.stub.WatchJob(pb.WatchJobRequest(id=job.id, no_wait=True))),
                             grpc.StatusCode.FAILED_PRECONDITION, "no result yet")
        st, _, _ = MAIN.rest("GET", "/v1/jobs/%s/result" % job.id)
        assert st == 409
    finally:
        MAIN.stub.CancelJob(pb.CancelJobRequest(id=job.id))


def test_cancel_job_and_cancelled():
    job = MAIN.stub.SubmitJob(upload(mesh("bunny.drc"), LONG))
    assert job.status in (pb.Job.QUEUED, pb.Job.RUNNING) and len(job.id) == 32
    call = MAIN.stub.WatchJob(pb.WatchJobRequest(id=job.id))
    c = MAIN.stub.CancelJob(pb.CancelJobRequest(id=job.id))
    assert c.id == job.id
    e = expect_rpc_error(lambda: list(call), grpc.StatusCode.CANCELLED)
    assert trailing(e, "mcf-code") == "ECANCELED", e.trailing_metadata()
    j = MAIN.stub.GetJob(pb.GetJobRequest(id=job.id))
    assert j.status == pb.Job.CANCELED and j.error.code == "ECANCELED"
    assert j.error.grpc_code == grpc.StatusCode.CANCELLED.value[0]
    assert MAIN.rest_json("/v1/jobs/" + job.id)["status"] == "canceled"


def test_deadline_cancels_the_job():
    # the deadline must leave room for the upload, the Draco sandbox and
    # the first step, which took over 2 s under ASan+UBSan on a loaded
    # two-core machine; LONG runs for minutes, so 20 s still ends in the
    # deadline whatever the machine
    call = MAIN.stub.Smooth(upload(mesh("bunny.drc"), LONG), timeout=20.0)
    it = wait_first_progress(call)
    jid = job_id_of(call)
    expect_rpc_error(lambda: list(it), grpc.StatusCode.DEADLINE_EXCEEDED)
    MAIN.wait_job(jid, ("canceled",), timeout=5)


def test_cancelled_call_frees_its_worker():
    d = Daemon("onewkr", "--workers", "1", "--queue", "4")
    try:
        call = d.stub.Smooth(upload(mesh("bunny.drc"), LONG))
        wait_first_progress(call)
        jid = job_id_of(call)
        assert d.rest_json("/v1/jobs/" + jid)["status"] == "running"
        call.cancel()
        t0 = time.time()
        g = smooth(d, mesh("sphere_cgal.obj"), dict(iterations=3))
        took = time.time() - t0
        # a worker still held by the cancelled run would hold the next job
        # for minutes (LONG): 60 s tells the two apart on a loaded machine
        assert len(g.progress) == 3 and took < 60, took
        assert d.rest_json("/v1/jobs/" + jid)["status"] == "canceled"
        print("    cancelled Smooth: the next job finished %.2f s later on the one worker" % took)
        d.stop()
    finally:
        d.kill()


def test_auth():
    tok = os.path.join(TMP, "token")
    with open(tok, "w") as f:
        f.write("s3cret-token-for-grpc\n")
    d = Daemon("auth", "--token-file", tok)
    try:
        data = mesh("sphere_cgal.obj")
        calls = [lambda md: smooth(d, data, dict(iterations=2), metadata=md),
                 lambda md: d.stub.SubmitJob(upload(data), metadata=md),
                 lambda md: d.stub.GetJob(pb.GetJobRequest(id="0" * 32), metadata=md),
                 lambda md: d.stub.CancelJob(pb.CancelJobRequest(id="0" * 32), metadata=md),
                 lambda md: list(d.stub.WatchJob(pb.WatchJobRequest(id="0" * 32), metadata=md)),
                 lambda md: d.stub.ListSchemes(pb.ListSchemesRequest(), metadata=md)]
        for fn in calls:
            for md in (None, [("authorization", "Bearer wrong")], [("authorization", "s3cret-token-for-grpc")],
                       [("authorization", "Bearer s3cret-token-for-grp")]):
                e = expect_rpc_error(lambda: fn(md), grpc.StatusCode.UNAUTHENTICATED, "authorization")
                assert trailing(e, "mcf-code") == "EAUTH"
        good = [("authorization", "Bearer s3cret-token-for-grpc")]
        g = smooth(d, data, dict(iterations=2), metadata=good)
        assert len(g.progress) == 2
        assert len(d.stub.ListSchemes(pb.ListSchemesRequest(), metadata=good).schemes) >= 13
        d.stop()
    finally:
        d.kill()


def test_health_and_drain():
    d = Daemon("drain", "--workers", "1", "--drain-timeout", "2s")
    try:
        h = health_pb2_grpc.HealthStub(d.channel)
        for svc in ("", "mcfd.v1.Smoother"):
            assert h.Check(health_pb2.HealthCheckRequest(service=svc)).status == \
                health_pb2.HealthCheckResponse.SERVING
        job = d.stub.SubmitJob(upload(mesh("bunny.drc"), LONG))
        d.wait_job(job.id, ("running",))
        d.p.send_signal(signal.SIGTERM)
        end, st = time.time() + 5, None
        while time.time() < end:
            st = h.Check(health_pb2.HealthCheckRequest(service="mcfd.v1.Smoother")).status
            if st == health_pb2.HealthCheckResponse.NOT_SERVING:
                break
            time.sleep(0.02)
        assert st == health_pb2.HealthCheckResponse.NOT_SERVING, st
        assert h.Check(health_pb2.HealthCheckRequest(service="")).status == \
            health_pb2.HealthCheckResponse.NOT_SERVING
        e = smooth_err(d, mesh("sphere_cgal.obj"), None, grpc.StatusCode.UNAVAILABLE, "shutting down")
        assert trailing(e, "retry-after-ms") is not None
        expect_rpc_error(lambda: d.stub.SubmitJob(upload(mesh("sphere_cgal.obj"))), grpc.StatusCode.UNAVAILABLE)
        # reads still answer while draining
        assert d.stub.GetJob(pb.GetJobRequest(id=job.id)).id == job.id
        assert d.p.wait(30) == 0, d.log_tail()
        # the checkpointed job is queued on disk and runs after a restart
        d.flags = ("--workers", "1")
        d.start()
        j = d.stub.GetJob(pb.GetJobRequest(id=job.id))
        assert j.status in (pb.Job.QUEUED, pb.Job.RUNNING), j.status
        d.stub.CancelJob(pb.CancelJobRequest(id=job.id))
        d.stop()
    finally:
        d.kill()


def test_reflection_and_list_schemes():
    r = reflection_pb2_grpc.ServerReflectionStub(MAIN.channel)
    resp = list(r.ServerReflectionInfo(iter([reflection_pb2.ServerReflectionRequest(list_services="")])))
    names = [s.name for s in resp[0].list_services_response.service]
    assert "mcfd.v1.Smoother" in names and "grpc.health.v1.Health" in names, names
    fd = list(r.ServerReflectionInfo(iter([reflection_pb2.ServerReflectionRequest(
        file_containing_symbol="mcfd.v1.Smoother")])))
    assert fd[0].file_descriptor_response.file_descriptor_proto, fd
    schemes = MAIN.stub.ListSchemes(pb.ListSchemesRequest()).schemes
    rest = MAIN.rest_json("/v1/schemes")["schemes"]
    assert [s.name for s in schemes] == [s["name"] for s in rest]
    assert [s.order for s in schemes] == [s["order"] for s in rest]


def test_jobs_visible_through_both_doors():
    data = mesh("bunny.drc")
    params = dict(scheme="ros2", iterations=5)
    # gRPC -> REST
    job = MAIN.stub.SubmitJob(upload(data, params))
    j = MAIN.wait_job(job.id, ("succeeded",))
    assert j["params"]["scheme"] == "ros2"
    st, _, rest_result = MAIN.rest("GET", "/v1/jobs/%s/result" % job.id)
    assert st == 200
    st, _, direct = MAIN.rest("POST", "/smooth?" + query(params), data)
    assert rest_result == direct
    g = MAIN.stub.GetJob(pb.GetJobRequest(id=job.id))
    assert g.status == pb.Job.SUCCEEDED and json.loads(g.metrics)["job"] == job.id
    assert g.progress.step == 5 and g.progress.fraction == 1 and g.finished
    # a SubmitJob without a target keeps no step log: no energy or volume
    # (REST null), where a measured job has the last step's
    assert not g.progress.HasField("energy") and not g.progress.HasField("volume")
    assert j["progress"]["energy"] is None and j["progress"]["volume"] is None
    st, _, body = MAIN.rest("POST", "/v1/jobs?measures=true&" + query(params), data)
    mid = json.loads(body)["id"]
    MAIN.wait_job(mid, ("succeeded",))
    gm = MAIN.stub.GetJob(pb.GetJobRequest(id=mid))
    assert gm.progress.HasField("energy") and gm.progress.energy > 0
    assert gm.progress.HasField("volume")
    # REST -> gRPC
    st, _, body = MAIN.rest("POST", "/v1/jobs?" + query(params), data)
    assert st == 202, (st, body[:300])
    rid = json.loads(body)["id"]
    w = Smoothed(MAIN.stub.WatchJob(pb.WatchJobRequest(id=rid)))
    assert w.result == direct and w.header.job_id == rid
    assert [p.step for p in w.progress] == [1, 2, 3, 4, 5]
    w2 = Smoothed(MAIN.stub.WatchJob(pb.WatchJobRequest(id=rid, from_step=4)))
    assert [p.step for p in w2.progress] == [4, 5] and w2.result == direct
    # a finished job streams at once (gRPC's buffer hint once held each
    # write until a flush: 209 ms for this)
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        Smoothed(MAIN.stub.WatchJob(pb.WatchJobRequest(id=rid)))
        times.append(time.perf_counter() - t0)
    times.sort()
    print("    WatchJob of a finished job: %.1f ms (median of 5)" % (times[2] * 1e3))
    assert times[2] < 0.1, times
    # a failed job: WatchJob ends with its error
    st, _, body = MAIN.rest("POST", "/v1/jobs", b"v 1 2 3\nf 1 2 9\n")
    fid = json.loads(body)["id"]
    MAIN.wait_job(fid, ("failed",))
    e = expect_rpc_error(lambda: list(MAIN.stub.WatchJob(pb.WatchJobRequest(id=fid))),
                         grpc.StatusCode.INVALID_ARGUMENT)
    assert MAIN.rest_json("/v1/jobs/" + fid)["error"]["detail"] == e.details()


def test_kill9_recovery():
    spool = os.path.join(TMP, "k9")
    d = Daemon("k9", "--workers", "1", "--queue", "4", spool=spool)
    try:
        data = mesh("bunny.drc")
        slow = d.stub.SubmitJob(upload(data, dict(scheme="desbrun2", iterations=3000)))
        quick = d.stub.SubmitJob(upload(data, dict(scheme="desbrun2", iterations=4)))
        d.wait_job(slow.id, ("running",))
        assert d.stub.GetJob(pb.GetJobRequest(id=quick.id)).status == pb.Job.QUEUED
        d.kill()
        d.start()
        # both are back under their IDs, in their order: the interrupted one
        # runs again (cancelled here to save time), then the queued one
        j = d.stub.GetJob(pb.GetJobRequest(id=slow.id))
        assert j.status in (pb.Job.QUEUED, pb.Job.RUNNING), j
        assert d.stub.GetJob(pb.GetJobRequest(id=quick.id)).status == pb.Job.QUEUED
        d.stub.CancelJob(pb.CancelJobRequest(id=slow.id))
        w = Smoothed(d.stub.WatchJob(pb.WatchJobRequest(id=quick.id), timeout=120))
        st, _, direct = MAIN.rest("POST", "/smooth?scheme=desbrun2&iterations=4", data)
        assert w.result == direct and len(w.progress) == 4
        assert d.rest_json("/v1/jobs/" + quick.id)["status"] == "succeeded"
        d.stop()
    finally:
        d.kill()


def test_32_concurrent_clients_short_queue():
    d = Daemon("busy", "--workers", "1", "--queue", "2")
    try:
        data = mesh("bunny.drc")
        params = dict(scheme="desbrun2", iterations=20)
        outcome, lock = [], threading.Lock()

        def client():
            try:
                g = smooth(d, data, params)
                r = ("ok", len(g.progress), g.result)
            except grpc.RpcError as e:
                r = (e.code(), trailing(e, "retry-after-ms"), trailing(e, "mcf-code"))
            with lock:
                outcome.append(r)

        ts = [threading.Thread(target=client) for _ in range(32)]
        for t in ts:
            t.start()
        for t in ts:
            t.join(180)
        assert len(outcome) == 32
        ok = [o for o in outcome if o[0] == "ok"]
        busy = [o for o in outcome if o[0] == grpc.StatusCode.RESOURCE_EXHAUSTED]
        assert len(ok) + len(busy) == 32, [o[:2] for o in outcome if o[0] != "ok"]
        assert len(ok) >= 3 and busy, (len(ok), len(busy))
        assert all(o[1] == 20 and o[2] == ok[0][2] for o in ok)
        assert all(o[2] == "EBUSY" and int(o[1]) > 0 for o in busy), busy[:3]
        print("    32 clients, 1 worker, queue 2: %d succeeded, %d RESOURCE_EXHAUSTED (retry-after-ms %s)"
              % (len(ok), len(busy), busy[0][1]))
        h = health_pb2_grpc.HealthStub(d.channel)
        assert h.Check(health_pb2.HealthCheckRequest()).status == health_pb2.HealthCheckResponse.SERVING
        assert len(smooth(d, data, dict(iterations=2)).progress) == 2
        # threads stay bounded after the burst: main, 1 worker, 2 HTTP
        # threads, the door's pump, and gRPC's own pollers and executor
        with open("/proc/%d/status" % d.p.pid) as f:
            threads = int([l for l in f if l.startswith("Threads:")][0].split()[1])
        print("    threads after the burst: %d" % threads)
        assert threads <= 24, threads
        st, _, m = d.rest("GET", "/metrics")
        m = m.decode()
        assert 'mcfd_grpc_calls_total{method="Smooth",code="OK"} %d' % (len(ok) + 1) in m, m
        assert 'mcfd_grpc_calls_total{method="Smooth",code="RESOURCE_EXHAUSTED"} %d' % len(busy) in m
        d.stop()
    finally:
        d.kill()


def test_streaming_call_caps():
    # --max-connections-per-ip bounds the streaming calls one address holds
    # (each upload may buffer up to --max-upload); SVC_FOLLOWERS_PER_JOB (64)
    # the followers of one job, counted across both doors
    d = Daemon("caps", "--workers", "1", "--queue", "4", "--max-connections-per-ip", "2")
    release = threading.Event()

    def held():                      # a header, then nothing until released
        yield pb.SmoothRequest(header=pb.SmoothHeader(params=pb.Params(iterations=2)))
        release.wait(30)

    try:
        calls = [d.stub.SubmitJob.future(held()) for _ in range(2)]
        time.sleep(0.5)              # both calls are in the daemon
        e = expect_rpc_error(lambda: d.stub.SubmitJob(upload(mesh("sphere_cgal.obj"))),
                             grpc.StatusCode.RESOURCE_EXHAUSTED, "--max-connections-per-ip 2")
        assert trailing(e, "mcf-code") == "EBUSY" and trailing(e, "retry-after-ms") == "1000"
        release.set()
        for c in calls:              # the held uploads end without a mesh
            expect_rpc_error(c.result, grpc.StatusCode.INVALID_ARGUMENT, "no mesh")
        # their places go when gRPC is done with the calls (OnDone), just
        # after their status reached us: a client that retries after
        # retry-after-ms (1 s) gets in (under ASan it came back EBUSY at once)
        for attempt in range(3):
            try:
                job = d.stub.SubmitJob(upload(mesh("sphere_cgal.obj"), dict(iterations=2)))
                break
            except grpc.RpcError as e:
                if e.code() != grpc.StatusCode.RESOURCE_EXHAUSTED or attempt == 2:
                    raise
                time.sleep(1.0)
        d.wait_job(job.id, ("succeeded",))
        d.stop()
    finally:
        release.set()
        d.kill()
    d = Daemon("followers", "--workers", "1", "--max-connections-per-ip", "0")
    try:
        job = d.stub.SubmitJob(upload(mesh("bunny.drc"), LONG))
        watchers = [d.stub.WatchJob(pb.WatchJobRequest(id=job.id)) for _ in range(64)]
        for w in watchers:           # each one subscribed: it has a progress message
            assert next(w).WhichOneof("part") == "progress"
        e = expect_rpc_error(lambda: next(d.stub.WatchJob(pb.WatchJobRequest(id=job.id))),
                             grpc.StatusCode.RESOURCE_EXHAUSTED, "already has 64 followers")
        st, _, body = d.rest("GET", "/v1/jobs/%s/events" % job.id)
        assert st == 503 and b"already has 64 followers" in body, (st, body[:200])
        for w in watchers[:2]:
            w.cancel()
        time.sleep(0.5)
        assert next(d.stub.WatchJob(pb.WatchJobRequest(id=job.id))).WhichOneof("part") == "progress"
        for w in watchers:
            w.cancel()
        d.stub.CancelJob(pb.CancelJobRequest(id=job.id))
        d.stop()
    finally:
        d.kill()


def test_upload_deadlines():
    # REST's --header-timeout and --body-timeout hold for gRPC uploads: a
    # call that sends no header, or trickles its mesh, is ended with
    # DEADLINE_EXCEEDED (ETIMEOUT) and its slot freed; an upload in time is
    # not touched
    d = Daemon("deadlines", "--header-timeout", "1", "--body-timeout", "2",
               "--max-connections-per-ip", "2")
    stop = threading.Event()

    def silent():                    # the call opens, nothing is sent
        stop.wait(30)
        return
        yield

    def trickle():                   # a header, then 1 KiB every 0.2 s
        data = mesh("sphere_cgal.obj")
        yield pb.SmoothRequest(header=pb.SmoothHeader(params=pb.Params(iterations=2)))
        for i in range(0, len(data), 1024):
            if stop.wait(0.2):
                return
            yield pb.SmoothRequest(chunk=data[i:i + 1024])

    try:
        for gen, what, lo, hi in ((silent, "--header-timeout 1", 0.9, 3.5),
                                  (trickle, "--body-timeout 2", 1.9, 4.5)):
            t0 = time.time()
            e = expect_rpc_error(lambda: d.stub.SubmitJob(gen(), timeout=30),
                                 grpc.StatusCode.DEADLINE_EXCEEDED, what)
            dt = time.time() - t0
            assert trailing(e, "mcf-code") == "ETIMEOUT", e.trailing_metadata()
            assert lo <= dt <= hi, (what, dt)
            print("    %s: ended after %.2f s" % (what, dt))
        # a trickling Smooth too, and neither held a slot after: two calls
        # (the per-address cap) still go through
        e = expect_rpc_error(lambda: list(d.stub.Smooth(trickle(), timeout=30)),
                             grpc.StatusCode.DEADLINE_EXCEEDED, "--body-timeout 2")
        for _ in range(2):
            g = smooth(d, mesh("sphere_cgal.obj"), dict(iterations=2))
            assert len(g.progress) == 2
        st, _, m = d.rest("GET", "/metrics")
        assert b'mcfd_grpc_calls_total{method="SubmitJob",code="DEADLINE_EXCEEDED"} 2' in m, m
        stop.set()
        d.stop()
    finally:
        stop.set()
        d.kill()


def test_corrupt_message_is_not_the_end_of_the_upload():
    # gRPC's own parse failure ends a read as a half-close does, so a
    # corrupt message after some chunks passed for the end of the upload
    # and the bytes before it were submitted (SubmitJob answered with a job
    # made from a truncated mesh). Now the door parses the bytes itself: any
    # message that is not a SmoothRequest is INVALID_ARGUMENT, nothing is
    # submitted; unknown fields are still skipped (proto3)
    ch = MAIN.channel
    smooth_raw = ch.stream_stream("/mcfd.v1.Smoother/Smooth", request_serializer=lambda b: b,
                                  response_deserializer=pb.SmoothResponse.FromString)
    submit_raw = ch.stream_unary("/mcfd.v1.Smoother/SubmitJob", request_serializer=lambda b: b,
                                 response_deserializer=pb.Job.FromString)
    data = mesh("sphere_cgal.obj")
    hdr = pb.SmoothRequest(header=pb.SmoothHeader(params=pb.Params(iterations=2))).SerializeToString()
    chunks = [pb.SmoothRequest(chunk=data[i:i + 4096]).SerializeToString()
              for i in range(0, len(data), 4096)]
    junk = b"\xff\xff\xff\xff\xff"          # a truncated varint: no protobuf at all
    for name, msgs, n in (("first", [junk], 1), ("after the header", [hdr, junk], 2),
                          ("after 3 chunks", [hdr] + chunks[:3] + [junk], 5)):
        for call in (lambda m: list(smooth_raw(iter(m), timeout=10)),
                     lambda m: submit_raw(iter(m), timeout=10)):
            t0 = time.time()
            e = expect_rpc_error(lambda: call(msgs), grpc.StatusCode.INVALID_ARGUMENT,
                                 "message %d of the upload is not a SmoothRequest" % n)
            assert trailing(e, "mcf-code") == "EINVAL", e.trailing_metadata()
            assert time.time() - t0 < 9      # refused, not left to the 10 s deadline
        print("    junk %s: INVALID_ARGUMENT %r" % (name, e.details()[:60]))
    # an unknown field (number 127, varint) in every message is skipped
    unk = b"\xf8\x07\x01"
    g = Smoothed(smooth_raw(iter([hdr + unk] + [c + unk for c in chunks]), timeout=30))
    assert len(g.progress) == 2 and g.header.size > 0
    # the daemon is as it was: the next upload goes through
    job = MAIN.stub.SubmitJob(upload(data, dict(iterations=2)))
    MAIN.wait_job(job.id, ("succeeded",))


def proc_figures(pid):
    """threads, open descriptors and VmRSS (KiB) of a process"""
    with open("/proc/%d/status" % pid) as f:
        st = dict(l.split(":", 1) for l in f)
    return (int(st["Threads"]), len(os.listdir("/proc/%d/fd" % pid)),
            int(st["VmRSS"].split()[0]))


def test_open_and_cancel_thousands_of_calls():
    # a client opening and cancelling streams as fast as it can (WatchJob on
    # a running job, half of them after their first message; Smooth in the
    # middle of its upload) leaves no thread, descriptor, follower or slot
    # behind, and the memory it costs stays bounded
    d = Daemon("churn", "--workers", "1", "--queue", "4", "--max-connections-per-ip", "0")
    try:
        data = mesh("sphere_cgal.obj")
        smooth(d, data, dict(iterations=2))
        job = d.stub.SubmitJob(upload(mesh("bunny.drc"), LONG))
        d.wait_job(job.id, ("running",))
        next(d.stub.WatchJob(pb.WatchJobRequest(id=job.id)))   # decoded: the sandbox is gone
        time.sleep(0.3)
        base = proc_figures(d.p.pid)
        with open("/proc/%d/maps" % d.p.pid) as f:
            asan = "libasan" in f.read()                       # its quarantine holds freed memory
        busy, t0 = 0, time.time()
        for r in range(2):
            for i in range(500):
                c = d.stub.WatchJob(pb.WatchJobRequest(id=job.id))
                if i % 2:
                    try:
                        next(c)
                    except grpc.RpcError as e:   # the 64-follower cap, while calls retire
                        assert e.code() == grpc.StatusCode.RESOURCE_EXHAUSTED, e
                        busy += 1
                c.cancel()
            for i in range(250):
                d.stub.Smooth(upload(data, dict(iterations=2))).cancel()
            if r == 0:
                mid = proc_figures(d.p.pid)
        took = time.time() - t0
        end = time.time() + 5
        while time.time() < end:
            m = d.rest("GET", "/metrics")[2].decode()
            after = proc_figures(d.p.pid)
            if "\nmcfd_followers 0\n" in m and after[1] <= base[1]:
                break
            time.sleep(0.1)
        print("    1500 calls opened and cancelled in %.1f s (%d refused while retiring): "
              "threads %d -> %d, fds %d -> %d, RSS %d -> %d KiB (%d after the first 750)"
              % (took, busy, base[0], after[0], base[1], after[1], base[2], after[2], mid[2]))
        assert "\nmcfd_followers 0\n" in m, [l for l in m.splitlines() if "follower" in l]
        assert after[1] <= base[1], (base, after)
        assert after[0] <= base[0] + 4, (base, after)
        # gRPC's and malloc's pools fill in the first half; a call that left
        # anything behind would show in the second (measured +2.7 MiB)
        assert asan or (after[2] - mid[2] < 12 * 1024 and after[2] - base[2] < 96 * 1024), \
            (base, mid, after)
        # the slots are free: 64 followers fit again
        ws = [d.stub.WatchJob(pb.WatchJobRequest(id=job.id)) for _ in range(64)]
        for w in ws:
            assert next(w).WhichOneof("part") == "progress"
        for w in ws:
            w.cancel()
        d.stub.CancelJob(pb.CancelJobRequest(id=job.id))
        d.stop()
    finally:
        d.kill()


def test_unread_answer_is_cancelled():
    # --send-timeout: a Smooth whose client reads nothing of its answer
    # (flow control holds the daemon's write) is cancelled after it, and
    # the result it held goes; a client that reads is not touched
    d = Daemon("unread", "--send-timeout", "2", "--max-upload", "16M")
    try:
        data = big_obj()
        t0 = time.time()
        call = d.stub.Smooth(upload(data, dict(iterations=1)), timeout=120)
        jid = job_id_of(call)        # the job is submitted; nothing is read
        d.wait_job(jid, ("succeeded",), timeout=90)
        deadline = time.time() + 30
        while time.time() < deadline:
            st, _, m = d.rest("GET", "/metrics")
            if b'mcfd_grpc_calls_total{method="Smooth",code="CANCELLED"} 1' in m:
                break
            time.sleep(0.2)
        else:
            raise AssertionError("the unread Smooth was not cancelled: %s" % d.log_tail())
        print("    an unread %.1f MB answer: cancelled %.1f s after the call began (--send-timeout 2)"
              % (len(data) / 1e6, time.time() - t0))
        assert "read nothing for --send-timeout 2" in d.log_tail()
        expect_rpc_error(lambda: list(call), grpc.StatusCode.CANCELLED)
        # a slow reader that keeps reading within the timeout gets everything
        got = Smoothed(d.stub.Smooth(upload(mesh("sphere_cgal.obj"), dict(iterations=3))))
        assert len(got.progress) == 3 and got.result
        d.stop()
    finally:
        d.kill()


def test_grpc_port_flags():
    # a port in use is an error at start (gRPC's SO_REUSEPORT is off: a
    # second daemon must not share the first one's port)
    p = subprocess.run([MCFD, "--bind", "127.0.0.1", "--port", "0", "--grpc-port", str(MAIN.gport),
                        "--spool", os.path.join(TMP, "dup")], capture_output=True, timeout=30)
    assert p.returncode == 1 and b"cannot listen for gRPC" in p.stderr, (p.returncode, p.stderr[-300:])
    p = subprocess.run([MCFD, "--grpc-port", "nope"], capture_output=True, timeout=10)
    assert p.returncode == 2 and b"--grpc-port" in p.stderr, p.stderr
    p = subprocess.run([MCFD, "--help"], capture_output=True, timeout=10)
    assert b"--grpc-port" in p.stdout and b"MCFD_GRPC_PORT" in p.stdout
    spool = os.path.join(TMP, "off")
    q = subprocess.Popen([MCFD, "--bind", "127.0.0.1", "--port", "0", "--spool", spool],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, start_new_session=True,
                         env=dict(os.environ, MCFD_GRPC_PORT="off"))
    CHILDREN.append(q)
    line = q.stdout.readline().decode()
    assert line.startswith("mcfd listening on http://127.0.0.1:"), line
    q.send_signal(signal.SIGTERM)
    rest = q.stdout.read().decode()
    assert q.wait(30) == 0 and "grpc" not in rest, rest


# ------------------------------------------------ issue 17: the door under attack
#
# Each of these attacks a real daemon with tests/h2raw.py (frames by hand),
# prints what it cost and asserts the bound; each failed on the daemon
# before the gate (server/grpc/h2gate/h2gate.c). `make attack` runs them too.

def proc_cpu(pid):
    """CPU seconds (user + system) a process has used"""
    with open("/proc/%d/stat" % pid) as f:
        x = f.read().rsplit(")", 1)[1].split()
    return (int(x[11]) + int(x[12])) / os.sysconf("SC_CLK_TCK")


def vm_hwm(pid):
    """VmHWM (KiB): the process's peak resident size"""
    with open("/proc/%d/status" % pid) as f:
        return int(dict(l.split(":", 1) for l in f)["VmHWM"].split()[0])


def sanitized(pid):
    """Whether a process runs under ASan or TSan: its RSS says nothing then
    (ASan's quarantine keeps 256 MiB of freed memory)"""
    with open("/proc/%d/maps" % pid) as f:
        maps = f.read()
    return "libasan" in maps or "libtsan" in maps


def timed(fn):
    t0 = time.time()
    try:
        fn()
        return "OK", time.time() - t0
    except grpc.RpcError as e:
        return e.code().name, time.time() - t0


def list_schemes(d, timeout=10):
    return timed(lambda: d.stub.ListSchemes(pb.ListSchemesRequest(), timeout=timeout))


def test_connection_flood_leaves_the_doors_working():
    # issue 17 item 1: 1,010 connections that send only the HTTP/2 preface
    # took every descriptor of a daemon with the image's nofile 1024 (REST
    # timed out, libmicrohttpd logged hundreds of MB retrying accept), and
    # once they closed gRPC never accepted again (gRPC 1.51's listener
    # stops at its first EMFILE). Now the gate admits at most the caps
    # (here 64 from an address, 157 in all: three descriptors each),
    # refuses the rest with a GOAWAY naming the cap, and gRPC closes idle
    # connections after --send-timeout
    d = Daemon("flood", "--send-timeout", "3", nofile=1024)
    conns = []
    try:
        base = proc_figures(d.p.pid)
        t0 = time.time()
        for i in range(1010):      # 16 addresses, 64 (the per-address cap) each
            try:
                conns.append(h2raw.Conn(d.gport, src="127.0.0.%d" % (2 + i // 64), timeout=5))
            except OSError:
                pass
        took = time.time() - t0
        time.sleep(0.5)
        flood = proc_figures(d.p.pid)
        t1 = time.time()
        st, _, _ = d.rest("GET", "/healthz")
        rest_s = time.time() - t1
        refusal = h2raw.goaway_text(conns[-1].frames(2, until=lambda f: f and f[0] == h2raw.GOAWAY))
        m = d.rest("GET", "/metrics")[2].decode()
        refused = [l for l in m.splitlines() if l.startswith("mcfd_grpc_connections_refused_total ")]
        t2 = time.time()
        closed = h2raw.wait_closed(conns, 10)
        idle_s = time.time() - t2
        after = list_schemes(d)
        for c in conns:
            c.close()
        time.sleep(0.5)
        end = proc_figures(d.p.pid)
        again = list_schemes(d)
        log = os.path.getsize(d.logpath)
        print("    1010 connections in %.1f s: fds %d -> %d of 1024; /healthz %d in %.0f ms; "
              "the excess refused (%r); all %d closed %.1f s later (idle); fds after %d; "
              "ListSchemes %s then %s; log %d bytes"
              % (took, base[1], flood[1], st, rest_s * 1000, refusal, closed, idle_s, end[1],
                 after[0], again[0], log))
        assert flood[1] <= 1024 - 64, flood          # the reserve is untouched
        assert st == 200 and rest_s < 2, (st, rest_s)
        assert refusal and "--max-connections" in refusal, refusal
        assert refused and float(refused[0].split()[1]) >= 1010 - 157, refused
        assert closed == len(conns), (closed, len(conns))
        assert after[0] == "OK" and again[0] == "OK", (after, again)
        assert end[1] <= base[1] + 4, (base, end)
        assert log < 64 * 1024, log                  # bounded, whatever the flood
        d.stop()
    finally:
        for c in conns:
            c.close()
        d.kill()


def test_no_descriptors_makes_the_daemon_unhealthy():
    # issue 17 item 1, health: a door that can no longer take a connection
    # must make /healthz and `mcfd --probe` fail (before, they said healthy
    # while gRPC accepted nothing). The daemon's descriptor limit is
    # lowered under it (prlimit) to within its reserve: gRPC connections are
    # refused at once with a GOAWAY saying why, REST still answers on its
    # half of the reserve, /healthz turns 503 after 5 s and --probe fails;
    # raised again, both doors work and health is back at once
    d = Daemon("nofds", "--workers", "1", nofile=1024)
    try:
        assert list_schemes(d)[0] == "OK"
        n = proc_figures(d.p.pid)[1]
        reserve = 64 + 8 * 1
        resource.prlimit(d.p.pid, resource.RLIMIT_NOFILE, (n + reserve * 3 // 4, 1024))
        t0 = time.time()
        c = h2raw.Conn(d.gport)
        refusal = h2raw.goaway_text(c.frames(2, until=lambda f: f and f[0] == h2raw.GOAWAY))
        c.close()
        st = 200
        while st == 200 and time.time() - t0 < 15:
            st, _, body = d.rest("GET", "/healthz")
            time.sleep(0.2)
        unhealthy_s = time.time() - t0
        probe = subprocess.run([MCFD, "--probe", "--bind", "127.0.0.1", "--port", str(d.port)],
                               capture_output=True, timeout=10)
        resource.prlimit(d.p.pid, resource.RLIMIT_NOFILE, (1024, 1024))
        t1 = time.time()
        while d.rest("GET", "/healthz")[0] != 200 and time.time() - t1 < 5:
            time.sleep(0.05)
        healthy_s = time.time() - t1
        probe2 = subprocess.run([MCFD, "--probe", "--bind", "127.0.0.1", "--port", str(d.port)],
                                capture_output=True, timeout=10)
        print("    descriptors limited to %d: gRPC refused (%r); /healthz %d after %.1f s (%s); "
              "--probe exit %d; limit restored: healthy after %.2f s, --probe exit %d"
              % (n + reserve * 3 // 4, refusal, st, unhealthy_s, body[:80], probe.returncode,
                 healthy_s, probe2.returncode))
        assert refusal and "out of descriptors" in refusal, refusal
        assert st == 503 and b"EUNHEALTHY" in body and 4 < unhealthy_s < 10, (st, body, unhealthy_s)
        assert probe.returncode == 1 and probe2.returncode == 0, (probe, probe2)
        assert healthy_s < 1 and list_schemes(d)[0] == "OK"
        d.stop()
    finally:
        d.kill()


def test_header_blocks_are_bounded():
    # issue 17 item 3 (CVE-2023-33953 class): gRPC 1.51's HPACK parser
    # copies the unparsed part of a header block again for each piece: a
    # header value spread over 16 KB CONTINUATION frames cost 2.5 s of CPU
    # per 8 MB (quadratic: 38.6 s for 32 MB), before authentication. The
    # gate closes a connection whose block passes 16 KiB or 16 frames, or
    # is not whole within --header-timeout, and hands gRPC each block
    # whole; what remains (16 KiB blocks at the most) is measured here
    d = Daemon("hpack", "--header-timeout", "2")
    try:
        cpu0 = proc_cpu(d.p.pid)
        c = h2raw.Conn(d.gport, timeout=5)
        sid = c.stream()
        c.send(h2raw.frame(h2raw.HEADERS, 0, sid, h2raw.request_headers(b"/mcfd.v1.Smoother/GetJob") +
                           h2raw.literal_prefix(b"x-junk", 1 << 30)))
        cont = h2raw.frame(h2raw.CONTINUATION, 0, sid, b"a" * 16384) * 16
        sent = 0
        try:
            while sent < 8 << 20:
                c.s.sendall(cont)
                sent += len(cont)
        except OSError:
            pass
        closed = c.closed_within(5)
        c.close()
        cpu_flood = proc_cpu(d.p.pid) - cpu0
        # a block trickled a byte at a time: cut at --header-timeout
        c = h2raw.Conn(d.gport, timeout=5)
        sid = c.stream()
        c.send(h2raw.frame(h2raw.HEADERS, 0, sid, h2raw.request_headers(b"/mcfd.v1.Smoother/GetJob")[:40]))
        t0 = time.time()
        trickle = None
        while time.time() - t0 < 6:
            try:
                c.send(h2raw.frame(h2raw.CONTINUATION, 0, sid, b"a"))
            except OSError:
                break
            if c.closed_within(0.2) is not None:
                break
        trickle = time.time() - t0
        c.close()
        # within the bounds, as fast as they go: 16 KiB blocks in 16 frames
        # (a value over gRPC's 8 KiB limit), each stream reset at once, from
        # four addresses for 3 s; a legitimate client calls meanwhile
        stop, sent_blocks, lat = threading.Event(), [0], []
        pre = h2raw.request_headers(b"/mcfd.v1.Smoother/GetJob")
        val = 16384 - len(pre) - 12
        block = pre + h2raw.literal_prefix(b"x-junk", val) + b"a" * val
        parts = [block[i:i + 1024] for i in range(0, len(block), 1024)]

        def attacker(k):
            a = h2raw.Conn(d.gport, src="127.0.0.%d" % (10 + k), timeout=5)
            try:
                while not stop.is_set():
                    sid = a.stream()
                    fr = [h2raw.frame(h2raw.HEADERS, 0, sid, parts[0])]
                    fr += [h2raw.frame(h2raw.CONTINUATION, h2raw.END_HEADERS if j == len(parts) - 1 else 0,
                                       sid, pt) for j, pt in enumerate(parts[1:], 1)]
                    fr.append(h2raw.frame(h2raw.RST_STREAM, 0, sid, b"\0\0\0\x08"))
                    a.send(*fr)
                    sent_blocks[0] += 1
                    a.frames(0.0)
            except OSError:
                pass
            a.close()
        cpu1 = proc_cpu(d.p.pid)
        ts = [threading.Thread(target=attacker, args=(k,)) for k in range(4)]
        for t in ts:
            t.start()
        t0 = time.time()
        while time.time() - t0 < 3:
            lat.append(list_schemes(d))
            time.sleep(0.1)
        stop.set()
        for t in ts:
            t.join()
        cpu_bounded = proc_cpu(d.p.pid) - cpu1
        mb = sent_blocks[0] * len(block) / 1e6
        worst = max(x[1] for x in lat)
        print("    a 1 GiB header value in CONTINUATIONs: closed after %d KB sent (%s), daemon CPU "
              "%.2f s; a block trickled: cut after %.1f s (--header-timeout 2); 16 KiB blocks "
              "as fast as they go, 4 addresses, 3 s: %.0f MB, daemon CPU %.2f s (%.3f s/MB), "
              "ListSchemes meanwhile worst %.0f ms"
              % (sent / 1000, "closed" if closed is not None else "open", cpu_flood, trickle, mb,
                 cpu_bounded, cpu_bounded / max(mb, 1e-9), worst * 1000))
        assert closed is not None and sent < 4 << 20, (closed, sent)
        assert cpu_flood < 0.5, cpu_flood
        assert 1.5 < trickle < 4.5, trickle
        # every call served; the latency bound holds for the product's build
        # (3.1 s measured under ASan+UBSan, where the gate runs 2-3x slower)
        assert all(x[0] == "OK" for x in lat), lat
        if not sanitized(d.p.pid):
            assert worst < 2, lat
        d.stop()
    finally:
        d.kill()


def test_abandoned_streams_are_bounded():
    # issue 17 item 4: 50,000 GetJob streams that never send their message,
    # on one connection, before authentication: RSS 26 -> 619 MiB in 3.4 s
    # (gRPC holds about 12 KiB per stream and advertised no
    # MAX_CONCURRENT_STREAMS). Now gRPC advertises 100, the gate holds a
    # client at 100 (even one that never acknowledges the setting) and
    # resets a stream whose first message has not come --header-timeout + 1
    # s after its HEADERS
    tok = os.path.join(TMP, "abandon.token")
    with open(tok, "w") as f:
        f.write("s3cret\n")
    d = Daemon("abandon", "--header-timeout", "1", "--token-file", tok)
    try:
        base = proc_figures(d.p.pid)[2]
        c = h2raw.Conn(d.gport, src="127.0.0.2", timeout=2)
        fr = c.frames(1, until=lambda f: f and f[0] == h2raw.SETTINGS)
        settings = fr[-1][3] if fr and fr[-1] else b""
        advertised = {int.from_bytes(settings[i:i + 2], "big"): int.from_bytes(settings[i + 2:i + 6], "big")
                      for i in range(0, len(settings) - 5, 6)}
        hb = h2raw.request_headers(b"/mcfd.v1.Smoother/GetJob")
        sent, t0 = 0, time.time()
        try:
            for _ in range(50):
                c.send(*[h2raw.frame(h2raw.HEADERS, h2raw.END_HEADERS, c.stream(), hb) for _ in range(1000)])
                sent += 1000
        except OSError:
            pass                     # the gate stopped reading: the client's buffers are full
        time.sleep(0.5)
        held = proc_figures(d.p.pid)[2]
        legit = list_schemes(d)      # another address, meanwhile
        resets = [f for f in c.frames(4) if f and f[0] == h2raw.RST_STREAM]
        c.close()
        time.sleep(1)
        after = proc_figures(d.p.pid)[2]
        print("    %d silent GetJob streams sent in %.1f s (MAX_CONCURRENT_STREAMS %s): RSS %.1f -> "
              "%.1f MiB, %.1f after closing; %d reset by the gate; ListSchemes meanwhile %s"
              % (sent, time.time() - t0, advertised.get(3), base / 1024, held / 1024, after / 1024,
                 len(resets), legit[0]))
        assert advertised.get(3) == 100, advertised
        assert sanitized(d.p.pid) or held - base < 24 * 1024, (base, held)
        assert len(resets) >= 100 and legit[0] == "UNAUTHENTICATED", (len(resets), legit)
        d.stop()
    finally:
        d.kill()


def test_rapid_reset_is_paced():
    # issue 17 item 5 (CVE-2023-44487 class): 40,000 HEADERS + RST_STREAM
    # per round left 1.46 GiB and legitimate calls took 3.6 s: gRPC 1.51
    # queues the work of each reset stream faster than it disposes of it.
    # The gate counts a stream reset before gRPC ended it until gRPC could
    # have disposed of it (1,000 a second), and new streams wait while
    # their address (256) or the daemon (1,024) is at its bound, the
    # waiting connections served in turn
    d = Daemon("reset")
    stop, pairs, lat, peak = threading.Event(), [0], [], [0]
    hb = h2raw.request_headers(b"/mcfd.v1.Smoother/GetJob")

    def attacker(k):
        a = h2raw.Conn(d.gport, src="127.0.0.%d" % (2 + k), timeout=5)
        try:
            while not stop.is_set():
                fr = []
                for _ in range(200):
                    sid = a.stream()
                    fr += [h2raw.frame(h2raw.HEADERS, h2raw.END_HEADERS, sid, hb),
                           h2raw.frame(h2raw.RST_STREAM, 0, sid, b"\0\0\0\x08")]
                a.send(*fr)
                pairs[0] += 200
                a.frames(0.0)
        except OSError:
            pass
        a.close()
    try:
        assert list_schemes(d)[0] == "OK"
        base = proc_figures(d.p.pid)[2]
        ts = [threading.Thread(target=attacker, args=(k,)) for k in range(2)]
        for t in ts:
            t.start()
        t0 = time.time()
        while time.time() - t0 < 5:
            lat.append(list_schemes(d))
            peak[0] = max(peak[0], proc_figures(d.p.pid)[2])
            time.sleep(0.1)
        stop.set()
        for t in ts:
            t.join()
        t1 = time.time()             # malloc's free pages go back every 5 s (main.c)
        while time.time() - t1 < 7:
            after = proc_figures(d.p.pid)[2]
            if after - base < 8 * 1024:
                break
            time.sleep(0.25)
        ls = sorted(x[1] for x in lat)
        print("    %d HEADERS + RST_STREAM from 2 addresses in 5 s: RSS %.1f -> %.1f MiB (peak), "
              "%.1f %.1f s after; ListSchemes meanwhile median %.0f ms, worst %.0f ms"
              % (pairs[0], base / 1024, peak[0] / 1024, after / 1024, time.time() - t1,
                 ls[len(ls) // 2] * 1000, ls[-1] * 1000))
        # every legitimate call is served meanwhile; the memory and latency
        # bounds hold for the product's build: under ASan+UBSan the RSS says
        # nothing (its quarantine) and the gate's pacing runs 2-3x slower
        # (a worst ListSchemes of 2.3 s measured on a loaded machine)
        assert all(x[0] == "OK" for x in lat), lat
        if not sanitized(d.p.pid):
            assert peak[0] - base < 32 * 1024, (base, peak)
            assert after - base < 8 * 1024, (base, after)
            assert ls[-1] < 1, lat
        d.stop()
    finally:
        stop.set()
        d.kill()


def test_compressed_messages_are_refused():
    # issue 17, a sharp edge: gRPC 1.51 inflates a whole compressed message
    # before any size limit (132 KB of gzip became 128 MiB, VmHWM +137
    # MiB), no token needed. Only identity is enabled now: a compressed
    # message is UNIMPLEMENTED, unread
    e = expect_rpc_error(lambda: MAIN.stub.GetJob(pb.GetJobRequest(id="x" * 100),
                                                  compression=grpc.Compression.Gzip),
                         grpc.StatusCode.UNIMPLEMENTED, "gzip")
    d = Daemon("gzip")
    try:
        hwm0 = vm_hwm(d.p.pid)
        bomb = h2raw.message(h2raw.gzip_bomb(128 << 20), compressed=True)
        c = h2raw.Conn(d.gport, timeout=10)
        sid = c.stream()
        c.send(h2raw.frame(h2raw.HEADERS, h2raw.END_HEADERS, sid,
                           h2raw.request_headers(b"/mcfd.v1.Smoother/Smooth", [(b"grpc-encoding", b"gzip")])))
        for i in range(0, len(bomb), 16384):
            try:
                c.send(h2raw.frame(h2raw.DATA, 0, sid, bomb[i:i + 16384]))
            except OSError:
                break
        c.frames(2)
        c.close()
        time.sleep(0.5)
        grew = vm_hwm(d.p.pid) - hwm0
        print("    a gzip message: %s (%s); %d KB inflating to 128 MiB: VmHWM +%.1f MiB"
              % (e.code().name, e.details(), len(bomb) / 1000, grew / 1024))
        assert grew < 16 * 1024, grew
        assert list_schemes(d)[0] == "OK"
        d.stop()
    finally:
        d.kill()



UPLOAD_SLACK = 12   # MiB over --max-memory: the transport's (docs/reliability.md)


def test_uploads_in_flight_fit_the_memory_budget():
    # issue 17 item 7: 16 Smooth uploads of 40 MiB held open took 681 MiB
    # against a documented peak of rest + --max-memory 100M (each upload
    # buffers up to --max-upload). Now an upload reserves its declared
    # total_size in --max-memory at its header, beside the running jobs and
    # the other uploads (RESOURCE_EXHAUSTED EBUSY with retry-after-ms when
    # it does not fit), or as its bytes come without one.
    # The documented bound (docs/reliability.md) is VmHWM <= rest +
    # --max-memory + UPLOAD_SLACK: the reservations hold the uploads'
    # bytes plus SVC_UPLOAD_AROUND (2 MiB) each, which covers what an
    # upload costs beside its bytes (measured <= 0.2 MiB per stream on one
    # connection, ~0.4 MiB per connection), but not what the transport
    # takes once for all of them: gRPC's threads' malloc arenas, grown by
    # the first uploads and kept (the daemon's RSS stays 4 MiB over rest
    # after them), and the bytes in flight between the socket and our
    # buffers while they stream (the gate's queues, gRPC's slices up to
    # the HTTP/2 windows). Measured growth here: 94-99 MiB alone and
    # beside a make -j2 build, 104 MiB reported under heavier load, for
    # 92-94 MiB of reserved bytes. UPLOAD_SLACK is 12 MiB: the 4 MiB
    # arenas plus 8 MiB in flight (the 104 MiB seen under load is 10 over
    # the budget's bytes), 8 MiB clear of the worst figure seen, and
    # still 570 MiB below issue 17's 681 MiB.
    d = Daemon("uploads", "--max-memory", "100M", "--max-upload", "64M",
               "--max-connections-per-ip", "0")
    data = b"v 0 0 0\n" * (40 * 1024 * 1024 // 8)
    release = threading.Event()

    def held(declared):
        h = pb.SmoothHeader(params=pb.Params(iterations=1))
        if declared:
            h.total_size = len(data)
        yield pb.SmoothRequest(header=h)
        for i in range(0, len(data) - 65536, 65536):   # all but the last chunk
            if release.is_set():
                return
            yield pb.SmoothRequest(chunk=data[i:i + 65536])
        release.wait(60)
    try:
        rest = vm_hwm(d.p.pid)
        calls = [d.stub.SubmitJob.future(held(True), timeout=120) for _ in range(16)]
        busy = []
        t0 = time.time()
        while len(busy) < 14 and time.time() - t0 < 30:
            busy = [c for c in calls if c.done()]
            time.sleep(0.1)
        last, t1 = -1, time.time()
        while time.time() - t1 < 10:        # the held ones: until their bytes stop coming
            now = proc_figures(d.p.pid)[2]
            if now == last:
                break
            last = now
            time.sleep(0.5)
        peak = vm_hwm(d.p.pid)
        codes = sorted(set((c.exception().code().name, trailing(c.exception(), "mcf-code"))
                           for c in busy if c.exception()))
        release.set()
        for c in calls:
            try:
                c.result()
            except grpc.RpcError:
                pass
        # without total_size: reserved as the bytes come, refused past the budget
        release.clear()
        calls = [d.stub.SubmitJob.future(held(False), timeout=120) for _ in range(4)]
        t0 = time.time()
        while sum(c.done() for c in calls) < 2 and time.time() - t0 < 30:
            time.sleep(0.1)
        undeclared = [c.exception().code().name for c in calls if c.done() and c.exception()]
        peak2 = vm_hwm(d.p.pid)
        release.set()
        for c in calls:
            try:
                c.result()
            except grpc.RpcError:
                pass
        print("    16 uploads of 40 MiB held open (--max-memory 100M): %d refused %s at their "
              "header; VmHWM %.0f -> %.0f MiB; 4 without total_size: %s, VmHWM %.0f MiB "
              "(+%.0f, bound +%d)" % (len(busy), codes, rest / 1024, peak / 1024, undeclared,
                                     peak2 / 1024, (peak2 - rest) / 1024, 100 + UPLOAD_SLACK))
        assert len(busy) == 14 and codes == [("RESOURCE_EXHAUSTED", "EBUSY")], (len(busy), codes)
        assert undeclared.count("RESOURCE_EXHAUSTED") >= 2, undeclared
        assert sanitized(d.p.pid) or peak2 - rest < (100 + UPLOAD_SLACK) * 1024, (rest, peak, peak2)
        # the budget is free again once gRPC is done with the refused calls:
        # their reservations go with them (OnDone, Upload's destructor), just
        # after their status reached us, so a client that retries after
        # retry-after-ms gets in (CI's ASan run of 2026-11-29 came back
        # RESOURCE_EXHAUSTED at once, as test_streaming_call_caps' did)
        for attempt in range(3):
            try:
                assert len(smooth(d, mesh("sphere_cgal.obj"), dict(iterations=2)).progress) == 2
                break
            except grpc.RpcError as e:
                if e.code() != grpc.StatusCode.RESOURCE_EXHAUSTED or attempt == 2:
                    raise
                time.sleep(min(5.0, max(1.0, int(trailing(e, "retry-after-ms") or 1000) / 1000.0)))
        d.stop()
    finally:
        release.set()
        d.kill()


TESTS = [v for k, v in list(globals().items()) if k.startswith("test_") and callable(v)]


def main():
    global MAIN
    flt = os.environ.get("MCF_TEST_FILTER")
    tests = [t for t in TESTS if not flt or t.__name__ == flt]
    print("[==========] Running %d test(s)." % len(tests), flush=True)
    failed = []
    try:
        # --max-work: a grid of 108,900 vertices x 100,000 steps is over it,
        # 50,000 steps of bunny.drc (LONG) under it
        MAIN = Daemon("main", "--workers", "2", "--queue", "8", "--max-upload", "16M",
                      "--max-work", "5e9")
    except Exception as e:  # noqa: BLE001
        print("[  ERROR   ] the main daemon: %s" % e)
        print("[  FAILED  ] %d test(s), listed below:" % len(tests))
        return 1
    for t in tests:
        print("[ RUN      ] %s" % t.__name__, flush=True)
        t0 = time.time()
        try:
            t()
            print("[       OK ] %s (%.1f s)" % (t.__name__, time.time() - t0), flush=True)
        except Exception:  # noqa: BLE001
            traceback.print_exc(file=sys.stdout)
            print("[  FAILED  ] %s" % t.__name__, flush=True)
            failed.append(t.__name__)
    try:
        MAIN.stop()
    except AssertionError as e:
        print("[  ERROR   ] %s" % e)
        failed.append("main daemon shutdown")
    print("[==========] %d test(s) run." % len(tests))
    print("[  PASSED  ] %d test(s)." % (len(tests) - len([f for f in failed if f in [t.__name__ for t in tests]])))
    if failed:
        print("[  FAILED  ] %d test(s), listed below:" % len(failed))
        for f in failed:
            print("[  FAILED  ] %s" % f)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
