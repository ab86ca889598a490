/* SPDX-License-Identifier: MIT */
/*
 * api_gltf.cc - the glTF 2.0 reader's C++ side: a thin extern "C" bridge
 * over Debian's tinygltf 2.7 (api__gltf_parse, api_internal.h), compiled
 * here without file system access (TINYGLTF_NO_FS, no external images) and
 * without image decoding (images pass through as bytes nobody reads).
 *
 * tinygltf parses the container (GLB chunks, data: URIs, the JSON into
 * typed objects); this file then reads what the smoothing needs from every
 * triangle primitive (mode 4, 5, 6) of every mesh: indices (strips and
 * fans unrolled into triangles), POSITION, NORMAL, TEXCOORD_0 and COLOR_0,
 * each accessor checked first (type, component type, count against the
 * limits, element within its buffer view and the view within its buffer,
 * stride), and where POSITION and NORMAL lie so the encoder can write
 * them in place. A KHR_draco_mesh_compression primitive is decoded by
 * api_draco.cc (api__draco_prim_decode: every attribute kept). The JSON
 * reached tinygltf only after api_gltf_decode.c's checks (nesting, size,
 * duplicate keys, buffer and view bounds, URIs), which also protect
 * tinygltf's own reading of images from buffer views.
 *
 * Refused, with the primitive named: sparse POSITION or NORMAL accessors
 * and indices (the encoder writes dense data in place), a POSITION without
 * data, non-float positions or normals, Draco primitives with uncompressed
 * fallback data or attributes outside the stream. Every entry point
 * catches all C++ exceptions (bad_alloc: ENOMEM, else EDECODE).
 */
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_FS
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <fstream> /* tiny_gltf.h uses it without including it */
#include <tiny_gltf.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "draco/core/draco_types.h"

#include "api.h"
extern "C" {
#include "api_internal.h"
}

