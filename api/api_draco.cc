/*
 * api_draco.cc - Google Draco (.drc) decoder and encoder: a thin extern "C"
 * bridge over Debian's libdraco 1.5.5.
 *
 * Decoder: any Draco mesh bitstream the library reads (old v1.x such as
 * bunny.drc, current v2.2; edgebreaker and sequential). A point cloud is
 * refused. Vertices are the POSITION attribute's *values*, not its points:
 * a face corner's point p becomes vertex att->mapped_index(p), so a mesh
 * whose points are split at normal/UV seams stays connected where the
 * encoder shared the position value (edgebreaker streams do). A sequential
 * stream that stored one position per point next to other attributes
 * (car.drc: 1,856 values for 920 distinct positions) has its copies of a
 * position welded (weld_split_points): the attributes' seams are theirs,
 * not the surface's. A positions-only stream is taken as it is.
 *
 * Attributes (api_draco_decode_attrs): the first NORMAL, TEX_COORD and
 * COLOR per face corner, and the quantization of every attribute, which
 * the bitstream records only inside its attribute decoders: the stream is
 * decoded a second time with Draco's dequantization skipped, and the bits
 * (and a texture grid's origin and range) read from the transform data.
 *
 * Encoder: a draco::Mesh with a POSITION attribute and, when attributes
 * are given, TEX_COORD (float32), NORMAL (float32, recomputed from the
 * surface) and COLOR (normalized uint8); one point per distinct (vertex,
 * texcoord, normal, colour) of the face corners, so only seams split
 * points; without attributes one point per vertex (identity map).
 * quantization_bits -1 (auto, the default) keeps a Draco input's
 * quantization per attribute, a texture grid included (so texcoords come
 * back as the very same floats), keeps raw raw (float32), and quantizes
 * other inputs' positions and texcoords at 16 bits, normals at 10; 0 is
 * lossless: no quantization, the values stored raw, as float32 when every
 * coordinate is exactly a float (meshes that came from Draco, STL or
 * float sources), else as float64, so decoding gives back the very same
 * doubles (libdraco reads float64; draco_decoder's PLY writer does not).
 * Draco quantizes float32 attributes only, so q in 1..30 stores float32
 * (a coordinate beyond the float range is refused; auto falls back to
 * lossless there). Compression level L maps to Draco speed 10 - L.
 * preserve_order selects the sequential method, which keeps face order
 * and, without attributes, vertex order (and unreferenced vertices);
 * otherwise edgebreaker, which renumbers vertices, reorders and rotates
 * faces, drops unreferenced vertices and splits non-manifold ones.
 *
 * Primitives (api__draco_prim_decode / _encode, for glTF's
 * KHR_draco_mesh_compression): every attribute as it came, by unique id,
 * its points' values as raw bytes of their data type and its quantization
 * (bits and grid, from the same second decode), and back: the same ids,
 * types and quantization (a grid reused where the values still lie on
 * it), edgebreaker, through the ExpertEncoder's per-attribute options.
 *
 * *max_quant_err is measured, not predicted: the encoded bytes are decoded
 * again and every input face is compared with its decoded counterpart
 * corner by corner (faces are looked up by centroid in a grid, cyclic
 * rotations tried), since edgebreaker changes vertex and face order.
 *
 * Every entry point catches all C++ exceptions: std::bad_alloc becomes
 * ENOMEM, anything else EDECODE (decoder) or EMESH (encoder). No C++ type
 * or exception crosses api.h.
 */
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <vector>

#include "draco/attributes/attribute_octahedron_transform.h"
#include "draco/attributes/attribute_quantization_transform.h"
#include "draco/compression/decode.h"
#include "draco/compression/encode.h"
#include "draco/compression/expert_encode.h"
#include "draco/mesh/mesh.h"

#include "api.h"
extern "C" {
#include "api_internal.h"
}

