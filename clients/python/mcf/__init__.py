# SPDX-License-Identifier: MIT
"""mcf - smooth meshes in this process, with the library `mcf smooth` runs.

    import mcf
    V2, F2 = mcf.smooth((V, F))                      # numpy arrays in, arrays out
    mesh2 = mcf.smooth(o3d_mesh, strength=0.5)       # an Open3D TriangleMesh
    mcf.smooth("scan.drc", out="smooth.ply")         # files

No daemon: the same C library (libmcf and its api layer, build/libmcfpy.so
through ctypes) runs the same job as `mcf smooth IN OUT --NAME VALUE ...`, so
the same input and parameters give the same mesh, to rounding: the library
links Debian's shared CHOLMOD, whose dense kernels are OpenBLAS's, where mcf
runs small ones as loops (core/cholmod_serial/stand_ins.c); positions agree
within 1e-12 of the bounding box's diagonal (tests/test_pymcf.py). The GIL is
released while it works (threads run beside it), progress is reported to a
callback, failures raise mcfd_client's typed errors with the daemon's codes
(EINVAL, EFORMAT, EDECODE, EMESH, ELIMIT, ...), and a result the library
warns about comes back with a mcfd_client.SmoothingWarning per warning.

Why ctypes: one call per job, whose cost is the smoothing (tens of ms to
seconds); ctypes adds about a microsecond to a call (measured: tests), needs
no compiler at install time and releases the GIL by itself.

Inputs trusted like a library's: Draco decodes are not bounded here (mcf
bounds them with rlimits, which would bound the whole Python process);
untrusted files belong in the daemon's sandbox (mcfd_client).
"""
import copy
import ctypes
import os
import warnings as _warnings

from mcfd_client import _mesh
from mcfd_client.errors import (Canceled, InvalidParameter, LimitExceeded, MCFDError,  # noqa: F401
                                MeshError, SmoothingWarning, error_for)

__version__ = "1.0.0"
__all__ = ["smooth", "smooth_files", "library_version", "Canceled", "InvalidParameter",
           "LimitExceeded", "MCFDError", "MeshError", "SmoothingWarning"]

_STEP = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_double,
                         ctypes.c_double, ctypes.c_double)
_WORK = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_double)
_lib = None


def _library_path():
    """MCF_LIBRARY, else the copy installed with the package, else the
    repository's build (the package used from a checkout)."""
    here = os.path.dirname(os.path.abspath(__file__))
    for path in (os.environ.get("MCF_LIBRARY"),
                 os.path.join(here, "_libmcfpy.so"),
                 os.path.join(here, "..", "..", "..", os.environ.get("MCF_BUILD", "build"),
                              "libmcfpy.so")):
        if path and os.path.exists(path):
            return path
    raise ImportError("mcf: no libmcfpy.so (build it with `make pylib` at the repository's top, "
                      "then pip install ./clients/python again, or set MCF_LIBRARY)")


def _load():
    global _lib
    if _lib is not None:
        return _lib
    # one BLAS and OpenMP thread per job, as mcf and mcfd run (README,
    # Threads), unless the caller chose: read by the libraries as they load
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
        os.environ.setdefault(name, "1")
    lib = ctypes.CDLL(_library_path())
    P, S = ctypes.c_void_p, ctypes.c_char_p
    lib.mcfpy_version.restype = S
    lib.mcfpy_run.restype = P
    lib.mcfpy_run.argtypes = [S, ctypes.c_size_t, S, ctypes.POINTER(S), ctypes.POINTER(S),
                              ctypes.c_int, ctypes.c_int, _STEP, _WORK, P,
                              ctypes.POINTER(ctypes.c_int)]
    for name, res in (("status", ctypes.c_int), ("code", S), ("message", S), ("metrics", S),
                      ("warnings", ctypes.c_uint)):
        f = getattr(lib, "mcfpy_" + name)
        f.restype, f.argtypes = res, [P]
    lib.mcfpy_output.restype = ctypes.c_void_p
    lib.mcfpy_output.argtypes = [P, ctypes.POINTER(ctypes.c_size_t)]
    lib.mcfpy_warning_name.restype = S
    lib.mcfpy_warning_name.argtypes = [ctypes.c_uint]
    lib.mcfpy_free.argtypes = [P]
    _lib = lib
    return lib


def library_version():
    """The library's version (api.h API_VERSION)."""
    return _load().mcfpy_version().decode()