namespace {

/* Images are not decoded: their bytes stay in the document untouched. */
bool no_image(tinygltf::Image *, const int, std::string *, std::string *, int,
              int, const unsigned char *, int, void *)
{
    return true;
}

/* The first line of tinygltf's message, for a one-line error. */
std::string first_line(const std::string &s)
{
    const size_t nl = s.find('\n');
    std::string l = s.substr(0, nl == std::string::npos ? s.size() : nl);
    return l.size() > 160 ? l.substr(0, 160) + "..." : l;
}

/* What a primitive is called in messages. */
struct where {
    int mesh, prim;
};

/* A located accessor: count elements of ncomp components of ctype, the
 * first at byte off of buffer buf, stride apart. */
struct located {
    int count = 0, ncomp = 0, ctype = 0, buf = -1, stride = 0;
    bool normalized = false;
    long long off = 0;
};

int comp_size(int ct)
{
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

int type_comps(int t)
{
    switch (t) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    default: return 0;
    }
}

/* Accessor ai (what: "POSITION", "indices", ...) checked: its type one of
 * the ncomp_ok component counts (a bit per count), its component type in
 * ctypes (0-terminated), at most max_count elements, dense, and every
 * element inside its view and buffer. */
mcf_status locate(const tinygltf::Model &m, int ai, const char *what, where w,
                  unsigned ncomp_ok, const int *ctypes, long long max_count,
                  located *out, mcf_error *err)
{
    if (ai < 0 || static_cast<size_t>(ai) >= m.accessors.size())
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: %s accessor %d does not exist",
                         w.mesh, w.prim, what, ai);
    const tinygltf::Accessor &a = m.accessors[static_cast<size_t>(ai)];
    const int nc = type_comps(a.type), cs = comp_size(a.componentType);
    bool ct_ok = false;
    for (const int *c = ctypes; *c; c++)
        ct_ok = ct_ok || *c == a.componentType;
    if (nc == 0 || !(ncomp_ok & (1u << nc)) || !ct_ok || cs == 0)
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: %s accessor %d has type %d "
                         "of component type %d, not one glTF allows there",
                         w.mesh, w.prim, what, ai, a.type, a.componentType);
    if (a.sparse.isSparse)
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: %s accessor %d is sparse "
                         "(mcfd reads dense accessors only there)",
                         w.mesh, w.prim, what, ai);
    if (a.count < 1 || static_cast<long long>(a.count) > max_count)
        return api__fail(err, a.count < 1 ? MCF_EDECODE : MCF_ELIMIT,
                         "gltf: mesh %d primitive %d: %s accessor %d has %zu "
                         "elements (1 to %lld allowed)",
                         w.mesh, w.prim, what, ai, a.count, max_count);
    if (a.bufferView < 0 || static_cast<size_t>(a.bufferView) >= m.bufferViews.size())
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: %s accessor %d has no data "
                         "(buffer view %d)",
                         w.mesh, w.prim, what, ai, a.bufferView);
    const tinygltf::BufferView &v = m.bufferViews[static_cast<size_t>(a.bufferView)];
    if (v.buffer < 0 || static_cast<size_t>(v.buffer) >= m.buffers.size())
        return api__fail(err, MCF_EDECODE, "gltf: buffer view %d: no buffer %d",
                         a.bufferView, v.buffer);
    const size_t blen = m.buffers[static_cast<size_t>(v.buffer)].data.size();
    const unsigned long long elem = static_cast<unsigned long long>(nc) * cs;
    const unsigned long long stride = v.byteStride ? v.byteStride : elem;
    /* Every quantity below 2^40 (sizes within the input), so no sum or
     * product overflows 64 bits. */
    if (v.byteOffset > blen || v.byteLength > blen - v.byteOffset ||
        a.byteOffset > v.byteLength || stride < elem || a.byteOffset % cs != 0 ||
        (v.byteOffset + a.byteOffset) % cs != 0 ||
        a.byteOffset + stride * (a.count - 1) + elem > v.byteLength)
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: %s accessor %d (%zu elements of "
                         "%llu bytes, %llu apart, from byte %zu) does not fit its "
                         "buffer view %d (%zu bytes at %zu of a %zu-byte buffer), "
                         "or is misaligned",
                         w.mesh, w.prim, what, ai, a.count, elem, stride, a.byteOffset,
                         a.bufferView, v.byteLength, v.byteOffset, blen);
    out->count = static_cast<int>(a.count);
    out->ncomp = nc;
    out->ctype = a.componentType;
    out->normalized = a.normalized;
    out->buf = v.buffer;
    out->stride = static_cast<int>(stride);
    out->off = static_cast<long long>(v.byteOffset + a.byteOffset);
    return MCF_OK;
}

/* Component c of element i of a located accessor, as glTF defines its
 * value (normalized integers divided by their maximum, signed ones
 * clamped at -1). */
double component(const tinygltf::Model &m, const located &l, int i, int c)
{
    const unsigned char *p = m.buffers[static_cast<size_t>(l.buf)].data.data() + l.off +
                             static_cast<long long>(l.stride) * i + c * comp_size(l.ctype);
    switch (l.ctype) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); return f; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t u; std::memcpy(&u, p, 4); return u; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t u; std::memcpy(&u, p, 2); return l.normalized ? u / 65535.0 : u; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return l.normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: { int16_t s; std::memcpy(&s, p, 2); return l.normalized ? std::fmax(s / 32767.0, -1.0) : s; }
    case TINYGLTF_COMPONENT_TYPE_BYTE: { int8_t s; std::memcpy(&s, p, 1); return l.normalized ? std::fmax(s / 127.0, -1.0) : s; }
    default: return 0.0;
    }
}

/* A malloc'ed array of n x k doubles (the doc owns it). */
double *doubles(size_t n, int k)
{
    double *d = static_cast<double *>(std::malloc(sizeof(double) * n * k + 1));
    if (!d)
        throw std::bad_alloc();
    return d;
}