namespace {

/* Reads the 3 components of value v of attribute a as doubles. Done by
 * hand rather than with GeometryAttribute::ConvertValue, whose template
 * (compiled here) would load a corrupt stream's DT_BOOL bytes as bool
 * (undefined behaviour) and does not bound-check the last component
 * against the buffer. Integer types read as their values (divided by the
 * type's maximum when the attribute is marked normalized, as Draco does). */
bool read_values(const draco::PointAttribute *a, uint32_t v, int n,
                 bool unit, double *out);

bool read_position(const draco::PointAttribute *a, uint32_t v, double out[3])
{
    return read_values(a, v, 3, false, out);
}

/* The first n components of value v; integer types are divided by their
 * maximum when the attribute is normalized or unit is set (colours). */
bool read_values(const draco::PointAttribute *a, uint32_t v, int n, bool unit,
                 double *out)
{
    const draco::DataType dt = a->data_type();
    const int64_t sz = draco::DataTypeLength(dt);
    const draco::DataBuffer *db = a->buffer();
    if (dt < draco::DT_INT8 || dt > draco::DT_FLOAT64 || sz <= 0 || !db)
        return false;
    const int64_t pos = a->byte_offset() + a->byte_stride() * static_cast<int64_t>(v);
    if (a->byte_offset() < 0 || a->byte_stride() < n * sz || pos < 0 ||
        static_cast<uint64_t>(pos) + n * static_cast<uint64_t>(sz) > db->data_size())
        return false;
    const uint8_t *p = db->data() + pos;
    for (int k = 0; k < n; k++, p += sz) {
        double x = 0.0, scale = 0.0;
        switch (dt) {
        case draco::DT_INT8: { int8_t t; std::memcpy(&t, p, 1); x = t; scale = INT8_MAX; break; }
        case draco::DT_UINT8: { uint8_t t; std::memcpy(&t, p, 1); x = t; scale = UINT8_MAX; break; }
        case draco::DT_INT16: { int16_t t; std::memcpy(&t, p, 2); x = t; scale = INT16_MAX; break; }
        case draco::DT_UINT16: { uint16_t t; std::memcpy(&t, p, 2); x = t; scale = UINT16_MAX; break; }
        case draco::DT_INT32: { int32_t t; std::memcpy(&t, p, 4); x = t; scale = INT32_MAX; break; }
        case draco::DT_UINT32: { uint32_t t; std::memcpy(&t, p, 4); x = t; scale = UINT32_MAX; break; }
        case draco::DT_INT64: { int64_t t; std::memcpy(&t, p, 8); x = static_cast<double>(t); scale = static_cast<double>(INT64_MAX); break; }
        case draco::DT_UINT64: { uint64_t t; std::memcpy(&t, p, 8); x = static_cast<double>(t); scale = static_cast<double>(UINT64_MAX); break; }
        case draco::DT_FLOAT32: { float t; std::memcpy(&t, p, 4); x = t; break; }
        case draco::DT_FLOAT64: { double t; std::memcpy(&t, p, 8); x = t; break; }
        default: return false;
        }
        out[k] = ((a->normalized() || unit) && scale > 0.0) ? x / scale : x;
    }
    return true;
}

/* ------------------------------------------------------ count pre-check */

/* libdraco sizes its tables from the counts in the stream before it reads
 * the data they describe: a 300-byte edgebreaker stream declaring a billion
 * faces makes it reserve 4 GB, a v2.0 stream with a huge hole-event count
 * grows a vector without end, and its metadata reader allocates an entry's
 * declared size and recurses without a depth bound. So the counts are read
 * here first, along the bitstream layout of Draco's decoders (header,
 * metadata, then the sequential or edgebreaker connectivity header), and
 * checked against the limits and the input size. Parsing stops quietly
 * where the input ends: Draco fails there too, before allocating. */
struct cursor {
    const uint8_t *p, *end;
    bool u8(uint32_t *v)
    {
        if (p >= end)
            return false;
        *v = *p++;
        return true;
    }
    bool u32(uint32_t *v)
    {
        if (end - p < 4)
            return false;
        *v = static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 |
             static_cast<uint32_t>(p[2]) << 16 | static_cast<uint32_t>(p[3]) << 24;
        p += 4;
        return true;
    }
    /* Draco's DecodeVarint<uint32_t>: at most 5 bytes, least significant
     * group first, assembled in 32-bit arithmetic. */
    bool varint(uint32_t *v)
    {
        uint8_t b[5];
        int n = 0;
        do {
            if (n == 5 || p >= end)
                return false;
            b[n] = *p++;
        } while (b[n++] & 0x80);
        uint32_t x = b[n - 1];
        for (int i = n - 2; i >= 0; i--)
            x = (x << 7) | (b[i] & 0x7fu);
        *v = x;
        return true;
    }
    /* u32 before bitstream 2.0, varint from then on (Draco's pattern). */
    bool count(int ver, uint32_t *v) { return ver < 0x200 ? u32(v) : varint(v); }
    size_t left() const { return static_cast<size_t>(end - p); }
};

/* Skips one metadata block (MetadataDecoder::DecodeMetadata) strictly. */
mcf_status skip_metadata(cursor *c, int depth, mcf_error *err)
{
    uint32_t n, len = 0, k;
    if (depth > 32)
        return api__fail(err, MCF_EDECODE, "draco: metadata nested deeper than 32 levels");
    if (!c->varint(&n))
        return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
    if (n > c->left())
        return api__fail(err, MCF_EDECODE,
                         "draco: metadata declares %u entries in %zu bytes", n,
                         c->left());
    for (k = 0; k < n; k++) {
        uint32_t name;
        if (!c->u8(&name) || name > c->left())
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        c->p += name;
        if (!c->varint(&len) || len == 0 || len > c->left())
            return api__fail(err, MCF_EDECODE,
                             "draco: metadata entry of %u bytes in %zu", len,
                             c->left());
        c->p += len;
    }
    if (!c->varint(&n))
        return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
    if (n > c->left())
        return api__fail(err, MCF_EDECODE,
                         "draco: metadata declares %u sub-metadata in %zu bytes", n,
                         c->left());
    for (k = 0; k < n; k++) {
        uint32_t name;
        if (!c->u8(&name) || name > c->left())
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        c->p += name;
        mcf_status rc = skip_metadata(c, depth + 1, err);
        if (rc != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

mcf_status check_counts(const uint8_t *buf, size_t len, const api_limits *lim,
                        mcf_error *err, uint32_t *declared = nullptr)
{
    cursor c{buf, buf + len};
    if (len < 11)
        return MCF_OK; /* Draco's header check reports it */
    const int ver = buf[5] << 8 | buf[6];
    const int method = buf[8];
    const unsigned flags = buf[9] | buf[10] << 8;
    c.p += 11;
    if (ver >= 0x103 && (flags & 0x8000)) {
        uint32_t n, k, id;
        if (!c.varint(&n))
            return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
        if (n > c.left())
            return api__fail(err, MCF_EDECODE,
                             "draco: metadata declares %u attribute blocks in %zu "
                             "bytes",
                             n, c.left());
        for (k = 0; k < n; k++) {
            if (!c.varint(&id))
                return api__fail(err, MCF_EDECODE, "draco: truncated metadata");
            mcf_status rc = skip_metadata(&c, 0, err);
            if (rc != MCF_OK)
                return rc;
        }
        mcf_status rc = skip_metadata(&c, 0, err);
        if (rc != MCF_OK)
            return rc;
    }
    uint32_t nfaces = 0, nverts = 0, extra = 0, v;
    if (method == 0) { /* sequential: faces, points */
        if (!(ver < 0x202 ? c.u32(&nfaces) : c.varint(&nfaces)) ||
            !(ver < 0x202 ? c.u32(&nverts) : c.varint(&nverts)))
            return MCF_OK;
    } else if (method == 1) { /* edgebreaker */
        uint32_t nattr, nsym, nsplit;
        if (!c.u8(&v))
            return MCF_OK;
        if (ver < 0x202) {
            if (!c.count(ver, &extra))
                return MCF_OK;
        }
        if (!c.count(ver, &nverts) || !c.count(ver, &nfaces) || !c.u8(&nattr) ||
            !c.count(ver, &nsym) || !c.count(ver, &nsplit))
            return MCF_OK;
        if (nsplit > nfaces)
            return api__fail(err, MCF_EDECODE,
                             "draco: %u split symbols for %u faces", nsplit, nfaces);
        if (nfaces <= static_cast<uint32_t>(lim->max_faces) &&
            nverts <= static_cast<uint32_t>(lim->max_vertices) && ver < 0x201) {
            /* Streams before 2.1 carry a hole-event count that Draco trusts:
             * find it behind the topology splits and bound it by the bytes
             * left (each event takes at least one). */
            cursor e = c;
            uint32_t nsplits, nholes = 0, size;
            if (ver < 0x202) {
                if (!c.count(ver, &size) || size == 0 || size > c.left())
                    return MCF_OK;
                e.p = c.p + size;
            }
            if (!e.count(ver, &nsplits) || nsplits > nfaces)
                return MCF_OK;
            for (uint32_t k = 0; k < nsplits; k++) {
                if (ver < 0x102) {
                    if (e.left() < 9)
                        return MCF_OK;
                    e.p += 9;
                } else if (!e.varint(&v) || !e.varint(&v)) {
                    return MCF_OK;
                }
            }
            if (ver >= 0x102 && nsplits > 0) {
                size_t bytes = (static_cast<size_t>(nsplits) * 2 + 7) / 8;
                if (bytes > e.left())
                    return MCF_OK;
                e.p += bytes;
            }
            if (!e.count(ver, &nholes))
                return MCF_OK;
            if (nholes > e.left())
                return api__fail(err, MCF_EDECODE,
                                 "draco: %u hole events in %zu bytes", nholes,
                                 e.left());
        }
    } else {
        return MCF_OK; /* Draco refuses unknown methods */
    }
    if (declared) { /* what the memory estimate sizes (api_estimate.c) */
        declared[0] = nverts > extra ? nverts : extra;
        declared[1] = nfaces;
    }
    if (nfaces > static_cast<uint32_t>(lim->max_faces))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u faces, more than max_faces (%d)",
                         nfaces, lim->max_faces);
    if (nverts > static_cast<uint32_t>(lim->max_vertices) ||
        extra > static_cast<uint32_t>(lim->max_vertices))
        return api__fail(err, MCF_ELIMIT,
                         "draco: header declares %u vertices, more than "
                         "max_vertices (%d)",
                         nverts > extra ? nverts : extra, lim->max_vertices);
    return MCF_OK;
}

/* ------------------------------------------------------------- decoder */

/* A stream that stores one position per point (identity map: the
 * sequential layout, e.g. car.drc) next to other attributes has its
 * surface cut at every seam of those attributes: each side of a UV seam
 * holds its own copy of the position, so the flow would see a boundary
 * there (frozen with boundary=fixed, torn open with free) and normals
 * from one side only. Such copies, bitwise-equal positions, become one
 * vertex; the attributes keep their seams through their own per-corner
 * indices. Vertices keep their order (each group at its first index).
 * Positions-only streams are left as they are. Returns the new vertex
 * count; X and F are rewritten in place. */
size_t weld_split_points(const draco::Mesh &dm, const draco::PointAttribute *pos,
                         std::vector<double> &X, std::vector<int32_t> &F)
{
    const size_t nv = X.size() / 3;
    if (!pos->is_mapping_identity() || dm.num_attributes() < 2 || nv < 2)
        return nv;
    std::vector<uint32_t> order(nv);
    for (size_t i = 0; i < nv; i++)
        order[i] = static_cast<uint32_t>(i);
    auto cmp = [&X](uint32_t a, uint32_t b) {
        return std::memcmp(&X[3 * static_cast<size_t>(a)],
                           &X[3 * static_cast<size_t>(b)], 3 * sizeof(double)) < 0;
    };
    std::stable_sort(order.begin(), order.end(), cmp);
    std::vector<uint32_t> rep(nv);
    for (size_t i = 0; i < nv; i++)
        rep[order[i]] = (i > 0 && !cmp(order[i - 1], order[i])) ? rep[order[i - 1]]
                                                                 : order[i];
    std::vector<int32_t> id(nv, -1);
    size_t n = 0;
    for (size_t v = 0; v < nv; v++) {
        if (rep[v] != v)
            continue;
        for (int k = 0; k < 3; k++)
            X[3 * n + k] = X[3 * v + k];
        id[v] = static_cast<int32_t>(n++);
    }
    if (n == nv)
        return nv;
    for (size_t v = 0; v < nv; v++)
        id[v] = id[rep[v]];
    for (int32_t &f : F)
        f = id[static_cast<size_t>(f)];
    X.resize(3 * n);
    return n;
}

mcf_status read_attrs(const void *buf, size_t len, const draco::Mesh &dm,
                      const draco::PointAttribute *pos, const mcf_mesh *m,
                      api_attrs **attrs, mcf_error *err);

/* The checks before libdraco decodes a stream: magic, a triangle mesh
 * (not a point cloud), the header's counts within lim. */
mcf_status check_stream(const void *buf, size_t len, const api_limits *lim,
                        mcf_error *err)
{
    if (len < 5 || std::memcmp(buf, "DRACO", 5) != 0)
        return api__fail(err, MCF_EDECODE,
                         "draco: no \"DRACO\" magic at the start of the input");
    draco::DecoderBuffer db;
    db.Init(static_cast<const char *>(buf), len);
    auto type = draco::Decoder::GetEncodedGeometryType(&db);
    if (!type.ok())
        return api__fail(err, MCF_EDECODE, "draco: bad header: %s",
                         type.status().error_msg());
    if (type.value() == draco::POINT_CLOUD)
        return api__fail(err, MCF_EDECODE,
                         "Draco point cloud, not a triangle mesh");
    if (type.value() != draco::TRIANGULAR_MESH)
        return api__fail(err, MCF_EDECODE, "draco: unknown geometry type %d",
                         static_cast<int>(type.value()));
    return check_counts(static_cast<const uint8_t *>(buf), len, lim, err);
}

mcf_status decode(const void *buf, size_t len, const api_limits *lim,
                  mcf_mesh **out, api_attrs **attrs, mcf_error *err)
{
    api_limits def;
    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (!buf && len)
        return api__fail(err, MCF_EINVAL, "draco: NULL buffer");
    if (len > lim->max_input_bytes)
        return api__fail(err, MCF_ELIMIT,
                         "draco: input of %zu bytes exceeds max_input_bytes (%zu)",
                         len, lim->max_input_bytes);
    if (len == 0)
        return api__fail(err, MCF_EDECODE, "draco: empty input");
    mcf_status rc = check_stream(buf, len, lim, err);
    if (rc != MCF_OK)
        return rc;

    draco::DecoderBuffer db;
    db.Init(static_cast<const char *>(buf), len);
    draco::Decoder dec;
    auto res = dec.DecodeMeshFromBuffer(&db);
    if (!res.ok())
        return api__fail(err, MCF_EDECODE, "draco: %s",
                         res.status().error_msg());
    std::unique_ptr<draco::Mesh> dm = std::move(res).value();
    if (!dm)
        return api__fail(err, MCF_EDECODE, "draco: decoder returned no mesh");

    const draco::PointAttribute *pos =
        dm->GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!pos)
        return api__fail(err, MCF_EDECODE, "draco: mesh has no POSITION attribute");
    if (pos->num_components() != 3)
        return api__fail(err, MCF_EDECODE,
                         "draco: POSITION has %d components, 3 needed",
                         static_cast<int>(pos->num_components()));

    const size_t nvals = pos->size();
    const size_t npts = dm->num_points();
    const size_t nfaces = dm->num_faces();
    if (nvals > static_cast<size_t>(lim->max_vertices))
        return api__fail(err, MCF_ELIMIT,
                         "draco: %zu vertices exceed max_vertices (%d)", nvals,
                         lim->max_vertices);
    if (nfaces > static_cast<size_t>(lim->max_faces))
        return api__fail(err, MCF_ELIMIT,
                         "draco: %zu faces exceed max_faces (%d)", nfaces,
                         lim->max_faces);
    if (nvals == 0)
        return api__fail(err, MCF_EDECODE, "draco: mesh has no vertices");
    if (nfaces == 0)
        return api__fail(err, MCF_EDECODE,
                         "draco: mesh has no faces (%zu vertices only)", nvals);

    std::vector<double> X(3 * nvals);
    std::vector<int32_t> F(3 * nfaces);
    for (size_t v = 0; v < nvals; v++) {
        double *x = &X[3 * v];
        if (!read_position(pos, static_cast<uint32_t>(v), x))
            return api__fail(err, MCF_EDECODE,
                             "draco: POSITION data type %d cannot be read",
                             static_cast<int>(pos->data_type()));
        if (!std::isfinite(x[0]) || !std::isfinite(x[1]) || !std::isfinite(x[2]))
            return api__fail(err, MCF_EDECODE,
                             "draco: vertex %zu has a non-finite coordinate", v);
    }
    for (size_t f = 0; f < nfaces; f++) {
        const draco::Mesh::Face &face =
            dm->face(draco::FaceIndex(static_cast<uint32_t>(f)));
        for (int k = 0; k < 3; k++) {
            const uint32_t p = face[k].value();
            if (p >= npts)
                return api__fail(err, MCF_EDECODE,
                                 "draco: face %zu refers to point %u of %zu", f,
                                 p, npts);
            const uint32_t a = pos->mapped_index(face[k]).value();
            if (a >= nvals)
                return api__fail(err, MCF_EDECODE,
                                 "draco: face %zu maps to position value %u of %zu",
                                 f, a, nvals);
            F[3 * f + k] = static_cast<int32_t>(a);
        }
    }
    const size_t nv = weld_split_points(*dm, pos, X, F);
    mcf_mesh *m = mcf_mesh_new(static_cast<int>(nv), X.data(),
                               static_cast<int>(nfaces), F.data(), err);
    if (!m)
        return (err && err->status != MCF_OK) ? err->status : MCF_EMESH;
    if (attrs) {
        try {
            rc = read_attrs(buf, len, *dm, pos, m, attrs, err);
        } catch (...) {
            mcf_mesh_free(m);
            throw;
        }
        if (rc != MCF_OK) {
            mcf_mesh_free(m);
            return rc;
        }
    }
    *out = m;
    return MCF_OK;
}

/* The quantization of attribute a (of a mesh decoded with the transforms
 * skipped): its bits (0: stored raw) and, for a quantized one, the grid. */
int transform_bits(const draco::PointAttribute *a, float origin[4], float *range)
{
    *range = 0.0f;
    const draco::AttributeTransformData *td = a ? a->GetAttributeTransformData() : nullptr;
    if (!td)
        return 0;
    if (td->transform_type() == draco::ATTRIBUTE_QUANTIZATION_TRANSFORM) {
        draco::AttributeQuantizationTransform q;
        if (!q.InitFromAttribute(*a))
            return 0;
        const int nc = std::min(4, static_cast<int>(a->num_components()));
        if (static_cast<int>(q.min_values().size()) >= nc) {
            for (int c = 0; c < nc; c++)
                origin[c] = q.min_value(c);
            *range = q.range();
        }
        return q.quantization_bits();
    }
    if (td->transform_type() == draco::ATTRIBUTE_OCTAHEDRON_TRANSFORM) {
        draco::AttributeOctahedronTransform o;
        if (!o.InitFromAttribute(*a))
            return 0;
        return o.quantization_bits();
    }
    return 0;
}

/* The attributes of the decoded dm (whose POSITION is pos) for mesh m:
 * the first NORMAL (3 components), TEX_COORD (2) and COLOR (3 or 4) as
 * per-corner values, and the quantization of each, learnt by decoding the
 * stream once more with Draco's dequantization skipped (the bitstream
 * keeps it nowhere else). One Draco cannot read is left out. */
mcf_status read_attrs(const void *buf, size_t len, const draco::Mesh &dm,
                      const draco::PointAttribute *pos, const mcf_mesh *m,
                      api_attrs **attrs, mcf_error *err)
{
    static const struct {
        draco::GeometryAttribute::Type type;
        api_attr_kind kind;
    } kinds[] = {{draco::GeometryAttribute::NORMAL, API_ATTR_NORMAL},
                 {draco::GeometryAttribute::TEX_COORD, API_ATTR_TEXCOORD},
                 {draco::GeometryAttribute::COLOR, API_ATTR_COLOR}};
    const size_t nf = dm.num_faces(), npts = dm.num_points();
    std::unique_ptr<api_attrs, void (*)(api_attrs *)> a(
        api_attrs_new(mcf_mesh_nvertices(m), mcf_mesh_nfaces(m)), api_attrs_free);
    if (!a)
        return api__fail(err, MCF_ENOMEM, "draco: out of memory for the attributes");
    a->float32 = pos->data_type() == draco::DT_FLOAT32 ? 1 : 0;

    /* The quantization: a second decode, transforms skipped. */
    std::unique_ptr<draco::Mesh> raw;
    {
        draco::DecoderBuffer db;
        db.Init(static_cast<const char *>(buf), len);
        draco::Decoder dec;
        dec.SetSkipAttributeTransform(draco::GeometryAttribute::POSITION);
        for (const auto &k : kinds)
            dec.SetSkipAttributeTransform(k.type);
        auto res = dec.DecodeMeshFromBuffer(&db);
        if (res.ok())
            raw = std::move(res).value();
    }
    if (raw) {
        float o[4];
        float r;
        a->pos_bits = transform_bits(
            raw->GetNamedAttribute(draco::GeometryAttribute::POSITION), o, &r);
        if (a->pos_bits > 0)
            a->float32 = 1; /* dequantized positions are float32 */
    }

    for (const auto &k : kinds) {
        const draco::PointAttribute *att = dm.GetNamedAttribute(k.type);
        if (!att)
            continue;
        const int nc = att->num_components();
        const int want = k.kind == API_ATTR_TEXCOORD ? 2 : 3;
        if (!(nc == want || (k.kind == API_ATTR_COLOR && nc == 4)))
            continue;
        const size_t nvals = att->size();
        if (nvals > static_cast<size_t>(INT32_MAX) / 4)
            continue;
        std::vector<double> V(nvals * nc);
        bool ok = true;
        for (size_t v = 0; v < nvals && ok; v++) {
            ok = read_values(att, static_cast<uint32_t>(v), nc,
                             k.kind == API_ATTR_COLOR, &V[v * nc]);
            for (int c = 0; ok && c < nc; c++)
                ok = std::isfinite(V[v * nc + c]);
        }
        std::vector<int32_t> C(3 * nf);
        for (size_t f = 0; f < nf && ok; f++) {
            const draco::Mesh::Face &face =
                dm.face(draco::FaceIndex(static_cast<uint32_t>(f)));
            for (int c = 0; c < 3 && ok; c++) {
                ok = face[c].value() < npts;
                const uint32_t i = ok ? att->mapped_index(face[c]).value() : 0;
                ok = ok && i < nvals;
                C[3 * f + c] = static_cast<int32_t>(i);
            }
        }
        if (!ok)
            continue;
        mcf_status rc = api_attrs_set(a.get(), k.kind, nc, static_cast<int>(nvals),
                                      V.data(), C.data(), err);
        if (rc != MCF_OK)
            return rc;
        api__attr &at = a->a[k.kind];
        at.bits = 0;
        if (raw) {
            const draco::PointAttribute *ra = raw->GetNamedAttribute(k.type);
            at.bits = transform_bits(ra, at.qorigin, &at.qrange);
        }
    }
    *attrs = a.release();
    return MCF_OK;
}

/* ------------------------------------------------------ error measurement */

/* The decoded faces binned by the cell of their centroid: a hash table
 * (open addressing, linear probing) from a cell to its faces, built in two
 * passes (count, then place), looked up in O(1). It replaced a sort and
 * 27 binary searches per input face, 1.4 s of CPU on the 871k-face dragon. */
class cell_index {
public:
    /* b: 3 cell coordinates per face, nfaces faces */
    explicit cell_index(const std::vector<int64_t> &b)
    {
        const size_t n = b.size() / 3;
        size_t cap = 16;
        while (cap < 2 * n)
            cap *= 2;
        mask_ = cap - 1;
        slot_.assign(cap, UINT32_MAX);
        std::vector<uint32_t> cell_of(n);
        for (size_t f = 0; f < n; f++) {
            const int64_t *k = &b[3 * f];
            size_t h = hash(k) & mask_;
            while (slot_[h] != UINT32_MAX && !same(slot_[h], k))
                h = (h + 1) & mask_;
            if (slot_[h] == UINT32_MAX) {
                slot_[h] = static_cast<uint32_t>(key_.size() / 3);
                key_.insert(key_.end(), k, k + 3);
                start_.push_back(0);
            }
            cell_of[f] = slot_[h];
            start_[slot_[h]]++;
        }
        /* counts -> starts (one more entry: the end of the last cell) */
        uint32_t sum = 0;
        for (uint32_t &c : start_) {
            const uint32_t cnt = c;
            c = sum;
            sum += cnt;
        }
        start_.push_back(sum);
        std::vector<uint32_t> next(start_.begin(), start_.end() - 1);
        face_.resize(n);
        for (size_t f = 0; f < n; f++)
            face_[next[cell_of[f]]++] = static_cast<uint32_t>(f);
    }
    /* The faces in cell k: [*begin, *end) of faces(); false when none. */
    bool find(const int64_t k[3], const uint32_t **begin, const uint32_t **end) const
    {
        for (size_t h = hash(k) & mask_; slot_[h] != UINT32_MAX; h = (h + 1) & mask_)
            if (same(slot_[h], k)) {
                *begin = face_.data() + start_[slot_[h]];
                *end = face_.data() + start_[slot_[h] + 1];
                return true;
            }
        return false;
    }

private:
    static size_t hash(const int64_t k[3])
    {
        /* the three coordinates spread by odd constants, then MurmurHash3's
         * 64-bit finalizer: neighbouring cells land far apart */
        uint64_t h = static_cast<uint64_t>(k[0]) * 0x9E3779B97F4A7C15ull ^
                     static_cast<uint64_t>(k[1]) * 0xC2B2AE3D27D4EB4Full ^
                     static_cast<uint64_t>(k[2]) * 0x165667B19E3779F9ull;
        h ^= h >> 33;
        h *= 0xff51afd7ed558ccdull;
        h ^= h >> 33;
        h *= 0xc4ceb9fe1a85ec53ull;
        h ^= h >> 33;
        return static_cast<size_t>(h);
    }
    bool same(uint32_t c, const int64_t k[3]) const
    {
        const int64_t *q = &key_[3 * static_cast<size_t>(c)];
        return q[0] == k[0] && q[1] == k[1] && q[2] == k[2];
    }
    size_t mask_ = 0;
    std::vector<uint32_t> slot_;   /* cell number or UINT32_MAX */
    std::vector<int64_t> key_;     /* 3 per cell */
    std::vector<uint32_t> start_;  /* cell -> first of its faces in face_ */
    std::vector<uint32_t> face_;   /* faces grouped by cell */
};

/* Largest coordinate error between the input (X, F) and the decoded mesh
 * dm, through face corners. Every input face whose three indices differ
 * must have a decoded face, up to a cyclic rotation, whose corners lie
 * within tol of its own (tol >= the quantization bound, so a missing one
 * is a real mismatch); *worst_face names it otherwise and false is
 * returned. Decoded faces are binned by centroid in cells of side h >= 2 tol;
 * a counterpart's centroid lies within tol of the input face's (each
 * corner does), so only the cells that box of half-side tol touches are
 * searched: one, or two along an axis where it straddles a cell wall. */
bool measure(int nv, const double *X, int nf, const int32_t *F,
             const draco::Mesh &dm, double tol, double *maxerr,
             int *worst_face)
{
    const draco::PointAttribute *pos =
        dm.GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!pos || pos->num_components() != 3)
        return false;
    const size_t ny = pos->size();
    const size_t ng = dm.num_faces();
    std::vector<double> Y(3 * ny);
    for (size_t v = 0; v < ny; v++)
        if (!read_position(pos, static_cast<uint32_t>(v), &Y[3 * v]))
            return false;
    std::vector<uint32_t> G(3 * ng);
    for (size_t f = 0; f < ng; f++) {
        const draco::Mesh::Face &face =
            dm.face(draco::FaceIndex(static_cast<uint32_t>(f)));
        for (int k = 0; k < 3; k++) {
            if (face[k].value() >= dm.num_points())
                return false;
            uint32_t a = pos->mapped_index(face[k]).value();
            if (a >= ny)
                return false;
            G[3 * f + k] = a;
        }
    }

    /* Sequential streams keep everything in place: compare all vertices
     * (unreferenced ones included) index by index. */
    if (ny == static_cast<size_t>(nv) && ng == static_cast<size_t>(nf) &&
        std::equal(G.begin(), G.end(), F,
                   [](uint32_t a, int32_t b) { return a == static_cast<uint32_t>(b); })) {
        double e = 0.0;
        for (size_t i = 0; i < 3 * ny; i++)
            e = std::max(e, std::fabs(Y[i] - X[i]));
        *maxerr = e;
        return true;
    }

    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, ext = 0.0;
    for (size_t i = 0; i < 3 * ny; i++)
        lo[i % 3] = std::min(lo[i % 3], Y[i]);
    for (int i = 0; i < 3 * nv; i++)
        lo[i % 3] = std::min(lo[i % 3], X[i]);
    for (size_t i = 0; i < 3 * ny; i++)
        ext = std::max(ext, Y[i] - lo[i % 3]);
    for (int i = 0; i < 3 * nv; i++)
        ext = std::max(ext, X[i] - lo[i % 3]);
    /* Cells of about a face's size (the extent over sqrt(faces): a few
     * centroids per cell on a surface), at least 2 tol so that a search box
     * mostly lies in one cell, and at most ~2^40 per axis so indices fit. */
    double h = std::max({2.0 * tol, ext / std::sqrt(static_cast<double>(ng) + 1.0), ext * 0x1p-40});
    if (!(h > 0.0))
        h = 1.0;
    auto bin = [&](const double c[3], int64_t b[3]) {
        for (int a = 0; a < 3; a++)
            b[a] = static_cast<int64_t>(std::floor((c[a] - lo[a]) / h));
    };
    auto centroid = [](const double *P, const double *Q, const double *R,
                       double c[3]) {
        for (int a = 0; a < 3; a++)
            c[a] = (P[a] + Q[a] + R[a]) / 3.0;
    };

    std::vector<int64_t> fb(3 * ng);
    for (size_t f = 0; f < ng; f++) {
        double c[3];
        centroid(&Y[3 * G[3 * f]], &Y[3 * G[3 * f + 1]], &Y[3 * G[3 * f + 2]], c);
        bin(c, &fb[3 * f]);
    }
    const cell_index cells(fb);
    /* the search box's half-side: tol, plus the centroids' rounding (a few
     * ulps of the extent), generously */
    const double r = tol + ext * 0x1p-40;

    double e = 0.0;
    for (int f = 0; f < nf; f++) {
        const int32_t *t = F + 3 * (size_t)f;
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
            continue;
        double c[3], clo[3], chi[3];
        int64_t b0[3], b1[3];
        centroid(&X[3 * t[0]], &X[3 * t[1]], &X[3 * t[2]], c);
        for (int a = 0; a < 3; a++) {
            clo[a] = c[a] - r;
            chi[a] = c[a] + r;
        }
        bin(clo, b0);
        bin(chi, b1);
        double best = HUGE_VAL;
        int64_t key[3];
        for (key[0] = b0[0]; key[0] <= b1[0]; key[0]++)
            for (key[1] = b0[1]; key[1] <= b1[1]; key[1]++)
                for (key[2] = b0[2]; key[2] <= b1[2]; key[2]++) {
                    const uint32_t *it, *end;
                    if (!cells.find(key, &it, &end))
                        continue;
                    for (; it != end; ++it) {
                        const uint32_t *g = &G[3 * (size_t)*it];
                        for (int r3 = 0; r3 < 3; r3++) {
                            double d = 0.0;
                            for (int q = 0; q < 3; q++) {
                                const double *x = &X[3 * t[q]];
                                const double *y = &Y[3 * g[(q + r3) % 3]];
                                for (int a = 0; a < 3; a++)
                                    d = std::max(d, std::fabs(y[a] - x[a]));
                            }
                            best = std::min(best, d);
                        }
                    }
                }
        if (!(best <= tol)) {
            *worst_face = f;
            return false;
        }
        e = std::max(e, best);
    }
    *maxerr = e;
    return true;
}

/* ------------------------------------------------------------- encoder */

/* Quantization bits at most: Draco's encoder allocates memory that
 * doubles per bit whatever the mesh (measured on an 812-vertex sphere:
 * 24 bits 58 MB, 26 bits 200 MB; 30 bits about 3 GB). */
#define API_DRACO_MAX_BITS 24

/* The encoder's choice for one attribute: bits 0 = raw float32, else
 * quantized with that many bits (on the input's grid when grid). */
struct attr_plan {
    int bits = 0;
    bool grid = false;
};

/* Bits for an attribute of kind k (or positions, API_ATTR_POSITION) under
 * quantization_bits q: -1 auto: the Draco input's own (raw stays raw),
 * else the stated defaults; 0 lossless: raw; q > 0: positions get q, the
 * other attributes what auto gives them. */
attr_plan plan_for(const api_attrs *a, int k, int q)
{
    attr_plan p;
    if (q == 0)
        return p;
    if (k == API_ATTR_POSITION && q > 0) {
        p.bits = q;
        return p;
    }
    const int in = api_attrs_draco_bits(a, k);
    if (in >= 0) {
        /* An input quantized finer than the cap is written at the cap. */
        p.bits = in > API_DRACO_MAX_BITS ? API_DRACO_MAX_BITS : in;
        p.grid = k == API_ATTR_TEXCOORD && in > 0 && in <= API_DRACO_MAX_BITS &&
                 a->a[k].qrange > 0.0f;
        return p;
    }
    p.bits = k == API_ATTR_POSITION ? API_DRACO_DEFAULT_BITS
             : k == API_ATTR_NORMAL ? API_DRACO_DEFAULT_NORMAL_BITS
             : k == API_ATTR_TEXCOORD ? API_DRACO_DEFAULT_TEXCOORD_BITS
                                       : 0;
    return p;
}

/* A point: one vertex with one value of each attribute (-1: none). */
struct point_key {
    int32_t v, t, n, c;
    bool operator<(const point_key &o) const
    {
        if (v != o.v) return v < o.v;
        if (t != o.t) return t < o.t;
        if (n != o.n) return n < o.n;
        return c < o.c;
    }
    bool operator==(const point_key &o) const
    {
        return v == o.v && t == o.t && n == o.n && c == o.c;
    }
};

/* Adds an attribute of type type to dm with nvalues values of nc
 * components of dt (data holds them packed) and the point -> value map
 * pv (identity when empty). Returns its id, or -1. */
int add_attribute(draco::Mesh &dm, draco::GeometryAttribute::Type type, int nc,
                  draco::DataType dt, bool normalized, size_t nvalues,
                  const void *data, const std::vector<int32_t> &pv)
{
    draco::GeometryAttribute ga;
    const int64_t sz = draco::DataTypeLength(dt);
    ga.Init(type, nullptr, static_cast<int8_t>(nc), dt, normalized, nc * sz, 0);
    const bool identity = pv.empty();
    const int id = dm.AddAttribute(ga, identity, static_cast<uint32_t>(nvalues));
    draco::PointAttribute *pa = dm.attribute(id);
    if (!pa)
        return -1;
    const uint8_t *d = static_cast<const uint8_t *>(data);
    for (size_t i = 0; i < nvalues; i++)
        pa->SetAttributeValue(draco::AttributeValueIndex(static_cast<uint32_t>(i)),
                              d + i * nc * sz);
    if (!identity) {
        pa->SetExplicitMapping(pv.size());
        for (size_t p = 0; p < pv.size(); p++)
            pa->SetPointMapEntry(draco::PointIndex(static_cast<uint32_t>(p)),
                                 draco::AttributeValueIndex(static_cast<uint32_t>(pv[p])));
    }
    return id;
}

std::vector<float> to_float(const double *v, size_t n)
{
    std::vector<float> f(n);
    for (size_t i = 0; i < n; i++)
        f[i] = static_cast<float>(v[i]);
    return f;
}

mcf_status encode(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                  double *max_quant_err, mcf_error *err)
{
    api_encode_opts defo;
    if (!o) {
        api_encode_opts_init(&defo);
        o = &defo;
    }
    const int qopt = o->quantization_bits;
    const int level = o->compression_level;
    if (qopt < -1 || qopt > API_DRACO_MAX_BITS)
        return api__fail(err, MCF_EINVAL,
                         "draco: quantization_bits %d out of range (-1 = auto, 0 = "
                         "lossless, 1..%d: the encoder's memory doubles per bit)",
                         qopt, API_DRACO_MAX_BITS);
    if (level < 0 || level > 10)
        return api__fail(err, MCF_EINVAL,
                         "draco: compression_level %d out of range (0..10)", level);
    const api_attrs *at = o->attrs;
    mcf_status rc = api__attrs_check(at, m, "draco", err);
    if (rc != MCF_OK)
        return rc;

    const int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);

