#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_client.py - the Python client (clients/python, mcfd_client) against
real daemons, through both doors: installed with pip from the repository
(no protoc: the stubs travel in the package), every kind of mesh in and
out, progress, metrics, warnings, typed errors with the daemon's code, and
retries of a busy daemon after the delay it asks for.

Two daemons (tests/testlib.py): MAIN with the defaults; GATE with one
worker, a queue of one, --max-vertices 1000 and a token, for the busy, limit
and auth cases. Runs on Debian's /usr/bin/python3 (numpy, grpcio).
"""
import json
import os
import shutil
import subprocess
import sys
import threading
import time
import urllib.request
import warnings

import numpy as np

import testlib
from testlib import DATA, ROOT, TMP, Daemon

sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
import mcfd_client  # noqa: E402
from mcfd_client import _mesh  # noqa: E402

MCF = os.path.join(testlib.BUILD, "mcf")
SPHERE = os.path.join(DATA, "meshes", "sphere_cgal.obj")
BUNNY = os.path.join(DATA, "meshes", "bunny.drc")
TOKEN = "s3cret-token"
MAIN = GATE = None


def info(path_or_bytes):
    """mcf info of a file or of bytes (through stdin)."""
    if isinstance(path_or_bytes, bytes):
        r = subprocess.run([MCF, "info", "-"], input=path_or_bytes, capture_output=True)
    else:
        r = subprocess.run([MCF, "info", path_or_bytes], capture_output=True)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def sphere_arrays():
    r = subprocess.run([MCF, "convert", SPHERE, "-", "--format", "ply"], capture_output=True)
    assert r.returncode == 0, r.stderr
    return _mesh.from_ply(r.stdout)


def both():
    return (MAIN.url, MAIN.grpc_url)


# ------------------------------------------------------------------ tests

def test_pip_install_without_protoc():
    """pip installs the package from the repository with Debian's pip and
    setuptools, offline; the installed copy (not the source) smooths over
    gRPC with its own stubs, with no protoc on PATH."""
    src = os.path.join(TMP, "src")
    shutil.copytree(os.path.join(ROOT, "clients", "python"), src)
    target = os.path.join(TMP, "site")
    r = subprocess.run(["/usr/bin/python3", "-m", "pip", "install", "-q", "--no-index",
                        "--no-build-isolation", "--target", target, src],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert os.path.exists(os.path.join(target, "mcfd_client", "_proto", "mcfd_pb2_grpc.py"))
    code = ("import sys, mcfd_client; assert mcfd_client.__file__.startswith(sys.argv[1]), "
            "mcfd_client.__file__; out = mcfd_client.smooth(open(sys.argv[2], 'rb').read(), "
            "url=sys.argv[3], iterations=2); print(len(out))")
    r = subprocess.run(["/usr/bin/python3", "-c", code, target, SPHERE, MAIN.grpc_url],
                       env={"PYTHONPATH": target, "PATH": "/nonexistent"},
                       capture_output=True, text=True, cwd=TMP)
    assert r.returncode == 0, r.stdout + r.stderr
    assert int(r.stdout) > 10000


def test_path_in_path_out():
    """A path gives a path: NAME-smoothed.EXT beside the input (or out=),
    the same bytes through both doors, the sphere's 812 vertices."""
    src = os.path.join(TMP, "ball.obj")
    shutil.copy(SPHERE, src)
    got = {}
    for url in both():
        out = mcfd_client.smooth(src, url=url, iterations=5)
        assert out == os.path.join(TMP, "ball-smoothed.obj"), out
        with open(out, "rb") as f:
            got[url] = f.read()
    assert got[MAIN.url] == got[MAIN.grpc_url]
    assert info(os.path.join(TMP, "ball-smoothed.obj"))["vertices"] == 812
    import pathlib
    out = mcfd_client.smooth(pathlib.Path(src), url=MAIN.url, out=os.path.join(TMP, "b.drc"),
                             format="draco")
    assert isinstance(out, pathlib.Path) and out.name == "b.drc"
    assert info(str(out))["format"] == "draco"