const int FLOAT_ONLY[] = {TINYGLTF_COMPONENT_TYPE_FLOAT, 0};
const int FLOAT_OR_UNORM[] = {TINYGLTF_COMPONENT_TYPE_FLOAT,
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                              TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, 0};
const int INDEX_TYPES[] = {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                           TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, 0};

/* Reads a located accessor of n elements into a new n x want array
 * (missing components: 1 for a colour's alpha, else 0). */
double *read_all(const tinygltf::Model &m, const located &l, int want)
{
    double *d = doubles(static_cast<size_t>(l.count), want);
    for (int i = 0; i < l.count; i++)
        for (int c = 0; c < want; c++)
            d[static_cast<size_t>(i) * want + c] =
                c < l.ncomp ? component(m, l, i, c) : (c == 3 ? 1.0 : 0.0);
    return d;
}

/* Attribute slot of the Draco attribute with unique id, or -1. */
int draco_slot(const api__draco_prim &d, int id)
{
    for (int i = 0; i < d.nattr; i++)
        if (d.attr[i].id == id)
            return i;
    return -1;
}

/* Component c of point p of Draco attribute a, as a double (normalized
 * integers divided by their maximum). */
double draco_component(const api__draco_attr &a, int p, int c)
{
    const unsigned char *q = a.data + static_cast<size_t>(p) * a.vsize + c * (a.vsize / a.ncomp);
    double x = 0.0, scale = 0.0;
    switch (a.dtype) {
    case draco::DT_INT8: { int8_t t; std::memcpy(&t, q, 1); x = t; scale = INT8_MAX; break; }
    case draco::DT_UINT8: x = *q; scale = UINT8_MAX; break;
    case draco::DT_INT16: { int16_t t; std::memcpy(&t, q, 2); x = t; scale = INT16_MAX; break; }
    case draco::DT_UINT16: { uint16_t t; std::memcpy(&t, q, 2); x = t; scale = UINT16_MAX; break; }
    case draco::DT_INT32: { int32_t t; std::memcpy(&t, q, 4); x = t; scale = INT32_MAX; break; }
    case draco::DT_UINT32: { uint32_t t; std::memcpy(&t, q, 4); x = t; scale = UINT32_MAX; break; }
    case draco::DT_FLOAT32: { float t; std::memcpy(&t, q, 4); x = t; break; }
    case draco::DT_FLOAT64: { double t; std::memcpy(&t, q, 8); x = t; break; }
    default: return 0.0;
    }
    return a.normalized && scale > 0.0 ? x / scale : x;
}

double *read_draco(const api__draco_attr &a, int npoints, int want)
{
    double *d = doubles(static_cast<size_t>(npoints), want);
    for (int p = 0; p < npoints; p++)
        for (int c = 0; c < want; c++)
            d[static_cast<size_t>(p) * want + c] =
                c < a.ncomp ? draco_component(a, p, c) : (c == 3 ? 1.0 : 0.0);
    return d;
}

/* The attribute index of name in the primitive, or -1. */
int attribute(const tinygltf::Primitive &p, const char *name)
{
    auto it = p.attributes.find(name);
    return it == p.attributes.end() ? -1 : it->second;
}