    /* Positions: float32 unless lossless needs more; quantization needs
     * float32. Auto falls back to lossless beyond the float range. */
    bool exact_float = true, in_range = true;
    for (int i = 0; i < 3 * nv; i++) {
        const double x = X[i];
        if (std::fabs(x) > FLT_MAX)
            in_range = exact_float = false;
        else if (static_cast<double>(static_cast<float>(x)) != x)
            exact_float = false;
    }
    int q = qopt;
    if (q == -1 && !in_range)
        q = 0;
    attr_plan pp = plan_for(at, API_ATTR_POSITION, q);
    if (!in_range && pp.bits > 0)
        return api__fail(err, MCF_EINVAL,
                         "draco: a coordinate exceeds the float range (quantized "
                         "Draco stores float32)");
    /* Raw: float32 when exact, or when auto keeps a raw float32 input raw;
     * float64 only for lossless doubles. */
    const bool as_float = pp.bits > 0 || exact_float || (q == -1 && in_range);

    const api__attr *tc = at && at->a[API_ATTR_TEXCOORD].corners ? &at->a[API_ATTR_TEXCOORD] : nullptr;
    const api__attr *nm = at && at->a[API_ATTR_NORMAL].corners ? &at->a[API_ATTR_NORMAL] : nullptr;
    const api__attr *co = at && at->a[API_ATTR_COLOR].corners ? &at->a[API_ATTR_COLOR] : nullptr;