def test_bytes_progress_metrics():
    """Bytes give bytes; progress reaches the callback once per step (and
    at the core's milestones, done never decreasing) and the metrics
    document comes with the result, through both doors."""
    with open(BUNNY, "rb") as f:
        data = f.read()
    for url in both():
        steps = []
        out, metrics = mcfd_client.smooth(data, url=url, progress=steps.append,
                                          with_metrics=True, iterations=4)
        assert isinstance(out, bytes) and info(out)["vertices"] == 34834
        work = [s["done"] for s in steps if s["done"] is not None]
        steps = [s for s in steps if s["done"] is None]
        assert [s["step"] for s in steps] == [1, 2, 3, 4], steps
        assert all(s["phase"] == "steps" for s in steps)
        assert all(s["t"] > 0 and s["dt"] > 0 and s["energy"] > 0 for s in steps)
        assert work and work == sorted(work) and 0 <= work[0] and work[-1] <= 1, work
        assert metrics["flow"]["steps"] == 4 and metrics["warnings"] == []
        assert metrics["params"]["iterations"] == 4


def test_arrays_in_arrays_out():
    """(vertices, faces) give (vertices, faces): the same triangles, moved
    vertices, the input's float type; the sphere shrinks (MCF)."""
    V, F = sphere_arrays()
    area = info(SPHERE)["area"]
    for url in both():
        for dtype in (np.float64, np.float32):
            V2, F2 = mcfd_client.smooth((V.astype(dtype), F.astype(np.int64)), url=url,
                                        strength=0.5)
            assert V2.dtype == dtype and V2.shape == V.shape, (V2.dtype, V2.shape)
            assert F2.dtype == np.int32 and (F2 == F).all()
            moved = np.abs(V2 - V).max()
            assert 1e-4 < moved < 0.1, moved
            a2 = info(_mesh.to_ply(V2, F2))["area"]
            assert 0.5 * area < a2 < area, (a2, area)
    try:
        mcfd_client.smooth((V, F), url=MAIN.url, format="obj")
    except ValueError as e:
        assert "PLY" in str(e)
    else:
        raise AssertionError("arrays with format=obj were accepted")


def test_typed_errors():
    """The daemon's refusals as typed exceptions carrying its code, the
    HTTP status or the gRPC status, and its detail."""
    with open(SPHERE, "rb") as f:
        data = f.read()
    with open(BUNNY, "rb") as f:
        bunny = f.read()
    for url, bad_status, fmt_status, limit_status, auth_status in (
            (MAIN.url, 400, 415, 413, 401),
            (MAIN.grpc_url, "INVALID_ARGUMENT", "INVALID_ARGUMENT", "RESOURCE_EXHAUSTED",
             "UNAUTHENTICATED")):
        gate = GATE.url if url.startswith("http") else GATE.grpc_url
        cases = [
            (dict(mesh=data, url=url, dt=5000), mcfd_client.InvalidParameter, "EINVAL",
             bad_status, "parameter 'dt' must be a number > 0 and <= 1000"),
            (dict(mesh=data, url=url, time=1e-3, dt=1e-2), mcfd_client.InvalidParameter,
             "EINVAL", bad_status, "is larger than 'time'"),
            (dict(mesh=b"solid x\nnot a mesh", url=url), mcfd_client.MeshError, None,
             fmt_status, ""),
            (dict(mesh=bunny, url=gate, token=TOKEN), mcfd_client.LimitExceeded, "ELIMIT",
             limit_status, "1000"),
            (dict(mesh=data, url=gate), mcfd_client.Unauthorized, "EAUTH", auth_status, ""),
        ]
        for kw, cls, code, status, text in cases:
            try:
                mcfd_client.smooth(kw.pop("mesh"), **kw)
            except mcfd_client.MCFDError as e:
                assert type(e) is cls, (url, kw, type(e), e)
                assert code is None or e.code == code, (url, kw, e.code)
                assert e.code, (url, kw)
                assert e.status == status, (url, kw, e.status)
                assert text in e.detail, (url, kw, e.detail)
            else:
                raise AssertionError("%s %r was accepted" % (url, kw))
    try:
        mcfd_client.smooth(data, url="http://127.0.0.1:9")
    except mcfd_client.Unreachable as e:
        assert e.code is None
    else:
        raise AssertionError("a closed port answered")


