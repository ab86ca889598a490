#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""test_pymcf.py - the in-process Python package (clients/python/mcf, the
library build/libmcfpy.so through ctypes) against `mcf smooth`, with no
daemon: the same bytes for the same input and parameters (files, bytes,
numpy arrays, an Open3D mesh, a duck-typed trimesh stand-in), attributes
kept, typed errors with the daemon's codes, progress and cancel, the GIL
released while it works, the batch helper, and a pip install into a
virtual environment. Debian's /usr/bin/python3 (numpy; Open3D when
python3-open3d is installed, else that test is skipped by name).
"""
import os
import subprocess
import sys
import threading
import time
import timeit
import warnings

import numpy as np

import noisy
import testlib
from testlib import BUILD, DATA, ROOT, TMP

sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
os.environ.setdefault("MCF_LIBRARY", os.path.join(BUILD, "libmcfpy.so"))
import mcf  # noqa: E402
from mcfd_client import _mesh  # noqa: E402

MESHES = os.path.join(DATA, "meshes")
BUNNY = os.path.join(MESHES, "bunny.drc")
# a noisy knot (3,200 vertices, noise 0.3 mean edges along the normals):
# the default removes something, so equal results mean something
KNOT = os.path.join(TMP, "knot-noisy.obj")
with open(KNOT, "wb") as _f:
    _f.write(noisy.noisy_obj(os.path.join(MESHES, "knot1.obj"), 0.3, 1))


def mcf_cli(src, dst, *args):
    r = subprocess.run([os.path.join(BUILD, "mcf"), "smooth", src, dst, "--quiet"] + list(args),
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    with open(dst, "rb") as f:
        return f.read()


def knot_arrays():
    rows = [line.split() for line in open(KNOT)]
    V = np.array([r[1:4] for r in rows if r[:1] == ["v"]], float)
    F = np.array([r[1:4] for r in rows if r[:1] == ["f"]], int) - 1
    return V, F


def knot_reference(*args):
    """mcf smooth's result for the knot's arrays (the PLY the package sends
    them as), as arrays."""
    V, F = knot_arrays()
    src = os.path.join(TMP, "knot-arrays.ply")
    with open(src, "wb") as f:
        f.write(_mesh.to_ply(V, F))
    return _mesh.from_ply(mcf_cli(src, os.path.join(TMP, "knot-ref.ply"), *args))


# ------------------------------------------------------------------ tests

def test_same_bytes_as_mcf():
    """Files and bytes: the same output bytes as mcf smooth, for the
    default and for named parameters, in three formats."""
    cases = [(BUNNY, "b.drc", {}, []), (BUNNY, "b.ply", {"scheme": "desbrun2", "strength": 0.5},
                                        ["--scheme", "desbrun2", "--strength", "0.5"]),
             (KNOT, "k.obj", {"iterations": 3, "boundary": "free"},
              ["--iterations", "3", "--boundary", "free"])]
    for src, name, params, args in cases:
        want = mcf_cli(src, os.path.join(TMP, "cli-" + name), *args)
        out = mcf.smooth(src, out=os.path.join(TMP, "py-" + name), **params)
        assert out == os.path.join(TMP, "py-" + name)
        with open(out, "rb") as f:
            assert f.read() == want, name
        with open(src, "rb") as f:
            data = f.read()
        fmt = os.path.splitext(name)[1][1:].replace("drc", "draco")
        assert mcf.smooth(data, format=fmt, **params) == want, name
    # a path without out=: NAME-smoothed.EXT beside it
    assert mcf.smooth(KNOT, iterations=1) == os.path.join(TMP, "knot-noisy-smoothed.obj")


def test_arrays_equal_mcf():
    """(V, F) arrays: mcf smooth's positions on the same mesh, to the bit
    (double in, double out), float32 kept; the noise was removed."""
    V, F = knot_arrays()
    Vr, Fr = knot_reference()
    V2, F2 = mcf.smooth((V, F))
    assert V2.dtype == np.float64 and F2.dtype == np.int32
    assert np.array_equal(V2, Vr) and np.array_equal(F2, Fr)
    assert np.abs(V2 - V).max() > 0.0
    V3, _ = mcf.smooth((V.astype(np.float32), F), iterations=2)
    assert V3.dtype == np.float32


class Trimesh:
    """A stand-in for trimesh.Trimesh (not in Debian): vertices and faces
    arrays, colours beside them, copy()."""

    def __init__(self, vertices, faces, colors):
        self.vertices, self.faces, self.colors = vertices, faces, colors

    def copy(self):
        return Trimesh(self.vertices.copy(), self.faces.copy(), self.colors.copy())


def test_duck_typed_mesh():
    """An object with vertices and faces: a copy of it with the result's
    vertices, its other attributes untouched, the input unchanged."""
    V, F = knot_arrays()
    Vr, _ = knot_reference()
    col = np.random.default_rng(3).integers(0, 255, (len(V), 4), dtype=np.uint8)
    m = Trimesh(V.copy(), F, col)
    m2 = mcf.smooth(m)
    assert isinstance(m2, Trimesh) and m2 is not m
    assert np.array_equal(m2.vertices, Vr)
    assert np.array_equal(m2.colors, col) and np.array_equal(m.vertices, V)


def test_open3d_mesh():
    """An Open3D TriangleMesh: an Open3D mesh back, with mcf smooth's
    positions, its vertex colours and triangle UVs kept, normals
    recomputed."""
    try:
        import open3d as o3d
    except ImportError:
        raise testlib.SkipTest("python3-open3d", "Open3D is not installed (python3-open3d)")
    V, F = knot_arrays()
    Vr, _ = knot_reference()
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V),
                                  o3d.utility.Vector3iVector(F.astype(np.int32)))
    rng = np.random.default_rng(4)
    col = rng.random((len(V), 3))
    uv = rng.random((3 * len(F), 2))
    m.vertex_colors = o3d.utility.Vector3dVector(col)
    m.triangle_uvs = o3d.utility.Vector2dVector(uv)
    m.compute_vertex_normals()
    m2 = mcf.smooth(m)
    assert isinstance(m2, o3d.geometry.TriangleMesh)
    assert np.array_equal(np.asarray(m2.vertices), Vr)
    assert np.array_equal(np.asarray(m2.vertex_colors), col)
    assert np.array_equal(np.asarray(m2.triangle_uvs), uv)
    assert not np.array_equal(np.asarray(m2.vertex_normals), np.asarray(m.vertex_normals))
    assert np.array_equal(np.asarray(m.vertices), V)


def test_typed_errors():
    """The daemon's codes and mcf's messages: a bad parameter, bytes that
    are no mesh, an unknown kind of input."""
    V, F = knot_arrays()
    for call, cls, code, text in [
            (lambda: mcf.smooth((V, F), strength="x"), mcf.InvalidParameter, "EINVAL",
             "parameter 'strength' must be a number"),
            (lambda: mcf.smooth((V, F), nonsense=1), mcf.InvalidParameter, "EINVAL", "nonsense"),
            (lambda: mcf.smooth(b"no mesh here"), mcf.MeshError, "EFORMAT", "unknown mesh format"),
            (lambda: mcf.smooth((V, F + 10 ** 6)), mcf.MeshError, None, "")]:
        try:
            call()
        except cls as e:
            assert code is None or e.code == code, (e.code, code)
            assert text in str(e), str(e)
        else:
            raise AssertionError("no %s" % cls.__name__)
    try:
        mcf.smooth(42)
    except TypeError as e:
        assert "Open3D TriangleMesh" in str(e)
    else:
        raise AssertionError("no TypeError")


def test_progress_and_cancel():
    """progress: every phase and step, done never decreasing, ending at 1;
    a true return cancels (Canceled, ECANCELED); an exception in the
    callback cancels and comes back out."""
    V, F = knot_arrays()
    seen = []
    mcf.smooth((V, F), progress=seen.append)
    done = [p["done"] for p in seen]
    assert len(seen) >= 5 and done == sorted(done) and done[-1] == 1.0, done
    assert {"setup", "noise", "output"} <= set(p["phase"] for p in seen)
    try:
        mcf.smooth((V, F), progress=lambda p: True)
    except mcf.Canceled as e:
        assert e.code == "ECANCELED"
    else:
        raise AssertionError("not canceled")

    def boom(p):
        raise KeyError("from the callback")
    try:
        mcf.smooth((V, F), progress=boom)
    except KeyError as e:
        assert "from the callback" in str(e)
    else:
        raise AssertionError("the callback's exception was lost")


def test_gil_released():
    """While the library works on the bunny, another Python thread runs:
    the main thread counts loop turns strictly inside the call (between
    the worker's timestamps); with the GIL held it could count none."""
    with open(BUNNY, "rb") as f:
        data = f.read()
    span = {}

    def work():
        span["t0"] = time.monotonic()
        mcf.smooth(data, format="ply")
        span["t1"] = time.monotonic()
    t = threading.Thread(target=work)
    stamps = []
    t.start()
    while t.is_alive():
        stamps.append(time.monotonic())
        time.sleep(0.001)
    t.join()
    inside = [s for s in stamps if span["t0"] < s < span["t1"]]
    # the switch interval is 5 ms: a run of 100+ ms gives dozens of turns
    assert len(inside) >= 10, (len(inside), span["t1"] - span["t0"])


def test_warnings_and_metrics():
    """with_metrics: the daemon's metrics document; a warning of the
    library comes as a SmoothingWarning naming it."""
    V, F = knot_arrays()
    (V2, F2), m = mcf.smooth((V, F), with_metrics=True)
    assert m["scheme"] and m["flow"]["steps"] >= 1 and m["input"]["vertices"] == len(V)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        mcf.smooth((V, F), scheme="desbrun2", strength=20)
    names = [x.message.name for x in w if isinstance(x.message, mcf.SmoothingWarning)]
    assert "area_loss" in names, names


def test_call_overhead():
    """Why ctypes (mcf's docstring): a call into the library costs about a
    microsecond, a job on the smallest test mesh thousands of times that."""
    lib = mcf._load()
    n = 20000
    call = timeit.timeit(lib.mcfpy_version, number=n) / n
    V, F = knot_arrays()
    t0 = time.process_time()
    mcf.smooth((V, F), iterations=1)
    job = time.process_time() - t0
    print("ctypes call %.2f us, one job on the knot %.1f ms" % (call * 1e6, job * 1e3))
    assert call * 1000 < job


def test_smooth_files_pool():
    """smooth_files: many files through a process pool, each the same
    bytes as mcf smooth."""
    srcs = [BUNNY, KNOT, os.path.join(MESHES, "sphere_cgal.obj")]
    outs = mcf.smooth_files(srcs, os.path.join(TMP, "batch"), processes=2, iterations=2)
    assert [os.path.basename(o) for o in outs] == [os.path.basename(s) for s in srcs]
    for s, o in zip(srcs, outs):
        with open(o, "rb") as f:
            assert f.read() == mcf_cli(s, os.path.join(TMP, "one" + os.path.splitext(s)[1]),
                                       "--iterations", "2"), s


def test_pip_install():
    """pip installs the package from the repository into a virtual
    environment (Debian's pip, offline, the system's numpy), with the
    library inside; the installed copy smooths arrays with no daemon and
    equals mcf smooth."""
    venv = os.path.join(TMP, "venv")
    subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], check=True)
    env = dict(os.environ, MCF_BUILD=BUILD)
    env.pop("MCF_LIBRARY", None)
    r = subprocess.run([os.path.join(venv, "bin", "pip"), "install", "-q", "--no-index",
                        "--no-build-isolation", os.path.join(ROOT, "clients", "python")],
                       capture_output=True, text=True, env=env, cwd=TMP)
    assert r.returncode == 0, r.stdout + r.stderr
    V, F = knot_arrays()
    np.save(os.path.join(TMP, "V.npy"), V)
    np.save(os.path.join(TMP, "F.npy"), F)
    code = ("import sys, numpy as np, mcf; assert mcf.__file__.startswith(sys.argv[1]), mcf.__file__;"
            "V2, F2 = mcf.smooth((np.load('V.npy'), np.load('F.npy'))); np.save('V2.npy', V2)")
    env.pop("MCF_BUILD")
    r = subprocess.run([os.path.join(venv, "bin", "python"), "-c", code, venv], env=env,
                       capture_output=True, text=True, cwd=TMP)
    assert r.returncode == 0, r.stdout + r.stderr
    assert np.array_equal(np.load(os.path.join(TMP, "V2.npy")), knot_reference()[0])


if __name__ == "__main__":
    if os.environ.get("MCF_SAN"):
        # a sanitized libmcfpy.so needs its runtime preloaded into Python
        print("[==========] Running 0 test(s).\n[  PASSED  ] 0 test(s).")
        sys.exit(0)
    sys.exit(testlib.run_tests([test_same_bytes_as_mcf, test_arrays_equal_mcf,
                                test_duck_typed_mesh, test_open3d_mesh, test_typed_errors,
                                test_progress_and_cancel, test_gil_released,
                                test_warnings_and_metrics, test_call_overhead,
                                test_smooth_files_pool, test_pip_install]))