    draco::Mesh dm;
    std::vector<int32_t> pv, pt, pn, pc;   /* point -> value, per attribute */
    std::vector<uint32_t> corner_point;    /* face corner -> point */
    if (!tc && !nm && !co) {
        /* Positions only: one point per vertex, unreferenced ones too. */
        dm.set_num_points(static_cast<uint32_t>(nv));
    } else {
        /* One point per distinct (vertex, texcoord, normal, colour) of the
         * corners, in vertex order: seams split, nothing else does. */
        const size_t nc = 3 * static_cast<size_t>(nf);
        std::vector<point_key> keys(nc);
        for (size_t c = 0; c < nc; c++)
            keys[c] = point_key{F[c], tc ? tc->corners[c] : -1,
                                nm ? nm->corners[c] : -1, co ? co->corners[c] : -1};
        std::vector<point_key> uniq(keys);
        std::sort(uniq.begin(), uniq.end());
        uniq.erase(std::unique(uniq.begin(), uniq.end()), uniq.end());
        corner_point.resize(nc);
        for (size_t c = 0; c < nc; c++)
            corner_point[c] = static_cast<uint32_t>(
                std::lower_bound(uniq.begin(), uniq.end(), keys[c]) - uniq.begin());
        dm.set_num_points(static_cast<uint32_t>(uniq.size()));
        for (const point_key &k : uniq) {
            pv.push_back(k.v);
            pt.push_back(k.t);
            pn.push_back(k.n);
            pc.push_back(k.c);
        }
    }