def test_warnings():
    """A run the daemon warns about returns its mesh with a
    SmoothingWarning per warning (here the sphere run past extinction)."""
    with open(SPHERE, "rb") as f:
        data = f.read()
    for url in both():
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            out = mcfd_client.smooth(data, url=url, time=0.03, iterations=6)
        names = [x.message.name for x in w if x.category is mcfd_client.SmoothingWarning]
        assert "area_loss" in names, (url, [str(x.message) for x in w])
        assert info(out)["vertices"] == 812


class _Sleeps:
    """Stands in for the client's time module: records the sleeps."""

    def __init__(self):
        self.calls = []

    def sleep(self, s):
        self.calls.append(s)
        time.sleep(s)


def _occupy():
    """Fills GATE's worker and queue with two long jobs; their IDs."""
    ids = []
    for _ in range(2):
        req = urllib.request.Request(
            GATE.url + "/v1/jobs?scheme=desbrun2&iterations=50000&dt=1e-9", data=open(SPHERE, "rb").read(),
            headers={"Authorization": "Bearer " + TOKEN,
                     "Content-Type": "application/octet-stream"}, method="POST")
        with urllib.request.urlopen(req, timeout=30) as r:
            ids.append(json.loads(r.read())["id"])
    return ids


def _cancel(ids):
    for i in ids:
        req = urllib.request.Request(GATE.url + "/v1/jobs/" + i, method="DELETE",
                                     headers={"Authorization": "Bearer " + TOKEN})
        urllib.request.urlopen(req, timeout=30).read()


def test_retries_when_busy():
    """GATE busy (its worker and queue taken): without retries a Busy
    error with the daemon's code and delay; with them, the client waits the
    delay the daemon asked for (REST Retry-After 1 s, gRPC retry-after-ms
    1000) and succeeds once the daemon has room."""
    with open(SPHERE, "rb") as f:
        data = f.read()
    for url, status in ((GATE.url, 503), (GATE.grpc_url, "RESOURCE_EXHAUSTED")):
        ids = _occupy()
        try:
            try:
                mcfd_client.smooth(data, url=url, token=TOKEN, retries=0)
            except mcfd_client.Busy as e:
                assert e.code == "EBUSY" and e.status == status, (e.code, e.status)
                assert e.retry_after == 1.0, e.retry_after
            else:
                raise AssertionError("%s: a busy daemon took the job" % url)
            sleeps, real = _Sleeps(), mcfd_client.time
            mcfd_client.time = sleeps
            threading.Timer(1.5, _cancel, (ids,)).start()
            t0 = time.time()
            try:
                out = mcfd_client.smooth(data, url=url, token=TOKEN, retries=10, iterations=2)
            finally:
                mcfd_client.time = real
            assert info(out)["vertices"] == 812
            assert len(sleeps.calls) >= 1 and all(s == 1.0 for s in sleeps.calls), sleeps.calls
            assert time.time() - t0 >= 1.0
        finally:
            try:
                _cancel(ids)
            except Exception:  # noqa: BLE001 (already canceled and finished)
                pass


