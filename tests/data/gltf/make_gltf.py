#!/usr/bin/python3
"""make_gltf.py - writes the small glTF test files of tests/data/gltf/ from
tests/data/meshes/sphere_cgal.obj (CGAL's sphere, CC0: tests/data/meshes/
SOURCES.md), with the standard library only. Run from the top of the tree:

    /usr/bin/python3 tests/data/gltf/make_gltf.py

sphere_2prims.gltf  the sphere cut into two primitives by the sign of each
                    face's centroid z (two materials), each primitive with
                    its own vertices (so the equator's vertices exist twice,
                    as exporters write material seams), POSITION, NORMAL
                    (the sphere's smooth vertex normals, equal on both sides
                    of the seam), TEXCOORD_0 (a spherical map), uint16
                    indices; a parent node with translation and a child with
                    rotation and scale; a camera and extras that must pass
                    through; one buffer as a base64 data: URI.
sphere_2prims.glb   the same as GLB, primitive 0's POSITION and NORMAL
                    interleaved in one buffer view (byteStride 24), an
                    8-byte image in a buffer view (never decoded), and a
                    LINES primitive over primitive 0's POSITION accessor.
car_draco.glb       tests/data/meshes/car.drc (Draco's own test file,
                    Apache-2.0) as a KHR_draco_mesh_compression GLB, written
                    by `mcf convert` (build/mcf, or $MCF).
draco_bomb.glb      tests/data/draco_texcoord_orientations.drc (the 210-byte
                    stream that costs libdraco 8.8 s and 256 MiB) wrapped in
                    a GLB as a Draco primitive: the daemon must decode it in
                    its sandbox, as the bare stream.
"""
import base64
import json
import math
import os
import struct
import subprocess

HERE = os.path.dirname(os.path.abspath(__file__))
TOP = os.path.join(HERE, "..", "..", "..")
OBJ = os.path.join(HERE, "..", "meshes", "sphere_cgal.obj")


