#!/bin/sh
# SPDX-License-Identifier: MIT
# make_seeds.sh - regenerates the seed corpora tests/fuzz/corpus_<name>/.
#
# Every seed is a small file written here (a tetrahedron, a cube of quads,
# an octahedron), never a copy of ../shared/meshes. Draco seeds come from
# Debian's draco_encoder (both methods, several levels and quantizations,
# extra attributes, a point cloud) and from our own encoder through the
# `mcf convert` CLI (float64 lossless, sequential). Run from the top of the
# tree after `make build/mcf`:  sh tests/fuzz/make_seeds.sh (corpus_h2gate:
# make_h2gate_seeds.py, run at the end)
set -eu
F=tests/fuzz
MCF=${MCF:-build/mcf}
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT

for n in obj ply stl off draco gltf roundtrip params query; do
  rm -rf "$F/corpus_$n"; mkdir -p "$F/corpus_$n"
done

# ---------------------------------------------------------------- OBJ
cat > $F/corpus_obj/tetra.obj <<'EOF'
# tetrahedron
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
f 1 3 2
f 1 2 4
f 2 3 4
f 1 4 3
EOF
cat > $F/corpus_obj/cube_quads.obj <<'EOF'
o cube
v -1 -1 -1
v 1 -1 -1
v 1 1 -1
v -1 1 -1
v -1 -1 1
v 1 -1 1
v 1 1 1
v -1 1 1
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
g side
usemtl m
s off
f 1/1/1 4/2/1 3/3/1 2/1/1
f 5//1 6//1 7//1 8//1
f -8 -7 -3 -4
f 2 3 7 6
f 3 4 8 7
f 4/1 1/2 5/3 8/1
EOF
printf 'v 0.5 1e-3 -2.5e+2\r\nv 1 0 0 1.0\r\nv 0 1 0 0.5 0.5 0.5\r\nf 1 2 3 # c\r\n' > $F/corpus_obj/crlf.obj

# ---------------------------------------------------------------- PLY
python3 - "$F" <<'EOF'
import struct, sys
F = sys.argv[1]
X = [(0,0,0),(1,0,0),(0,1,0),(0,0,1)]
T = [(0,2,1),(0,1,3),(1,2,3),(0,3,2)]
def hdr(fmt, extra_v='', extra_f='', other=''):
    return ('ply\nformat %s 1.0\ncomment seed\n%selement vertex 4\n%sproperty float x\n'
            'property float y\nproperty float z\nelement face 4\n'
            'property list uchar int vertex_indices\n%send_header\n'
            % (fmt, other, extra_v, extra_f)).encode()
open(F + '/corpus_ply/tetra_ascii.ply', 'wb').write(hdr('ascii') + b''.join(
    b'%g %g %g\n' % v for v in X) + b''.join(b'3 %d %d %d\n' % t for t in T))
for fmt, e in (('binary_little_endian', '<'), ('binary_big_endian', '>')):
    body = b''.join(struct.pack(e + 'fff', *v) for v in X) + \
           b''.join(struct.pack(e + 'Biii', 3, *t) for t in T)
    open(F + '/corpus_ply/tetra_%s.ply' % ('le' if e == '<' else 'be'), 'wb').write(hdr(fmt) + body)
# extra properties, another element, a quad face, vertex_index, double xyz
h = (b'ply\nformat binary_little_endian 1.0\nelement edge 1\nproperty int a\n'
     b'property list ushort short l\nelement vertex 4\nproperty uchar red\n'
     b'property double x\nproperty double y\nproperty double z\nproperty short s\n'
     b'element face 2\nproperty float q\nproperty list uint ushort vertex_index\n'
     b'end_header\n')