/* A Draco primitive: the stream decoded, its points the vertices. */
mcf_status read_draco_prim(const tinygltf::Model &m, const tinygltf::Primitive &p,
                           const tinygltf::Value &ext, const api_limits *lim,
                           api__gltf_prim *g, mcf_error *err)
{
    const where w{g->mesh, g->index};
    const tinygltf::Value &bv = ext.Get("bufferView"), &map = ext.Get("attributes");
    if (!bv.IsInt() || !map.IsObject())
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: KHR_draco_mesh_compression "
                         "needs an integer bufferView and an attributes object",
                         w.mesh, w.prim);
    const int vi = bv.Get<int>();
    if (vi < 0 || static_cast<size_t>(vi) >= m.bufferViews.size())
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: Draco buffer view %d does not exist",
                         w.mesh, w.prim, vi);
    if (g->mode != TINYGLTF_MODE_TRIANGLES)
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: a Draco primitive of mode %d "
                         "(triangles, 4, expected)", w.mesh, w.prim, g->mode);
    const tinygltf::BufferView &v = m.bufferViews[static_cast<size_t>(vi)];
    const std::vector<unsigned char> &b = m.buffers[static_cast<size_t>(v.buffer)].data;
    if (v.byteOffset > b.size() || v.byteLength > b.size() - v.byteOffset)
        return api__fail(err, MCF_EDECODE, "gltf: buffer view %d outside its buffer", vi);
    /* Every attribute must come from the stream, with no fallback data
     * (whose vertex order need not be the stream's). */
    for (const auto &kv : p.attributes) {
        const tinygltf::Value &id = map.Get(kv.first);
        /* glTF: a Draco primitive's attributes still name accessors (their
         * counts and types; the encoder rewrites them) */
        if (kv.second < 0 || static_cast<size_t>(kv.second) >= m.accessors.size())
            return api__fail(err, MCF_EDECODE,
                             "gltf: mesh %d primitive %d: attribute %s names accessor %d, "
                             "which does not exist", w.mesh, w.prim, kv.first.c_str(), kv.second);
        const bool has_view = m.accessors[static_cast<size_t>(kv.second)].bufferView >= 0;
        if (!id.IsInt() || has_view)
            return api__fail(err, MCF_EDECODE,
                             "gltf: mesh %d primitive %d: attribute %s %s",
                             w.mesh, w.prim, kv.first.c_str(),
                             has_view ? "has uncompressed fallback data (not supported "
                                        "next to KHR_draco_mesh_compression)"
                                      : "is not in the Draco stream");
        /* one Draco attribute per semantic: a stream attribute named twice
         * (POSITION and NORMAL both 0, made by the fuzzer) decodes, but
         * the rewrite's stream has one attribute per semantic and the
         * document's map no longer matches it (its positions become the
         * normals) */
        for (const auto &kv2 : p.attributes) {
            if (kv2.first == kv.first)
                break;
            const tinygltf::Value &id2 = map.Get(kv2.first);
            if (id2.IsInt() && id2.Get<int>() == id.Get<int>())
                return api__fail(err, MCF_EDECODE,
                                 "gltf: mesh %d primitive %d: attributes %s and %s name the "
                                 "same Draco attribute %d (KHR_draco_mesh_compression: one "
                                 "each)", w.mesh, w.prim, kv2.first.c_str(), kv.first.c_str(),
                                 id.Get<int>());
        }
    }
    g->draco_view = vi;
    mcf_status rc = api__draco_prim_decode(b.data() + v.byteOffset, v.byteLength, lim,
                                           &g->draco, err);
    if (rc != MCF_OK)
        return rc;
    const api__draco_prim &d = g->draco;
    const tinygltf::Value &pid = map.Get("POSITION"), &nid = map.Get("NORMAL"),
                          &tid = map.Get("TEXCOORD_0"), &cid = map.Get("COLOR_0");
    g->draco_pos = pid.IsInt() ? draco_slot(d, pid.Get<int>()) : -1;
    g->draco_nrm = nid.IsInt() ? draco_slot(d, nid.Get<int>()) : -1;
    const int ts = tid.IsInt() ? draco_slot(d, tid.Get<int>()) : -1;
    const int cs = cid.IsInt() ? draco_slot(d, cid.Get<int>()) : -1;
    auto float3 = [&](int s) {
        return s >= 0 && d.attr[s].ncomp == 3 && d.attr[s].dtype == API__DRACO_FLOAT32;
    };
    if (!float3(g->draco_pos) || (nid.IsInt() && !float3(g->draco_nrm)))
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: the Draco stream has no float "
                         "VEC3 %s under the id the extension names",
                         w.mesh, w.prim, float3(g->draco_pos) ? "NORMAL" : "POSITION");
    g->nvert = d.npoints;
    g->ntri = d.nfaces;
    g->tri = static_cast<int32_t *>(std::malloc(3 * sizeof(int32_t) * d.nfaces + 1));
    if (!g->tri)
        throw std::bad_alloc();
    std::memcpy(g->tri, d.faces, 3 * sizeof(int32_t) * d.nfaces);
    g->xyz = read_draco(d.attr[g->draco_pos], d.npoints, 3);
    if (g->draco_nrm >= 0)
        g->nxyz = read_draco(d.attr[g->draco_nrm], d.npoints, 3);
    if (ts >= 0 && d.attr[ts].ncomp == 2)
        g->uv = read_draco(d.attr[ts], d.npoints, 2);
    if (cs >= 0 && d.attr[cs].ncomp >= 3)
        g->rgba = read_draco(d.attr[cs], d.npoints, 4);
    /* The POSITION accessor's min and max are rewritten; its count too. */
    g->pos.acc = attribute(p, "POSITION");
    g->nrm.acc = attribute(p, "NORMAL");
    return MCF_OK;
}

