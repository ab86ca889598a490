# SPDX-License-Identifier: MIT
"""mcfd_client - smooth meshes with an mcfd daemon, over REST or gRPC.

    import mcfd_client
    out = mcfd_client.smooth("scan.obj", url="http://127.0.0.1:8080", strength=0.5)
    V2, F2 = mcfd_client.smooth((V, F), url="grpc://127.0.0.1:50051", scheme="desbrun2")
    job = mcfd_client.submit("scan.drc", url="http://127.0.0.1:8080")   # returns at once
    out = job.result(timeout=60)                     # or job.status(), job.wait(), job.cancel()
    mcfd_client.smooth_files(["a.obj", "b.ply"], "out/", url="http://127.0.0.1:8080")

The parameters are the daemon's (`mcf params` lists them, with their ranges
and defaults); the daemon validates them, so a bad one raises
InvalidParameter with the daemon's own message. See smooth().
"""
import os
import time
import urllib.parse
import warnings as _warnings

from . import _grpc, _mesh, _rest
from ._jobs import Job, smooth_files
from .errors import (Busy, Canceled, InvalidParameter, LimitExceeded, MCFDError, MeshError,
                     NotFound, NotReady, ServerError, SmoothingWarning, Unauthorized,
                     Unreachable)

__version__ = "1.0.0"
__all__ = ["smooth", "submit", "smooth_files", "Job", "Busy", "Canceled", "InvalidParameter",
           "LimitExceeded", "MCFDError", "MeshError", "NotFound", "NotReady", "ServerError",
           "SmoothingWarning", "Unauthorized", "Unreachable"]

_EXT = {"draco": "drc"}


def smooth(mesh, url="http://127.0.0.1:8080", *, target=None, out=None, progress=None,
           with_metrics=False, timeout=600.0, retries=5, max_wait=60.0, token=None,
           **params):
    """Smooths mesh with the daemon at url and returns the result in the
    kind mesh was given:

    - a path (str or os.PathLike): the result is written to `out` (default:
      beside the input, NAME-smoothed.EXT, EXT the output format's; an
      existing directory: NAME-smoothed.EXT in it) and its path returned,
      of the input's type;
    - bytes: the result's bytes (the daemon's format: the input's, or the
      `format` parameter's);
    - a (vertices, faces) pair of numpy arrays, (n, 3) and (m, 3): a new
      pair, vertices in the input's float type (float32 stays float32,
      anything else is float64), faces int32. Sent and received as PLY.

    url: http://HOST:PORT (REST) or grpc://HOST:PORT (gRPC; grpcs:// with
    TLS). params: the job parameters (scheme, strength, time, iterations,
    dt, format, ...; "auto" where the daemon accepts it). target: a clean
    mesh (path or bytes) with the same connectivity, for the metrics'
    comparison. progress: called with a dict {step, t, dt, energy, volume,
    phase, done} after every step and at the core's milestones between
    them (the phases of the default request: phase names it, done is the
    share of the work; a step has phase "steps"), as mcf.smooth calls it. with_metrics: return (result, metrics), metrics the
    daemon's document (a dict). timeout: seconds for the whole call.
    token: the daemon's bearer token (--token-file).

    A busy daemon (REST 503, gRPC RESOURCE_EXHAUSTED or UNAVAILABLE with a
    delay) is retried up to `retries` times after the delay it asks for
    (Retry-After, retry-after-ms; at most max_wait seconds each). Failures
    raise an MCFDError subclass carrying the daemon's `code`; a result the
    daemon warns about (folds, edge_collapse, area_loss, little_smoothing)
    is returned, with one SmoothingWarning per warning (warnings.warn).
    """
    kind, data, filename, params, target = _prepare(mesh, params, target)
    door = _door_for(url, token, timeout)
    answer = _with_retries(lambda: door.smooth(data, filename, params, target, progress,
                                               with_metrics), retries, max_wait)
    _warn(answer, stacklevel=3)
    result = _deliver(kind, mesh, out, answer)
    return (result, answer.metrics) if with_metrics else result