def read_obj(path):
    V, F = [], []
    for line in open(path):
        t = line.split()
        if not t:
            continue
        if t[0] == "v":
            V.append(tuple(float(x) for x in t[1:4]))
        elif t[0] == "f":
            F.append(tuple(int(x.split("/")[0]) - 1 for x in t[1:4]))
    return V, F


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def main():
    V, F = read_obj(OBJ)
    # smooth vertex normals of the whole sphere (area weighted)
    N = [[0.0, 0.0, 0.0] for _ in V]
    for a, b, c in F:
        p, q, r = V[a], V[b], V[c]
        u = [q[i] - p[i] for i in range(3)]
        v = [r[i] - p[i] for i in range(3)]
        n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        for k in (a, b, c):
            for i in range(3):
                N[k][i] += n[i]
    N = [[x / math.sqrt(sum(y * y for y in n)) for x in n] for n in N]
    prims = [[], []]
    for f in F:
        z = sum(V[k][2] for k in f)
        prims[0 if z >= 0 else 1].append(f)

    def build(interleave_first, glb):
        blob = bytearray()
        views, accs, meshprims = [], [], []

        def view(data, stride=None, target=34962):
            while len(blob) % 4:
                blob.append(0)
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                          "target": target})
            if stride:
                views[-1]["byteStride"] = stride
            blob.extend(data)
            return len(views) - 1

        def acc(v, count, ctype, typ, off=0, mn=None, mx=None):
            a = {"bufferView": v, "componentType": ctype, "count": count, "type": typ}
            if off:
                a["byteOffset"] = off
            if mn is not None:
                a["min"], a["max"] = mn, mx
            accs.append(a)
            return len(accs) - 1

        for pi, faces in enumerate(prims):
            used = sorted({k for f in faces for k in f})
            ren = {k: i for i, k in enumerate(used)}
            P = [V[k] for k in used]
            mn = [min(f32(p[i]) for p in P) for i in range(3)]
            mx = [max(f32(p[i]) for p in P) for i in range(3)]
            uv = []
            for k in used:
                x, y, z = N[k]
                uv.append((math.atan2(y, x) / (2 * math.pi) + 0.5,
                           math.acos(max(-1.0, min(1.0, z))) / math.pi))
            if interleave_first and pi == 0:
                data = b"".join(struct.pack("<6f", *V[k], *N[k]) for k in used)
                v = view(data, stride=24)
                pa = acc(v, len(used), 5126, "VEC3", 0, mn, mx)
                na = acc(v, len(used), 5126, "VEC3", 12)
            else:
                pa = acc(view(b"".join(struct.pack("<3f", *V[k]) for k in used)),
                         len(used), 5126, "VEC3", 0, mn, mx)
                na = acc(view(b"".join(struct.pack("<3f", *N[k]) for k in used)),
                         len(used), 5126, "VEC3")
            ta = acc(view(b"".join(struct.pack("<2f", *t) for t in uv)), len(used), 5126, "VEC2")
            ia = acc(view(b"".join(struct.pack("<3H", *(ren[k] for k in f)) for f in faces),
                          target=34963), 3 * len(faces), 5123, "SCALAR")
            meshprims.append({"attributes": {"POSITION": pa, "NORMAL": na, "TEXCOORD_0": ta},
                              "indices": ia, "material": pi})
            if glb and pi == 0:
                # a LINES primitive over the same POSITION accessor
                edges = [(ren[f[0]], ren[f[1]]) for f in faces[:50]]
                la = acc(view(b"".join(struct.pack("<2H", *e) for e in edges), target=34963),
                         2 * len(edges), 5123, "SCALAR")
                meshprims.append({"attributes": {"POSITION": pa}, "indices": la, "mode": 1})
        doc = {
            "asset": {"version": "2.0", "generator": "mcfd tests/data/gltf/make_gltf.py"},
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [{"name": "parent", "translation": [1.0, 2.0, 3.0], "children": [1]},
                      {"name": "sphere", "mesh": 0, "rotation": [0.0, 0.0, 0.7071068, 0.7071068],
                       "scale": [2.0, 2.0, 2.0], "extras": {"scan": "cgal-sphere"}},
                      {"name": "eye", "camera": 0, "translation": [0.0, 0.0, 5.0]}],
            "cameras": [{"type": "perspective",
                         "perspective": {"yfov": 0.8, "znear": 0.01, "zfar": 100.0}}],
            "materials": [{"name": "north", "pbrMetallicRoughness":
                           {"baseColorFactor": [0.8, 0.2, 0.2, 1.0], "metallicFactor": 0.0}},
                          {"name": "south", "pbrMetallicRoughness":
                           {"baseColorFactor": [0.2, 0.2, 0.8, 1.0], "metallicFactor": 0.0}}],
            "meshes": [{"name": "sphere", "primitives": meshprims}],
            "accessors": accs,
            "bufferViews": views,
            "extras": {"note": "passes through"},
        }
        doc["scenes"][0]["nodes"].append(2)
        if glb:
            iv = view(b"\x89PNG\r\n\x1a\n", target=None)
            del views[iv]["target"]
            doc["images"] = [{"bufferView": iv, "mimeType": "image/png"}]
        while len(blob) % 4:
            blob.append(0)
        if glb:
            doc["buffers"] = [{"byteLength": len(blob)}]
            j = json.dumps(doc, separators=(",", ":")).encode()
            j += b" " * (-len(j) % 4)
            return (b"glTF" + struct.pack("<II", 2, 12 + 8 + len(j) + 8 + len(blob)) +
                    struct.pack("<I", len(j)) + b"JSON" + j +
                    struct.pack("<I", len(blob)) + b"BIN\0" + bytes(blob))
        doc["buffers"] = [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                           + base64.b64encode(bytes(blob)).decode()}]
        return json.dumps(doc, indent=1).encode()

    open(os.path.join(HERE, "sphere_2prims.gltf"), "wb").write(build(False, False))
    open(os.path.join(HERE, "sphere_2prims.glb"), "wb").write(build(True, True))


def glb(doc, blob):
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    blob = blob + b"\0" * (-len(blob) % 4)
    return (b"glTF" + struct.pack("<II", 2, 12 + 8 + len(j) + 8 + len(blob)) +
            struct.pack("<I", len(j)) + b"JSON" + j + struct.pack("<I", len(blob)) + b"BIN\0" + blob)


def wrap_drc(drc, npoints, nfaces):
    """A GLB whose one primitive is the Draco stream drc (POSITION id 0)."""
    doc = {"asset": {"version": "2.0", "generator": "mcfd tests/data/gltf/make_gltf.py"},
           "extensionsUsed": ["KHR_draco_mesh_compression"],
           "extensionsRequired": ["KHR_draco_mesh_compression"],
           "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                       "extensions": {"KHR_draco_mesh_compression":
                                                      {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}],
           "accessors": [{"componentType": 5126, "count": npoints, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 1]},
                         {"componentType": 5123, "count": 3 * nfaces, "type": "SCALAR"}],
           "bufferViews": [{"buffer": 0, "byteLength": len(drc)}],
           "buffers": [{"byteLength": len(drc) + (-len(drc) % 4)}]}
    return glb(doc, drc)


if __name__ == "__main__":
    main()
    bomb = open(os.path.join(HERE, "..", "draco_texcoord_orientations.drc"), "rb").read()
    open(os.path.join(HERE, "draco_bomb.glb"), "wb").write(wrap_drc(bomb, 3, 1))
    mcf = os.environ.get("MCF", os.path.join(TOP, "build", "mcf"))
    subprocess.run([mcf, "convert", os.path.join(HERE, "..", "meshes", "car.drc"),
                    os.path.join(HERE, "car_draco.glb")], check=True)