def _text(value):
    """A parameter's value as mcf's command line spells it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return ",".join(str(int(v)) for v in value)
    return str(value)


class _Job:
    """One run of the library: the hooks' state (progress, cancel)."""

    def __init__(self, progress):
        self.progress = progress
        self.cancel = ctypes.c_int(0)
        self.error = None
        self.last = {"step": 0, "t": 0.0, "dt": 0.0, "energy": float("nan"),
                     "volume": float("nan")}
        self.step_cb = _STEP(self._step)
        self.work_cb = _WORK(self._work)

    def _step(self, _ctx, step, t, dt, energy, volume):
        self.last = {"step": step, "t": t, "dt": dt, "energy": energy, "volume": volume}

    def _work(self, _ctx, phase, done):
        if self.progress is None or self.error is not None:
            return
        try:
            if self.progress(dict(self.last, phase=phase.decode(), done=done)):
                self.cancel.value = 1
        except BaseException as e:  # noqa: B902 - re-raised after the run
            self.error = e
            self.cancel.value = 1


def _run(data, out_name, params, progress, with_metrics):
    """(output bytes, metrics dict or None, warning names) of one job."""
    lib = _load()
    keys = [k.encode() for k in params]
    vals = [_text(v).encode() for v in params.values()]
    karr = (ctypes.c_char_p * max(1, len(keys)))(*keys)
    varr = (ctypes.c_char_p * max(1, len(vals)))(*vals)
    job = _Job(progress)
    r = lib.mcfpy_run(data, len(data), out_name.encode(), karr, varr, len(keys),
                      1 if with_metrics else 0, job.step_cb, job.work_cb, None,
                      ctypes.byref(job.cancel))
    if not r:
        raise MemoryError("mcf: out of memory")
    try:
        if job.error is not None:
            raise job.error
        if lib.mcfpy_status(r) != 0:
            raise error_for(lib.mcfpy_code(r).decode(), lib.mcfpy_message(r).decode())
        n = ctypes.c_size_t()
        p = lib.mcfpy_output(r, ctypes.byref(n))
        out = ctypes.string_at(p, n.value) if n.value else b""
        metrics = lib.mcfpy_metrics(r)
        bits = lib.mcfpy_warnings(r)
        names = [lib.mcfpy_warning_name(1 << b).decode() for b in range(32)
                 if bits & (1 << b) and lib.mcfpy_warning_name(1 << b)]
    finally:
        lib.mcfpy_free(r)
    if metrics is not None:
        import json
        metrics = json.loads(metrics.decode())
    return out, metrics, names


def _o3d_kind(mesh):
    """"legacy" for an open3d.geometry.TriangleMesh, "tensor" for an
    open3d.t.geometry.TriangleMesh, else None."""
    m = type(mesh)
    if not (m.__module__.startswith("open3d") and m.__name__ == "TriangleMesh"):
        return None
    return "tensor" if ".t." in m.__module__ + "." else "legacy"


def smooth(mesh, *, out=None, progress=None, with_metrics=False, **params):
    """Smooths mesh in this process and returns the result in the kind it
    was given:

    - a (vertices, faces) pair of numpy arrays, (n, 3) and (m, 3): a new
      pair, vertices in the input's float type (float32 stays float32,
      anything else float64), faces int32;
    - an Open3D TriangleMesh: a new one, its vertex colours, triangle UVs
      and everything else kept, its normals recomputed when it had them
      (open3d.geometry's, or open3d.t.geometry's with its float type);
    - any other object with `vertices` and `faces` arrays (a trimesh
      Trimesh, ...): a copy (its own copy(), else copy.deepcopy) whose
      `vertices` are the result; colours, UVs and the rest untouched;
    - bytes: the result's bytes, in the input's format or `format`'s;
    - a path (str or os.PathLike): the result is written to `out`
      (default: beside the input, NAME-smoothed.EXT) and its path returned.

    Smoothing moves vertices and never changes the connectivity, so every
    per-vertex and per-corner attribute stays valid. params: the job's
    parameters as mcf smooth and the daemon take them (scheme, strength,
    iterations, time, dt, boundary, fixed_vertices, format, ...; `mcf
    params` lists them). progress: called in this thread at every step and
    phase with a dict {step, t, dt, energy, volume, phase, done} (done: the
    share of the work, 0..1); a true return (or an exception, re-raised)
    cancels the run. with_metrics: return (result, metrics), metrics the
    daemon's document (a dict).

    Errors raise mcfd_client's MCFDError subclasses with the daemon's code:
    InvalidParameter (EINVAL), MeshError (EFORMAT, EDECODE, EMESH, ...),
    LimitExceeded (ELIMIT), Canceled (ECANCELED).
    """
    if isinstance(mesh, (bytes, bytearray, memoryview)):
        data = bytes(mesh)
        fmt = params.get("format") or _format_name(data)
        result, metrics, names = _run(data, "result." + _EXT.get(fmt, fmt), params, progress,
                                      with_metrics)
    elif isinstance(mesh, (str, os.PathLike)):
        with open(mesh, "rb") as f:
            data = f.read()
        path = out if out is not None else _beside(mesh, params.get("format") or _format_name(data))
        result, metrics, names = _run(data, os.fspath(path), params, progress, with_metrics)
        with open(path, "wb") as f:
            f.write(result)
        result = path
    else:
        V, F, rebuild = _arrays(mesh)
        if params.get("format", "ply") != "ply":
            raise ValueError("arrays travel as PLY: format=%r cannot come back as arrays"
                             % params["format"])
        params = dict(params, format="ply")
        data = _mesh.to_ply(V, F)
        raw, metrics, names = _run(data, "result.ply", params, progress, with_metrics)
        V2, _ = _mesh.from_ply(raw, float_type=V.dtype)
        result = rebuild(V2)
    for name in names:
        _warnings.warn(SmoothingWarning(name), stacklevel=2)
    return (result, metrics) if with_metrics else result