def submit(mesh, url="http://127.0.0.1:8080", *, target=None, out=None, timeout=600.0,
           retries=5, max_wait=60.0, token=None, **params):
    """Submits mesh to the daemon at url and returns at once, once the job
    is queued, with a Job handle: job.id, job.status(), job.wait(timeout,
    progress), job.result(timeout) (the result in the kind mesh was given,
    as smooth() returns it; a failed job raises its typed error),
    job.metrics(), job.cancel(). The arguments are smooth()'s; timeout
    bounds each call to the daemon. Parameters the daemon refuses raise at
    once (InvalidParameter); problems that need the mesh (MeshError,
    LimitExceeded) come from job.result()."""
    kind, data, filename, params, target = _prepare(mesh, params, target)
    door = _door_for(url, token, timeout)
    doc = _with_retries(lambda: door.submit(data, filename, params, target), retries, max_wait)
    return Job(doc["id"], url, _door=door,
               _deliver=lambda answer: _deliver(kind, mesh, out, answer))


def _prepare(mesh, params, target):
    """(kind, bytes, file name, params, target bytes) of a request."""
    kind, data, filename = _input(mesh)
    if kind == "arrays":
        if params.get("format", "ply") != "ply":
            raise ValueError("arrays travel as PLY: format=%r cannot come back as arrays"
                             % params["format"])
        params["format"] = "ply"
    if target is not None:
        target = _input(target)[1]
    return kind, data, filename, params, target


def _warn(answer, stacklevel=3):
    for name in answer.warnings:
        _warnings.warn(SmoothingWarning(name, answer.job), stacklevel=stacklevel)


def _deliver(kind, mesh, out, answer):
    """The answer in the kind mesh was given: arrays, bytes, or a path."""
    if kind == "arrays":
        return _mesh.from_ply(answer.data, float_type=_float_type(mesh))
    if kind == "bytes":
        return answer.data
    if out is None:
        path = _beside(mesh, answer.format)
    elif os.path.isdir(out):
        path = os.path.join(out, os.path.basename(_beside(mesh, answer.format)))
    else:
        path = out
    with open(path, "wb") as f:
        f.write(answer.data)
    return type(mesh)(path) if not isinstance(mesh, str) else os.fspath(path)


def _float_type(mesh):
    """The float type the arrays come back in: the input vertices'."""
    import numpy
    return numpy.float32 if numpy.asarray(mesh[0]).dtype == numpy.float32 else numpy.float64


def _input(mesh):
    """(kind, bytes, file name) of a path, bytes or (vertices, faces)."""
    if isinstance(mesh, (bytes, bytearray, memoryview)):
        return "bytes", bytes(mesh), "mesh"
    if isinstance(mesh, (str, os.PathLike)):
        with open(mesh, "rb") as f:
            return "path", f.read(), os.path.basename(os.fspath(mesh))
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        return "arrays", _mesh.to_ply(*mesh), "mesh.ply"
    raise TypeError("mesh must be a path, bytes or a (vertices, faces) pair of arrays, not %s"
                    % type(mesh).__name__)


def _beside(path, fmt):
    """NAME-smoothed.EXT beside the input, EXT the answer's format's."""
    p = os.fspath(path)
    stem = os.path.splitext(os.path.basename(p))[0]
    ext = _EXT.get(fmt, fmt) if fmt else os.path.splitext(p)[1].lstrip(".")
    return os.path.join(os.path.dirname(p), "%s-smoothed.%s" % (stem, ext))


def _door_for(url, token, timeout):
    """The door object of url: REST (http, https) or gRPC (grpc, grpcs)."""
    u = urllib.parse.urlsplit(url)
    if u.scheme in ("grpc", "grpcs"):
        meta = (("authorization", "Bearer " + token),) if token else None
        return _grpc.Door(u.netloc, u.scheme == "grpcs", timeout, meta)
    if u.scheme in ("http", "https"):
        headers = {"Authorization": "Bearer " + token} if token else {}
        return _rest.Door(url.rstrip("/"), timeout, headers)
    raise ValueError("url must start with http://, https://, grpc:// or grpcs://, not %r" % url)


def _with_retries(call, retries, max_wait):
    """call(), retried after a Busy daemon's delay up to retries times."""
    attempt = 0
    while True:
        try:
            return call()
        except Busy as e:
            if attempt >= retries or e.retry_after is None:
                raise
            attempt += 1
            time.sleep(min(e.retry_after, max_wait))