/* A plain primitive: accessors read, indices unrolled into triangles. */
mcf_status read_plain_prim(const tinygltf::Model &m, const tinygltf::Primitive &p,
                           const api_limits *lim, api__gltf_prim *g, mcf_error *err)
{
    const where w{g->mesh, g->index};
    located pos, nrm, uv, col, idx;
    mcf_status rc = locate(m, attribute(p, "POSITION"), "POSITION", w, 1u << 3,
                           FLOAT_ONLY, lim->max_vertices, &pos, err);
    if (rc != MCF_OK)
        return rc;
    g->nvert = pos.count;
    g->pos = api__gltf_at{attribute(p, "POSITION"), pos.buf, pos.stride, pos.off};
    g->xyz = read_all(m, pos, 3);
    for (size_t i = 0; i < 3 * static_cast<size_t>(pos.count); i++)
        if (!std::isfinite(g->xyz[i]))
            return api__fail(err, MCF_EDECODE,
                             "gltf: mesh %d primitive %d: vertex %zu has a non-finite "
                             "coordinate", w.mesh, w.prim, i / 3);
    if (attribute(p, "NORMAL") >= 0) {
        if ((rc = locate(m, attribute(p, "NORMAL"), "NORMAL", w, 1u << 3, FLOAT_ONLY,
                         pos.count, &nrm, err)) != MCF_OK)
            return rc;
        if (nrm.count != pos.count)
            return api__fail(err, MCF_EDECODE,
                             "gltf: mesh %d primitive %d: %d normals for %d positions",
                             w.mesh, w.prim, nrm.count, pos.count);
        g->nrm = api__gltf_at{attribute(p, "NORMAL"), nrm.buf, nrm.stride, nrm.off};
        g->nxyz = read_all(m, nrm, 3);
    }
    /* Texture coordinates and colours only feed other formats' output:
     * one glTF does not read cleanly is left out, not refused. */
    if (attribute(p, "TEXCOORD_0") >= 0 &&
        locate(m, attribute(p, "TEXCOORD_0"), "TEXCOORD_0", w, 1u << 2, FLOAT_OR_UNORM,
               pos.count, &uv, nullptr) == MCF_OK && uv.count == pos.count)
        g->uv = read_all(m, uv, 2);
    if (attribute(p, "COLOR_0") >= 0 &&
        locate(m, attribute(p, "COLOR_0"), "COLOR_0", w, 1u << 3 | 1u << 4,
               FLOAT_OR_UNORM, pos.count, &col, nullptr) == MCF_OK &&
        col.count == pos.count)
        g->rgba = read_all(m, col, 4);

    /* Indices: 3 per triangle (4), or a strip (5) or fan (6) of n - 2. */
    std::vector<uint32_t> ix;
    if (p.indices >= 0) {
        if ((rc = locate(m, p.indices, "indices", w, 1u << 1, INDEX_TYPES,
                         3LL * lim->max_faces + 2, &idx, err)) != MCF_OK)
            return rc;
        ix.resize(static_cast<size_t>(idx.count));
        for (int i = 0; i < idx.count; i++) {
            const double x = component(m, idx, i, 0);
            if (x >= pos.count)
                return api__fail(err, MCF_EDECODE,
                                 "gltf: mesh %d primitive %d: index %d is %.0f, past "
                                 "its %d vertices", w.mesh, w.prim, i, x, pos.count);
            ix[static_cast<size_t>(i)] = static_cast<uint32_t>(x);
        }
    } else {
        ix.resize(static_cast<size_t>(pos.count));
        for (int i = 0; i < pos.count; i++)
            ix[static_cast<size_t>(i)] = static_cast<uint32_t>(i);
    }
    const size_t n = ix.size();
    if (g->mode == TINYGLTF_MODE_TRIANGLES && n % 3 != 0)
        return api__fail(err, MCF_EDECODE,
                         "gltf: mesh %d primitive %d: %zu indices, not a multiple of 3",
                         w.mesh, w.prim, n);
    const size_t nt = g->mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : n >= 3 ? n - 2 : 0;
    if (nt > static_cast<size_t>(lim->max_faces))
        return api__fail(err, MCF_ELIMIT,
                         "gltf: mesh %d primitive %d: %zu triangles exceed max_faces (%d)",
                         w.mesh, w.prim, nt, lim->max_faces);
    g->ntri = static_cast<int>(nt);
    g->tri = static_cast<int32_t *>(std::malloc(3 * sizeof(int32_t) * nt + 1));
    if (!g->tri)
        throw std::bad_alloc();
    for (size_t t = 0; t < nt; t++) {
        size_t a, b, c;
        if (g->mode == TINYGLTF_MODE_TRIANGLES) {
            a = 3 * t; b = 3 * t + 1; c = 3 * t + 2;
        } else if (g->mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            /* every other triangle of a strip turns the other way */
            a = t % 2 ? t + 1 : t; b = t % 2 ? t : t + 1; c = t + 2;
        } else {
            a = 0; b = t + 1; c = t + 2;
        }
        g->tri[3 * t] = static_cast<int32_t>(ix[a]);
        g->tri[3 * t + 1] = static_cast<int32_t>(ix[b]);
        g->tri[3 * t + 2] = static_cast<int32_t>(ix[c]);
    }
    return MCF_OK;
}