    int att;
    if (as_float) {
        std::vector<float> v = to_float(X, 3 * static_cast<size_t>(nv));
        att = add_attribute(dm, draco::GeometryAttribute::POSITION, 3,
                            draco::DT_FLOAT32, false, nv, v.data(), pv);
    } else {
        att = add_attribute(dm, draco::GeometryAttribute::POSITION, 3,
                            draco::DT_FLOAT64, false, nv, X, pv);
    }
    if (att < 0)
        return api__fail(err, MCF_ENOMEM, "draco: cannot add the POSITION attribute");

    attr_plan pt_plan, pn_plan;
    if (tc) {
        pt_plan = plan_for(at, API_ATTR_TEXCOORD, q);
        std::vector<float> v = to_float(tc->values, 2 * static_cast<size_t>(tc->nvalues));
        if (add_attribute(dm, draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32,
                          false, tc->nvalues, v.data(), pt) < 0)
            return api__fail(err, MCF_ENOMEM, "draco: cannot add TEX_COORD");
    }
    if (nm) {
        pn_plan = plan_for(at, API_ATTR_NORMAL, q);
        double *N = nullptr;
        if ((rc = api__attrs_normals(at, m, &N, err)) != MCF_OK)
            return rc;
        std::vector<float> v = to_float(N, 3 * static_cast<size_t>(nm->nvalues));
        std::free(N);
        if (add_attribute(dm, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32,
                          false, nm->nvalues, v.data(), pn) < 0)
            return api__fail(err, MCF_ENOMEM, "draco: cannot add NORMAL");
    }
    if (co) {
        /* Colours as normalized bytes, as glTF and draco_encoder store them. */
        const size_t n = static_cast<size_t>(co->nvalues) * co->ncomp;
        std::vector<uint8_t> v(n);
        for (size_t i = 0; i < n; i++) {
            const double b = std::floor(co->values[i] * 255.0 + 0.5);
            v[i] = static_cast<uint8_t>(b < 0 ? 0 : b > 255 ? 255 : b);
        }
        if (add_attribute(dm, draco::GeometryAttribute::COLOR, co->ncomp,
                          draco::DT_UINT8, true, co->nvalues, v.data(), pc) < 0)
            return api__fail(err, MCF_ENOMEM, "draco: cannot add COLOR");
    }