body = struct.pack('<iHhh', 7, 2, -1, 1)
body += b''.join(struct.pack('<Bdddh', 9, *v, -3) for v in X)
body += struct.pack('<fIHHHH', 0.5, 4, 0, 1, 2, 3) + struct.pack('<fIHHH', 0.5, 3, 0, 3, 2)
open(F + '/corpus_ply/extras_le.ply', 'wb').write(h + body)
open(F + '/corpus_ply/quad_ascii.ply', 'wb').write(
    b'ply\r\nformat ascii 1.0\r\nelement vertex 4\r\nproperty int x\r\nproperty int y\r\n'
    b'property int z\r\nproperty list uchar float uv\r\nelement face 1\r\n'
    b'property list char uint vertex_indices\r\nend_header\r\n'
    b'0 0 0 2 0.5 0.5\r\n1 0 0 0\r\n1 1 0 0\r\n0 1 0 1 9\r\n4 0 1 2 3\r\n')

# ---------------------------------------------------------------- STL
def stl_ascii(tris, name='seed'):
    s = 'solid %s\n' % name
    for t in tris:
        s += ' facet normal 0 0 1\n  outer loop\n'
        for v in t:
            s += '   vertex %g %g %g\n' % X[v]
        s += '  endloop\n endfacet\n'
    return (s + 'endsolid %s\n' % name).encode()
open(F + '/corpus_stl/tetra_ascii.stl', 'wb').write(stl_ascii(T))
def stl_bin(tris, head=b'seed binary'):
    b = head.ljust(80, b'\0') + struct.pack('<I', len(tris))
    for t in tris:
        b += struct.pack('<3f', 0, 0, 1) + b''.join(struct.pack('<3f', *X[v]) for v in t) + b'\0\0'
    return b
open(F + '/corpus_stl/tetra_bin.stl', 'wb').write(stl_bin(T))
open(F + '/corpus_stl/solid_header_bin.stl', 'wb').write(stl_bin(T, b'solid looks ascii'))
open(F + '/corpus_stl/one_line.stl', 'wb').write(
    b'solid x facet normal 0 0 1 outer loop vertex 0 0 0 vertex 1 0 0 vertex 1 1 0 '
    b'vertex 0 1 0 endloop endfacet endsolid x\nsolid y\nendsolid y\n')

# ---------------------------------------------------------------- OFF
open(F + '/corpus_off/tetra.off', 'wb').write(b'OFF\n4 4 6\n' + b''.join(
    b'%g %g %g\n' % v for v in X) + b''.join(b'3 %d %d %d\n' % t for t in T))
open(F + '/corpus_off/coff_quad.off', 'wb').write(
    b'# comment\nCOFF 4 1 0 # counts\n\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n'
    b'1 1 0 0 0 255 255 # c\n0 1 0 1 1 1 1\n4 0 1 2 3 0.1 0.2 0.3 1\n')
open(F + '/corpus_off/noff_crlf.off', 'wb').write(
    b'NOFF\r\n3 1\r\n0 0 0 0 0 1\r\n1 0 0 0 0 1\r\n0 1 0 0 0 1\r\n3 0 1 2\r\n')

# ---------------------------------------------------------- parameters
P = F + '/corpus_params/'
for i, j in enumerate([
        '{}',
        '{"scheme":"desbrun2","dt":1e-3,"iterations":10}',
        '{"scheme":"euler","dt":"auto","time":0.01,"boundary":"free"}',
        '{"fixed_vertices":[0,1,2,3],"rescale":"volume","normalize":false}',
        '{"laplacian":"uniform","mass":"voronoi","adaptive":true,"tol":1e-4,"max_steps":50}',
        '{"format":"draco","quantization_bits":14,'
        '"compression_level":10,"preserve_order":true,"ply_binary":false}',
        '{"scheme":"ros2","dt":0.5,"iterations":3,"scheme":"taubin"}',
        '{"a":{"b":[1,[2,[3]]]},"dt":-1}']):
    open(P + 'p%d.json' % i, 'w').write(j)