mcf_status parse(const void *buf, size_t len, const char *json_text, size_t json_len,
                 const api_limits *lim, api__gltf_doc *doc, mcf_error *err)
{
    tinygltf::TinyGLTF loader;
    tinygltf::Model m;
    std::string e, wn;
    loader.SetImageLoader(no_image, nullptr);
    const bool glb = doc->container == API_FMT_GLB;
    const bool ok = glb ? loader.LoadBinaryFromMemory(
                              &m, &e, &wn, static_cast<const unsigned char *>(buf),
                              static_cast<unsigned int>(len), "")
                        : loader.LoadASCIIFromString(&m, &e, &wn,
                                                     static_cast<const char *>(buf),
                                                     static_cast<unsigned int>(len), "");
    if (!ok)
        return api__fail(err, MCF_EDECODE, "gltf: %s",
                         first_line(e.empty() ? "tinygltf refused the document" : e).c_str());

    /* The document: the JSON text as it came, the buffers' bytes. */
    doc->json = static_cast<char *>(std::malloc(json_len + 1));
    doc->buf = static_cast<unsigned char **>(std::calloc(m.buffers.size() + 1, sizeof(unsigned char *)));
    doc->buf_len = static_cast<size_t *>(std::calloc(m.buffers.size() + 1, sizeof(size_t)));
    if (!doc->json || !doc->buf || !doc->buf_len)
        throw std::bad_alloc();
    std::memcpy(doc->json, json_text, json_len);
    doc->json[json_len] = '\0';
    doc->json_len = json_len;
    for (size_t i = 0; i < m.buffers.size(); i++) {
        const std::vector<unsigned char> &d = m.buffers[i].data;
        doc->buf[i] = static_cast<unsigned char *>(std::malloc(d.size() + 1));
        if (!doc->buf[i])
            throw std::bad_alloc();
        if (!d.empty())
            std::memcpy(doc->buf[i], d.data(), d.size());
        doc->buf_len[i] = d.size();
        doc->nbuf = static_cast<int>(i + 1);
    }

    /* The triangle primitives (points and lines pass through). */
    size_t nprim = 0;
    for (const auto &mesh : m.meshes)
        for (const auto &p : mesh.primitives)
            nprim += p.mode >= TINYGLTF_MODE_TRIANGLES && p.mode <= TINYGLTF_MODE_TRIANGLE_FAN;
    if (nprim == 0)
        return api__fail(err, MCF_EDECODE,
                         "gltf: no triangle primitive in %zu meshes", m.meshes.size());
    if (nprim > API_GLTF_MAX_PRIMS)
        return api__fail(err, MCF_ELIMIT, "gltf: %zu triangle primitives (at most %d)",
                         nprim, API_GLTF_MAX_PRIMS);
    doc->prim = static_cast<api__gltf_prim *>(std::calloc(nprim, sizeof(api__gltf_prim)));
    if (!doc->prim)
        throw std::bad_alloc();
    long long nvert = 0, ntri = 0;
    for (size_t mi = 0; mi < m.meshes.size(); mi++)
        for (size_t pi = 0; pi < m.meshes[mi].primitives.size(); pi++) {
            const tinygltf::Primitive &p = m.meshes[mi].primitives[pi];
            if (p.mode < TINYGLTF_MODE_TRIANGLES || p.mode > TINYGLTF_MODE_TRIANGLE_FAN)
                continue;
            api__gltf_prim *g = &doc->prim[doc->nprim++];
            g->mesh = static_cast<int>(mi);
            g->index = static_cast<int>(pi);
            g->mode = p.mode;
            g->pos = g->nrm = api__gltf_at{-1, -1, 0, 0};
            g->draco_view = g->draco_pos = g->draco_nrm = -1;
            auto ext = p.extensions.find("KHR_draco_mesh_compression");
            mcf_status rc = ext != p.extensions.end()
                                ? read_draco_prim(m, p, ext->second, lim, g, err)
                                : read_plain_prim(m, p, lim, g, err);
            if (rc != MCF_OK)
                return rc;
            nvert += g->nvert;
            ntri += g->ntri;
            if (nvert > lim->max_vertices || ntri > lim->max_faces)
                return api__fail(err, MCF_ELIMIT,
                                 "gltf: the triangle primitives hold more than "
                                 "max_vertices (%d) vertices or max_faces (%d) triangles",
                                 lim->max_vertices, lim->max_faces);
        }
    return MCF_OK;
}

} /* namespace */

extern "C" mcf_status api__gltf_parse(const void *buf, size_t len,
                                      const char *json_text, size_t json_len, const api_limits *lim,
                                      api__gltf_doc *doc, mcf_error *err)
{
    try {
        return parse(buf, len, json_text, json_len, lim, doc, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory while decoding");
    } catch (const std::exception &x) {
        return api__fail(err, MCF_EDECODE, "gltf: %s", first_line(x.what()).c_str());
    } catch (...) {
        return api__fail(err, MCF_EDECODE, "gltf: the reader failed (exception)");
    }
}