    dm.SetNumFaces(static_cast<size_t>(nf));
    for (int f = 0; f < nf; f++) {
        draco::Mesh::Face face;
        for (int k = 0; k < 3; k++)
            face[k] = draco::PointIndex(corner_point.empty()
                                            ? static_cast<uint32_t>(F[3 * f + k])
                                            : corner_point[3 * static_cast<size_t>(f) + k]);
        dm.SetFace(draco::FaceIndex(static_cast<uint32_t>(f)), face);
    }

    draco::Encoder enc;
    if (pp.bits > 0)
        enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, pp.bits);
    if (tc && pt_plan.bits > 0) {
        const api__attr &t = *tc;
        /* The input's grid only when every value lies on it: a hostile
         * stream's texcoord prediction can decode values far outside its
         * declared range (1.8e6 on a grid of range 1), and quantizing those
         * on that grid made libdraco's entropy coder ask for 4 GB. */
        bool on_grid = pt_plan.grid && pt_plan.bits == t.bits;
        for (int i = 0; on_grid && i < t.nvalues; i++)
            for (int c = 0; c < 2; c++) {
                const float v = static_cast<float>(t.values[2 * i + c]);
                on_grid = on_grid && v >= t.qorigin[c] && v <= t.qorigin[c] + t.qrange;
            }
        if (on_grid) {
            /* The input's grid: every value comes back exactly. */
            enc.SetAttributeExplicitQuantization(draco::GeometryAttribute::TEX_COORD,
                                                 t.bits, 2, t.qorigin, t.qrange);
        } else {
            enc.SetAttributeQuantization(draco::GeometryAttribute::TEX_COORD,
                                         pt_plan.bits);
        }
    }
    if (nm && pn_plan.bits > 0)
        enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, pn_plan.bits);
    enc.SetSpeedOptions(10 - level, 10 - level);
    enc.SetEncodingMethod(o->preserve_order ? draco::MESH_SEQUENTIAL_ENCODING
                                            : draco::MESH_EDGEBREAKER_ENCODING);
    draco::EncoderBuffer eb;
    const draco::Status st = enc.EncodeMeshToBuffer(dm, &eb);
    if (!st.ok())
        return api__fail(err, MCF_EMESH, "draco: the encoder refused the mesh: %s",
                         st.error_msg());

    double qerr = 0.0;
    if (max_quant_err) {
        draco::DecoderBuffer db;
        db.Init(eb.data(), eb.size());
        draco::Decoder dec;
        auto res = dec.DecodeMeshFromBuffer(&db);
        if (!res.ok() || !res.value())
            return api__fail(err, MCF_EMESH,
                             "draco: the encoded mesh does not decode: %s",
                             res.ok() ? "no mesh" : res.status().error_msg());
        /* Draco's quantization step is range/(2^q - 1) over the largest
         * extent; rounding errs by half a step, float32 dequantization by a
         * few ulps more: a full step bounds both. Float32 storage rounds
         * each coordinate by half an ulp. Lossless: exact, tol 0. */
        double tol = 0.0;
        if (pp.bits > 0 || (as_float && !exact_float)) {
            double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL},
                   hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
            for (int i = 0; i < 3 * nv; i++) {
                lo[i % 3] = std::min(lo[i % 3], X[i]);
                hi[i % 3] = std::max(hi[i % 3], X[i]);
            }
            double range = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
            if (pp.bits > 0)
                tol = range / (std::ldexp(1.0, pp.bits) - 1.0);
            /* plus float32 rounding of the stored inputs themselves */
            double amax = std::max({std::fabs(lo[0]), std::fabs(lo[1]),
                                    std::fabs(lo[2]), std::fabs(hi[0]),
                                    std::fabs(hi[1]), std::fabs(hi[2])});
            tol += 4.0 * amax * FLT_EPSILON;
        }
        int bad = -1;
        if (!measure(nv, X, nf, F, *res.value(), tol, &qerr, &bad))
            return api__fail(err, MCF_EMESH,
                             "draco: round-trip check failed: input face %d has no "
                             "decoded counterpart within %g",
                             bad, tol);
    }
    rc = api_buf_append(out, eb.data(), eb.size());
    if (rc != MCF_OK) {
        if (rc == MCF_ENOMEM)
            return api__fail(err, rc, "draco: out of memory for %zu bytes",
                             eb.size());
        return api__fail(err, rc,
                         "draco: output of %zu bytes exceeds its maximum of %zu bytes",
                         eb.size(), out->max);
    }
    if (max_quant_err)
        *max_quant_err = qerr;
    return MCF_OK;
}