Q = F + '/corpus_query/'
for i, q in enumerate([
        'scheme=desbrun2&dt=1e-3&iterations=10',
        'dt=auto&scheme=euler&async=1&callback=http%3A%2F%2Fx',
        'fixed_vertices=0,1,2&boundary=free&normalize=0',
        'format=ply&ply_binary=false',
        'scheme=%64esbrun&time=1e-2&&=&x',
        'quantization_bits=30&compression_level=0&preserve_order=true']):
    open(Q + 'q%d.txt' % i, 'w').write(q)
EOF

# ---------------------------------------------------------------- Draco
cat > $T/oct.obj <<'EOF'
v 1 0 0
v -1 0 0
v 0 1 0
v 0 -1 0
v 0 0 1
v 0 0 -1
vt 0 0
vt 1 0
vt 0 1
vn 0 0 1
vn 0 0 -1
f 1/1/1 3/2/1 5/3/1
f 3/1/1 2/2/1 5/3/1
f 2/1/1 4/2/1 5/3/1
f 4/1/1 1/2/1 5/3/1
f 3/1/2 1/2/2 6/3/2
f 2/1/2 3/2/2 6/3/2
f 4/1/2 2/2/2 6/3/2
f 1/1/2 4/2/2 6/3/2
EOF
D=$F/corpus_draco
draco_encoder -i $T/oct.obj -o $D/oct_cl7_qp11.drc >/dev/null
draco_encoder -i $T/oct.obj -o $D/oct_cl0_qp0.drc -cl 0 -qp 0 >/dev/null
draco_encoder -i $T/oct.obj -o $D/oct_cl10_qp14.drc -cl 10 -qp 14 >/dev/null
draco_encoder -i $T/oct.obj -o $D/oct_cl4_qp8.drc -cl 4 -qp 8 >/dev/null
draco_encoder -i $F/corpus_obj/cube_quads.obj -o $D/cube_cl10_qp0.drc -cl 10 -qp 0 >/dev/null
draco_encoder -i $T/oct.obj -o $D/oct_pointcloud.drc -point_cloud >/dev/null
if [ -x "$MCF" ]; then
  "$MCF" convert $F/corpus_obj/crlf.obj $D/crlf_f64.drc --preserve-order >/dev/null
  "$MCF" convert $F/corpus_obj/tetra.obj $D/tetra_f32.drc >/dev/null
  "$MCF" convert $F/corpus_obj/cube_quads.obj $D/cube_q10_seq.drc \
    --quantization-bits 10 --preserve-order >/dev/null
fi

# ---------------------------------------------------------------- glTF
# A one-triangle .gltf by hand (buffer as a data: URI, a triangle and a
# strip primitive), then GLB and .gltf written by `mcf convert` (new
# documents: plain, and KHR_draco_mesh_compression from a Draco input).
G=$F/corpus_gltf
cat > $G/tri.gltf <<'EOF'
{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"translation":[1,0,0]}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":2},"indices":1,"mode":4},{"attributes":{"POSITION":0},"indices":1,"mode":5}]}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},
{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},
{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
"bufferViews":[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
"buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}]}
EOF
if [ -x "$MCF" ]; then
  "$MCF" convert $F/corpus_obj/tetra.obj $G/tetra.glb >/dev/null
  "$MCF" convert $F/corpus_obj/cube_quads.obj $G/cube.gltf >/dev/null
  "$MCF" convert $F/corpus_draco/oct_cl7_qp11.drc $G/oct_draco.glb >/dev/null
  "$MCF" convert $F/corpus_draco/oct_cl7_qp11.drc $G/oct_draco.gltf >/dev/null
fi

# ----------------------------------------------------------- roundtrip
for n in obj ply stl off draco gltf; do
  for f in $F/corpus_$n/*; do
    case $f in *pointcloud*) continue;; esac
    cp "$f" $F/corpus_roundtrip/
  done
done
# ---------------------------------------------------------------- the gRPC door's gate
/usr/bin/python3 $F/make_h2gate_seeds.py

ls -l $F/corpus_* | awk '/^total/ {next} {s += $5} END {print "seed bytes:", s}'
