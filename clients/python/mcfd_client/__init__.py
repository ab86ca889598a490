# SPDX-License-Identifier: MIT
"""mcfd_client - smooth meshes with an mcfd daemon, over REST or gRPC.

    import mcfd_client
    out = mcfd_client.smooth("scan.obj", url="http://127.0.0.1:8080", strength=0.5)
    V2, F2 = mcfd_client.smooth((V, F), url="grpc://127.0.0.1:50051", scheme="desbrun2")

The parameters are the daemon's (`mcf params` lists them, with their ranges
and defaults); the daemon validates them, so a bad one raises
InvalidParameter with the daemon's own message. See smooth().
"""
import os
import time
import urllib.parse
import warnings as _warnings

from . import _grpc, _mesh, _rest
from .errors import (Busy, Canceled, InvalidParameter, LimitExceeded, MCFDError, MeshError,
                     NotFound, ServerError, SmoothingWarning, Unauthorized, Unreachable)

__version__ = "1.0.0"
__all__ = ["smooth", "Busy", "Canceled", "InvalidParameter", "LimitExceeded", "MCFDError",
           "MeshError", "NotFound", "ServerError", "SmoothingWarning", "Unauthorized",
           "Unreachable"]

_EXT = {"draco": "drc"}


def smooth(mesh, url="http://127.0.0.1:8080", *, target=None, out=None, progress=None,
           with_metrics=False, timeout=600.0, retries=5, max_wait=60.0, token=None,
           **params):
    """Smooths mesh with the daemon at url and returns the result in the
    kind mesh was given:

    - a path (str or os.PathLike): the result is written to `out` (default:
      beside the input, NAME-smoothed.EXT, EXT the output format's) and its
      path returned, of the input's type;
    - bytes: the result's bytes (the daemon's format: the input's, or the
      `format` parameter's);
    - a (vertices, faces) pair of numpy arrays, (n, 3) and (m, 3): a new
      pair, vertices in the input's float type (float32 stays float32,
      anything else is float64), faces int32. Sent and received as PLY.

    url: http://HOST:PORT (REST) or grpc://HOST:PORT (gRPC; grpcs:// with
    TLS). params: the job parameters (scheme, strength, time, iterations,
    dt, format, ...; "auto" where the daemon accepts it). target: a clean
    mesh (path or bytes) with the same connectivity, for the metrics'
    comparison. progress: called with a dict {step, t, dt, energy, volume}
    after every step. with_metrics: return (result, metrics), metrics the
    daemon's document (a dict). timeout: seconds for the whole call.
    token: the daemon's bearer token (--token-file).

    A busy daemon (REST 503, gRPC RESOURCE_EXHAUSTED or UNAVAILABLE with a
    delay) is retried up to `retries` times after the delay it asks for
    (Retry-After, retry-after-ms; at most max_wait seconds each). Failures
    raise an MCFDError subclass carrying the daemon's `code`; a result the
    daemon warns about (folds, edge_collapse, area_loss, little_smoothing)
    is returned, with one SmoothingWarning per warning (warnings.warn).
    """
    kind, data, filename = _input(mesh)
    if kind == "arrays":
        if params.get("format", "ply") != "ply":
            raise ValueError("arrays travel as PLY: format=%r cannot come back as arrays"
                             % params["format"])
        params["format"] = "ply"
    if target is not None:
        target = _input(target)[1]
    answer = _with_retries(url, data, filename, params, target, progress, with_metrics,
                           timeout, retries, max_wait, token)
    for name in answer.warnings:
        _warnings.warn(SmoothingWarning(name, answer.job), stacklevel=2)
    if kind == "arrays":
        result = _mesh.from_ply(answer.data, float_type=_float_type(mesh))
    elif kind == "bytes":
        result = answer.data
    else:
        path = out if out is not None else _beside(mesh, answer.format)
        with open(path, "wb") as f:
            f.write(answer.data)
        result = type(mesh)(path) if not isinstance(mesh, str) else os.fspath(path)
    return (result, answer.metrics) if with_metrics else result


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


def _with_retries(url, data, filename, params, target, progress, with_metrics, timeout,
                  retries, max_wait, token):
    u = urllib.parse.urlsplit(url)
    if u.scheme in ("grpc", "grpcs"):
        meta = (("authorization", "Bearer " + token),) if token else None
        call = lambda: _grpc.smooth(u.netloc, u.scheme == "grpcs", data, filename, params,  # noqa: E731
                                    target, progress, with_metrics, timeout, meta)
    elif u.scheme in ("http", "https"):
        base = url.rstrip("/")
        headers = {"Authorization": "Bearer " + token} if token else {}
        call = lambda: _rest.smooth(base, data, filename, params, target, progress,  # noqa: E731
                                    with_metrics, timeout, headers)
    else:
        raise ValueError("url must start with http://, https://, grpc:// or grpcs://, not %r" % url)
    attempt = 0
    while True:
        try:
            return call()
        except Busy as e:
            if attempt >= retries or e.retry_after is None:
                raise
            attempt += 1
            time.sleep(min(e.retry_after, max_wait))