/* ------------------------------------------- primitives (glTF, all attributes) */

static_assert(draco::GeometryAttribute::POSITION == API__DRACO_POSITION &&
                  draco::GeometryAttribute::NORMAL == API__DRACO_NORMAL &&
                  draco::DT_FLOAT32 == API__DRACO_FLOAT32,
              "api_internal.h's Draco numbers");

mcf_status prim_decode(const void *buf, size_t len, const api_limits *lim,
                       api__draco_prim *out, mcf_error *err)
{
    mcf_status rc = buf ? check_stream(buf, len, lim, err)
                        : api__fail(err, MCF_EDECODE, "draco: no stream");
    if (rc != MCF_OK)
        return rc;
    std::unique_ptr<draco::Mesh> dm, raw;
    for (int pass = 0; pass < 2; pass++) {
        /* pass 1: transforms skipped, for each attribute's quantization */
        draco::DecoderBuffer db;
        db.Init(static_cast<const char *>(buf), len);
        draco::Decoder dec;
        if (pass == 1)
            for (int t = draco::GeometryAttribute::POSITION;
                 t < draco::GeometryAttribute::NAMED_ATTRIBUTES_COUNT; t++)
                dec.SetSkipAttributeTransform(static_cast<draco::GeometryAttribute::Type>(t));
        auto res = dec.DecodeMeshFromBuffer(&db);
        if (!res.ok() || !res.value()) {
            if (pass == 1)
                break;
            return api__fail(err, MCF_EDECODE, "draco: %s",
                             res.ok() ? "no mesh" : res.status().error_msg());
        }
        (pass ? raw : dm) = std::move(res).value();
    }
    const size_t npts = dm->num_points(), nf = dm->num_faces();
    if (npts > static_cast<size_t>(lim->max_vertices) ||
        nf > static_cast<size_t>(lim->max_faces))
        return api__fail(err, MCF_ELIMIT,
                         "draco: %zu points and %zu faces exceed max_vertices (%d) "
                         "or max_faces (%d)",
                         npts, nf, lim->max_vertices, lim->max_faces);
    if (nf == 0)
        return api__fail(err, MCF_EDECODE, "draco: mesh has no faces");
    out->npoints = static_cast<int>(npts);
    out->nfaces = static_cast<int>(nf);
    out->faces = static_cast<int32_t *>(std::malloc(3 * sizeof(int32_t) * nf));
    const int na = dm->num_attributes();
    out->attr = static_cast<api__draco_attr *>(
        std::calloc(static_cast<size_t>(na > 0 ? na : 1), sizeof(api__draco_attr)));
    if (!out->faces || !out->attr)
        return api__fail(err, MCF_ENOMEM, "draco: out of memory for %zu faces", nf);
    for (size_t f = 0; f < nf; f++) {
        const draco::Mesh::Face &face = dm->face(draco::FaceIndex(static_cast<uint32_t>(f)));
        for (int k = 0; k < 3; k++) {
            if (face[k].value() >= npts)
                return api__fail(err, MCF_EDECODE,
                                 "draco: face %zu refers to point %u of %zu", f,
                                 face[k].value(), npts);
            out->faces[3 * f + k] = static_cast<int32_t>(face[k].value());
        }
    }
    for (int i = 0; i < na; i++) {
        const draco::PointAttribute *a = dm->attribute(i);
        api__draco_attr &o = out->attr[out->nattr++];
        const draco::DataType dt = a->data_type();
        const int64_t sz = draco::DataTypeLength(dt);
        const int nc = a->num_components();
        const draco::DataBuffer *b = a->buffer();
        if (dt < draco::DT_INT8 || dt > draco::DT_FLOAT64 || nc < 1 || nc > 4 ||
            !b || a->byte_offset() < 0 || a->byte_stride() < nc * sz)
            return api__fail(err, MCF_EDECODE,
                             "draco: attribute %u has %d components of data type %d",
                             a->unique_id(), nc, static_cast<int>(dt));
        o.id = static_cast<int>(a->unique_id());
        o.type = a->attribute_type();
        o.dtype = dt;
        o.ncomp = nc;
        o.normalized = a->normalized();
        o.vsize = static_cast<int>(nc * sz);
        const draco::PointAttribute *ra = raw ? raw->GetAttributeByUniqueId(a->unique_id()) : nullptr;
        o.bits = transform_bits(ra, o.qorigin, &o.qrange);
        o.data = static_cast<unsigned char *>(std::malloc(npts * o.vsize + 1));
        if (!o.data)
            return api__fail(err, MCF_ENOMEM, "draco: out of memory for %zu points", npts);
        for (size_t p = 0; p < npts; p++) {
            const uint32_t v = a->mapped_index(draco::PointIndex(static_cast<uint32_t>(p))).value();
            const int64_t at = a->byte_offset() + a->byte_stride() * static_cast<int64_t>(v);
            if (v >= a->size() || at < 0 ||
                static_cast<uint64_t>(at) + o.vsize > b->data_size())
                return api__fail(err, MCF_EDECODE,
                                 "draco: attribute %d of point %zu out of its buffer", o.id, p);
            std::memcpy(o.data + p * o.vsize, b->data() + at, o.vsize);
        }
    }
    return MCF_OK;
}