def test_submit_wait_result():
    """submit() returns at once with a handle whose result() equals
    smooth()'s for the same request, in the kind the mesh was given (bytes,
    arrays, a path), through both doors; wait() reports progress and ends
    succeeded; metrics() is the job's document; a handle rebuilt from the ID
    gives bytes."""
    with open(BUNNY, "rb") as f:
        data = f.read()
    V, F = sphere_arrays()
    src = os.path.join(TMP, "sub.obj")
    shutil.copy(SPHERE, src)
    for url in both():
        want = mcfd_client.smooth(data, url=url, iterations=4)
        job = mcfd_client.submit(data, url=url, iterations=4)
        assert len(job.id) == 32 and job.status()["status"] in ("queued", "running", "succeeded")
        steps = []
        doc = job.wait(timeout=120, progress=steps.append)
        assert doc["status"] == "succeeded" and doc["progress"]["step"] == 4, doc
        assert steps and steps[-1]["step"] == 4 and all(s["step"] >= 1 for s in steps), steps
        assert job.result() == want, url
        assert job.metrics()["flow"]["steps"] == 4
        assert mcfd_client.Job(job.id, url).result() == want
        V2, F2 = mcfd_client.submit((V.astype(np.float32), F), url=url, strength=0.5).result(120)
        W2, _ = mcfd_client.smooth((V.astype(np.float32), F), url=url, strength=0.5)
        assert V2.dtype == np.float32 and (F2 == F).all() and (V2 == W2).all()
        out = mcfd_client.submit(src, url=url, iterations=2, out=TMP).result(120)
        assert out == os.path.join(TMP, "sub-smoothed.obj") and info(out)["vertices"] == 812


def test_submit_cancel_and_failures():
    """A running job canceled through its handle ends canceled and its
    result() raises Canceled; a mesh that does not decode is accepted at
    submit and its result() raises MeshError with the daemon's code; a bad
    parameter raises at submit; wait() past its timeout raises TimeoutError
    and leaves the job running; the batch helper returns paths and errors in
    order."""
    with open(SPHERE, "rb") as f:
        data = f.read()
    for url in both():
        job = mcfd_client.submit(data, url=url, scheme="desbrun2", iterations=50000, dt=1e-9)
        try:
            job.wait(timeout=0.3)
        except TimeoutError:
            pass
        else:
            raise AssertionError("50,000 steps finished within 0.3 s")
        assert job.cancel()["status"] in ("canceled", "running", "queued")
        assert job.wait(timeout=60)["status"] == "canceled"
        assert job.cancel()["status"] == "canceled"   # a finished job is left as it is
        try:
            job.result()
        except mcfd_client.Canceled as e:
            assert e.code == "ECANCELED" and e.job == job.id
        else:
            raise AssertionError("a canceled job gave a result")
        bad = mcfd_client.submit(b"solid x\nnot a mesh", url=url)
        try:
            bad.result(timeout=60)
        except mcfd_client.MeshError as e:
            assert e.code in ("EFORMAT", "EDECODE"), e.code
        else:
            raise AssertionError("a non-mesh gave a result")
        try:
            mcfd_client.submit(data, url=url, dt=5000)
        except mcfd_client.InvalidParameter as e:
            assert "dt" in e.detail
        else:
            raise AssertionError("dt=5000 was accepted")
    missing = os.path.join(TMP, "missing.obj")
    got = mcfd_client.smooth_files([SPHERE, missing, BUNNY], os.path.join(TMP, "batch"),
                                   url=MAIN.url, max_in_flight=2, iterations=2)
    assert got[0] == os.path.join(TMP, "batch", "sphere_cgal-smoothed.obj"), got
    assert isinstance(got[1], OSError), got
    assert got[2] == os.path.join(TMP, "batch", "bunny-smoothed.drc"), got
    assert info(got[0])["vertices"] == 812 and info(got[2])["vertices"] == 34834


def setup():
    global MAIN, GATE
    MAIN = Daemon("main", "--workers", "2")
    tok = os.path.join(TMP, "token")
    with open(tok, "w") as f:
        f.write(TOKEN + "\n")
    GATE = Daemon("gate", "--workers", "1", "--queue", "1", "--max-vertices", "1000",
                  "--token-file", tok)


def teardown():
    MAIN.stop()
    GATE.stop()


if __name__ == "__main__":
    sys.exit(testlib.run_tests([v for k, v in list(globals().items())
                                if k.startswith("test_") and callable(v)], setup, teardown))
