/* SPDX-License-Identifier: MIT */
/*
 * api_draco_decode.cc - the Draco decoder: a stream checked
 * (api_draco_check.cc), decoded by libdraco into an mcf_mesh, its
 * attributes and quantization read, and glTF's primitives decoded.
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
 */
#include <algorithm>
#include <cstring>
#include <memory>
#include <vector>

#include "draco/attributes/attribute_octahedron_transform.h"
#include "draco/attributes/attribute_quantization_transform.h"
#include "draco/compression/decode.h"

#include "api_draco_internal.h"

namespace api_draco {

/* Reads the 3 components of value v of attribute a as doubles. Done by
 * hand rather than with GeometryAttribute::ConvertValue, whose template
 * (compiled here) would load a corrupt stream's DT_BOOL bytes as bool
 * (undefined behaviour) and does not bound-check the last component
 * against the buffer. Integer types read as their values (divided by the
 * type's maximum when the attribute is marked normalized, as Draco does). */
static bool read_values(const draco::PointAttribute *a, uint32_t v, int n,
                        bool unit, double *out);

bool read_position(const draco::PointAttribute *a, uint32_t v, double out[3])
{
    return read_values(a, v, 3, false, out);
}

/* The first n components of value v; integer types are divided by their
 * maximum when the attribute is normalized or unit is set (colours). */
static bool read_values(const draco::PointAttribute *a, uint32_t v, int n, bool unit,
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
static size_t weld_split_points(const draco::Mesh &dm, const draco::PointAttribute *pos,
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

static mcf_status read_attrs(const void *buf, size_t len, const draco::Mesh &dm,
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

/* The input's size against lim, then check_stream. */
static mcf_status check_input(const void *buf, size_t len, const api_limits *lim,
                              mcf_error *err)
{
    if (!buf && len)
        return api__fail(err, MCF_EINVAL, "draco: NULL buffer");
    if (len > lim->max_input_bytes)
        return api__fail(err, MCF_ELIMIT,
                         "draco: input of %zu bytes exceeds max_input_bytes (%zu)",
                         len, lim->max_input_bytes);
    if (len == 0)
        return api__fail(err, MCF_EDECODE, "draco: empty input");
    return check_stream(buf, len, lim, err);
}

/* libdraco's decode of the stream into *dm. */
static mcf_status decode_stream(const void *buf, size_t len, std::unique_ptr<draco::Mesh> *dm,
                                mcf_error *err)
{
    draco::DecoderBuffer db;
    db.Init(static_cast<const char *>(buf), len);
    draco::Decoder dec;
    auto res = dec.DecodeMeshFromBuffer(&db);
    if (!res.ok())
        return api__fail(err, MCF_EDECODE, "draco: %s",
                         res.status().error_msg());
    *dm = std::move(res).value();
    if (!*dm)
        return api__fail(err, MCF_EDECODE, "draco: decoder returned no mesh");
    return MCF_OK;
}

/* The decoded mesh's POSITION (3 components) in *pos, and its counts of
 * values and faces: within lim, neither zero. */
static mcf_status check_geometry(const draco::Mesh &dm, const api_limits *lim,
                                 const draco::PointAttribute **pos, mcf_error *err)
{
    const draco::PointAttribute *p = dm.GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!p)
        return api__fail(err, MCF_EDECODE, "draco: mesh has no POSITION attribute");
    if (p->num_components() != 3)
        return api__fail(err, MCF_EDECODE,
                         "draco: POSITION has %d components, 3 needed",
                         static_cast<int>(p->num_components()));
    const size_t nvals = p->size();
    const size_t nfaces = dm.num_faces();
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
    *pos = p;
    return MCF_OK;
}

/* The positions (finite) into X and the faces, as position values
 * (mapped_index), into F; both already sized. */
static mcf_status read_geometry(const draco::Mesh &dm, const draco::PointAttribute *pos,
                                std::vector<double> &X, std::vector<int32_t> &F,
                                mcf_error *err)
{
    const size_t nvals = X.size() / 3, nfaces = F.size() / 3;
    const size_t npts = dm.num_points();
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
            dm.face(draco::FaceIndex(static_cast<uint32_t>(f)));
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
    return MCF_OK;
}

mcf_status decode(const void *buf, size_t len, const api_limits *lim,
                  mcf_mesh **out, api_attrs **attrs, mcf_error *err)
{
    api_limits def;
    std::unique_ptr<draco::Mesh> dm;
    const draco::PointAttribute *pos = nullptr;
    mcf_status rc;
    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if ((rc = check_input(buf, len, lim, err)) != MCF_OK ||
        (rc = decode_stream(buf, len, &dm, err)) != MCF_OK ||
        (rc = check_geometry(*dm, lim, &pos, err)) != MCF_OK)
        return rc;
    std::vector<double> X(3 * pos->size());
    std::vector<int32_t> F(3 * dm->num_faces());
    if ((rc = read_geometry(*dm, pos, X, F, err)) != MCF_OK)
        return rc;
    const size_t nv = weld_split_points(*dm, pos, X, F);
    mcf_mesh *m = mcf_mesh_new(static_cast<int>(nv), X.data(),
                               static_cast<int>(F.size() / 3), F.data(), err);
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
static mcf_status read_attrs(const void *buf, size_t len, const draco::Mesh &dm,
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

} // namespace api_draco