mcf_status prim_encode(const api__draco_prim *p, int level, api_buf *out,
                       mcf_error *err)
{
    draco::Mesh dm;
    dm.set_num_points(static_cast<uint32_t>(p->npoints));
    const std::vector<int32_t> identity;
    for (int i = 0; i < p->nattr; i++) {
        const api__draco_attr &a = p->attr[i];
        const int id = add_attribute(dm, static_cast<draco::GeometryAttribute::Type>(a.type),
                                     a.ncomp, static_cast<draco::DataType>(a.dtype),
                                     a.normalized != 0, static_cast<size_t>(p->npoints),
                                     a.data, identity);
        if (id < 0)
            return api__fail(err, MCF_ENOMEM, "draco: cannot add attribute %d", a.id);
        dm.attribute(id)->set_unique_id(static_cast<uint32_t>(a.id));
    }
    dm.SetNumFaces(static_cast<size_t>(p->nfaces));
    for (int f = 0; f < p->nfaces; f++) {
        draco::Mesh::Face face;
        for (int k = 0; k < 3; k++) {
            const int32_t v = p->faces[3 * static_cast<size_t>(f) + k];
            if (v < 0 || v >= p->npoints)
                return api__fail(err, MCF_EINVAL, "draco: face %d refers to point %d of %d",
                                 f, static_cast<int>(v), p->npoints);
            face[k] = draco::PointIndex(static_cast<uint32_t>(v));
        }
        dm.SetFace(draco::FaceIndex(static_cast<uint32_t>(f)), face);
    }
    draco::ExpertEncoder enc(dm);
    for (int i = 0; i < p->nattr; i++) {
        const api__draco_attr &a = p->attr[i];
        const int bits = std::min(a.bits, API_DRACO_MAX_BITS);
        if (bits <= 0 || a.dtype != draco::DT_FLOAT32)
            continue;
        /* The input's grid when every value still lies on it (an attribute
         * nobody changed comes back exactly; see encode() on a hostile
         * stream's values far off its grid), else a new one. */
        bool on_grid = a.qrange > 0.0f && a.bits == bits && a.ncomp <= 4 &&
                       a.type != draco::GeometryAttribute::NORMAL;
        for (int q = 0; on_grid && q < p->npoints; q++)
            for (int c = 0; c < a.ncomp; c++) {
                float v;
                std::memcpy(&v, a.data + static_cast<size_t>(q) * a.vsize + 4 * c, 4);
                on_grid = on_grid && v >= a.qorigin[c] && v <= a.qorigin[c] + a.qrange;
            }
        if (on_grid)
            enc.SetAttributeExplicitQuantization(i, bits, a.ncomp, a.qorigin, a.qrange);
        else
            enc.SetAttributeQuantization(i, bits);
    }
    enc.SetSpeedOptions(10 - level, 10 - level);
    enc.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
    draco::EncoderBuffer eb;
    const draco::Status st = enc.EncodeToBuffer(&eb);
    if (!st.ok())
        return api__fail(err, MCF_EMESH, "draco: the encoder refused the primitive: %s",
                         st.error_msg());
    mcf_status rc = api_buf_append(out, eb.data(), eb.size());
    if (rc != MCF_OK)
        return api__fail(err, rc, "draco: no room for %zu bytes", eb.size());
    return MCF_OK;
}

} /* namespace */

extern "C" mcf_status api_draco_decode(const void *buf, size_t len,
                                       const api_limits *lim, mcf_mesh **out,
                                       mcf_error *err)
{
    return api_draco_decode_attrs(buf, len, lim, out, nullptr, err);
}

extern "C" mcf_status api_draco_decode_attrs(const void *buf, size_t len,
                                             const api_limits *lim,
                                             mcf_mesh **out, api_attrs **attrs,
                                             mcf_error *err)
{
    try {
        return decode(buf, len, lim, out, attrs, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while decoding");
    } catch (...) {
        return api__fail(err, MCF_EDECODE, "draco: the decoder failed (exception)");
    }
}

extern "C" mcf_status api_draco_encode(const mcf_mesh *m,
                                       const api_encode_opts *o, api_buf *out,
                                       double *max_quant_err, mcf_error *err)
{
    try {
        return encode(m, o, out, max_quant_err, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while encoding");
    } catch (...) {
        return api__fail(err, MCF_EMESH, "draco: the encoder failed (exception)");
    }
}

extern "C" int api__draco_declared(const void *buf, size_t len, uint32_t *nv,
                                   uint32_t *nf)
{
    api_limits lim;
    uint32_t d[2] = {0, 0};
    if (len < 11 || memcmp(buf, "DRACO", 5) != 0)
        return 0;
    api_limits_default(&lim);
    lim.max_faces = lim.max_vertices = 0x7fffffff;
    try {
        check_counts(static_cast<const uint8_t *>(buf), len, &lim, nullptr, d);
    } catch (...) {
        return 0;
    }
    *nv = d[0];
    *nf = d[1];
    return d[1] > 0;
}

extern "C" void api__draco_prim_free(api__draco_prim *p)
{
    if (!p)
        return;
    for (int i = 0; i < p->nattr; i++)
        std::free(p->attr[i].data);
    std::free(p->attr);
    std::free(p->faces);
    std::memset(p, 0, sizeof *p);
}

extern "C" mcf_status api__draco_prim_decode(const void *buf, size_t len,
                                             const api_limits *lim,
                                             api__draco_prim *out, mcf_error *err)
{
    api_limits def;
    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    std::memset(out, 0, sizeof *out);
    try {
        return prim_decode(buf, len, lim, out, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while decoding");
    } catch (...) {
        return api__fail(err, MCF_EDECODE, "draco: the decoder failed (exception)");
    }
}

extern "C" mcf_status api__draco_prim_encode(const api__draco_prim *p, int level,
                                             api_buf *out, mcf_error *err)
{
    if (level < 0 || level > 10)
        return api__fail(err, MCF_EINVAL,
                         "draco: compression_level %d out of range (0..10)", level);
    try {
        return prim_encode(p, level, out, err);
    } catch (const std::bad_alloc &) {
        return api__fail(err, MCF_ENOMEM, "draco: out of memory while encoding");
    } catch (...) {
        return api__fail(err, MCF_EMESH, "draco: the encoder failed (exception)");
    }
}