def _arrays(mesh):
    """(vertices, faces, rebuild) of an in-memory mesh: rebuild(V2) is the
    result in the input's kind."""
    import numpy as np
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        V, F = _mesh.check_arrays(*mesh)
        return V, F, lambda V2: (V2, np.ascontiguousarray(F, dtype=np.int32))
    kind = _o3d_kind(mesh)
    if kind == "tensor":
        import open3d as o3d
        V, F = _mesh.check_arrays(mesh.vertex.positions.numpy(), mesh.triangle.indices.numpy())

        def rebuild(V2):
            m = mesh.clone()                             # colours, UVs, the rest
            m.vertex.positions = o3d.core.Tensor(V2)
            if "normals" in m.vertex:
                m.compute_vertex_normals()
            if "normals" in m.triangle:
                m.compute_triangle_normals()
            return m
        return V, F, rebuild
    if kind == "legacy":
        import open3d as o3d
        V, F = _mesh.check_arrays(np.asarray(mesh.vertices), np.asarray(mesh.triangles))

        def rebuild(V2):
            m = o3d.geometry.TriangleMesh(mesh)          # a copy: colours, UVs, textures
            m.vertices = o3d.utility.Vector3dVector(V2)
            if mesh.has_vertex_normals():
                m.compute_vertex_normals()
            elif mesh.has_triangle_normals():
                m.compute_triangle_normals()
            return m
        return V, F, rebuild
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        V, F = _mesh.check_arrays(np.asarray(mesh.vertices), np.asarray(mesh.faces))

        def rebuild(V2):
            m = mesh.copy() if callable(getattr(mesh, "copy", None)) else copy.deepcopy(mesh)
            m.vertices = V2
            return m
        return V, F, rebuild
    raise TypeError("mesh must be a (vertices, faces) pair of arrays, an Open3D TriangleMesh, an "
                    "object with vertices and faces arrays, bytes or a path, not %s"
                    % type(mesh).__name__)


_EXT = {"draco": "drc"}


def _format_name(data):
    """The input's format as an extension (the result keeps it)."""
    head = data[:64]
    if head.startswith(b"DRACO"):
        return "drc"
    if head.startswith(b"ply"):
        return "ply"
    if head.startswith(b"OFF"):
        return "off"
    if head.startswith(b"glTF"):
        return "glb"
    if head.lstrip().startswith(b"{"):
        return "gltf"
    if head.startswith(b"solid") or (len(data) >= 84 and
                                     len(data) == 84 + 50 * int.from_bytes(data[80:84], "little")):
        return "stl"
    return "obj"


def _beside(path, fmt):
    p = os.fspath(path)
    stem = os.path.splitext(os.path.basename(p))[0]
    return os.path.join(os.path.dirname(p), "%s-smoothed.%s" % (stem, _EXT.get(fmt, fmt)))


def _smooth_file(job):
    src, dst, params = job
    return smooth(src, out=dst, **params)


def smooth_files(paths, out_dir=None, *, processes=None, **params):
    """Smooths many files in a pool of processes (one job each, as many at
    once as processes, default the cores) and returns their output paths
    in the order given: beside each input (NAME-smoothed.EXT) or in
    out_dir under the input's name. The first failure raises its error."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    jobs = []
    for p in paths:
        dst = None
        if out_dir is not None:
            os.makedirs(out_dir, exist_ok=True)
            name = os.path.basename(os.fspath(p))
            if params.get("format"):
                name = os.path.splitext(name)[0] + "." + _EXT.get(params["format"], params["format"])
            dst = os.path.join(out_dir, name)
        jobs.append((p, dst, params))
    # fresh processes (spawn), not forks of this one: a fork copies the
    # BLAS's and OpenMP's thread pools half-locked (forked workers hung)
    with ProcessPoolExecutor(max_workers=processes,
                             mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(_smooth_file, jobs))
