/* SPDX-License-Identifier: MIT */
/*
 * api_draco_encode.cc - the Draco encoder: an mcf_mesh (and its
 * attributes) into a draco::Mesh and a stream, measured on the way back
 * (api_draco_measure.cc), and glTF's primitives encoded.
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
 */
#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "draco/compression/decode.h"
#include "draco/compression/encode.h"
#include "draco/compression/expert_encode.h"

#include "api_draco_internal.h"

namespace api_draco {

/* ------------------------------------------------------------- encoder */

/* Quantization bits at most: Draco's encoder allocates memory that
 * doubles per bit whatever the mesh (measured on an 812-vertex sphere:
 * 24 bits 58 MB, 26 bits 200 MB; 30 bits about 3 GB). */
#define API_DRACO_MAX_BITS 24

/* Draco quantizes in float32 on a range r (the largest extent over the
 * components): a step r / 2^bits below FLT_MIN underflows, and the
 * inverse scale overflows, so the dequantized values are garbage
 * (fuzz_gltf, 2026-11-29: a Draco glTF whose 3 points span 7e-40 in z
 * came back as one point at -7.7e-34, every triangle collapsed). Such an
 * attribute is stored raw (float32, exact) instead. */
static bool step_underflows(double range, int bits)
{
    return range > 0.0 && range / std::ldexp(1.0, bits) < FLT_MIN;
}

/* An explicit grid reaches libdraco's quantizer through draco::Options as
 * text: SetAttributeExplicitQuantization writes std::to_string ("%f", six
 * decimals), which strtof and atof read back, so an origin of 3.5e-37 and
 * a range of 8e-15 became 0 and 0 and every point came back at one place
 * (fuzz_gltf, 2026-11-29), and a real file's origin -0.0946834 became
 * -0.094683, off its grid. set_explicit_grid writes the two options again
 * as "%.17g" of each float, which both read back as that very float. */
static std::string grid_text(const float *v, int n)
{
    std::string s;
    char t[40];
    for (int c = 0; c < n; c++) {
        std::snprintf(t, sizeof t, c ? " %.17g" : "%.17g", static_cast<double>(v[c]));
        s += t;
    }
    return s;
}

template <class Encoder, class Key>
static void set_explicit_grid(Encoder &enc, Key key, int bits, int n, const float *origin,
                              float range)
{
    enc.SetAttributeExplicitQuantization(key, bits, n, origin, range);
    const draco::Options *cur = enc.options().FindAttributeOptions(key);
    draco::Options o = cur ? *cur : draco::Options();
    o.SetString("quantization_origin", grid_text(origin, n));
    o.SetString("quantization_range", grid_text(&range, 1));
    enc.options().SetAttributeOptions(key, o);
}

/* The grid set_explicit_grid gives libdraco, read from the same text the
 * way libdraco reads it, with its float32 arithmetic (draco::Quantizer,
 * Dequantizer, AttributeQuantizationTransform): a value v is stored as
 * q = floor((v - origin) * (maxq / range) + 0.5) and read back as
 * q * (range / maxq) + origin. */
struct draco_grid {
    float origin[4], inv, delta;
    int32_t maxq;
    bool ok;
};

static draco_grid grid_of(const float *origin, int n, float range, int bits)
{
    draco_grid g;
    const std::string ot = grid_text(origin, n), rt = grid_text(&range, 1);
    const char *p = ot.c_str();
    for (int c = 0; c < n && c < 4; c++) {
        char *e;
        g.origin[c] = std::strtof(p, &e);
        p = e;
    }
    const float r = static_cast<float>(std::atof(rt.c_str()));
    g.maxq = static_cast<int32_t>((1u << bits) - 1u);
    g.inv = static_cast<float>(g.maxq) / r;
    g.delta = r / static_cast<float>(g.maxq);
    g.ok = r > 0.0f && std::isfinite(g.inv) && g.delta > 0.0f;
    return g;
}

/* The grid cell libdraco's quantizer gives v (draco::Quantizer::
 * QuantizeFloat after AttributeQuantizationTransform's subtraction of the
 * origin), in float32 as it computes it: floor((v - origin) * inv + 0.5),
 * as a double so that a NaN or an overflow can be told apart before any
 * conversion to int. */
static double draco_cell(float v, float origin, float inv)
{
    float d = v - origin;
    d *= inv;
    return std::floor(static_cast<double>(d + 0.5f));
}

/* 1 when the value v of component c comes back bit for bit through g.
 * Checking every value is what "the input's grid keeps every value"
 * means: a value merely inside the range may sit between two grid points,
 * and where the step nears float32's resolution at the values, neighbours
 * fall on one point. Values that come back exactly stay distinct, so no
 * face collapses. */
static bool on_draco_grid(float v, int c, const draco_grid &g)
{
    const double qd = draco_cell(v, g.origin[c], g.inv);
    if (!(qd >= 0.0 && qd <= static_cast<double>(g.maxq)))
        return false;
    const float back = static_cast<float>(static_cast<int32_t>(qd)) * g.delta + g.origin[c];
    return back == v;
}

/* The bits, from bits up to API_DRACO_MAX_BITS, at which libdraco's own
 * grid of the n points' positions (AttributeQuantizationTransform::
 * ComputeParameters: each component's minimum lo, the largest extent as
 * range, 1 when every point is one) keeps distinct points apart; 0 (raw
 * float32) when none does. Points on a finer or shifted grid than that
 * one, or closer than its step, can fall on one grid point, and the glTF
 * reader welds them and drops their triangles (fuzz_gltf, 2026-11-29: a
 * stream whose 7-bit grid did not hold its own values, points 6e-17
 * apart on a step of 1e-15: every triangle vanished). */
static int bits_keeping_points(const unsigned char *data, int vsize, int n, int ncomp,
                               const float *lo, const float *hi, int bits)
{
    struct point {
        std::array<int32_t, 4> q;
        std::array<float, 4> v;
        bool operator<(const point &o) const { return q < o.q || (q == o.q && v < o.v); }
    };
    float range = 0.0f;
    for (int c = 0; c < ncomp; c++)
        range = std::max(range, hi[c] - lo[c]);
    if (range == 0.0f)
        range = 1.0f;
    std::vector<point> pts(static_cast<size_t>(n));
    for (; bits <= API_DRACO_MAX_BITS; bits++) {
        const float inv = static_cast<float>((1u << bits) - 1u) / range;
        for (int i = 0; i < n; i++) {
            point &p = pts[static_cast<size_t>(i)];
            p.q.fill(0);
            p.v.fill(0.0f);
            for (int c = 0; c < ncomp; c++) {
                std::memcpy(&p.v[c], data + static_cast<size_t>(i) * vsize + 4 * c, 4);
                const double qd = draco_cell(p.v[c], lo[c], inv);
                /* a NaN or a value off [lo, hi] (none: lo and hi are theirs) */
                p.q[c] = qd >= 0.0 && qd <= 16777216.0 ? static_cast<int32_t>(qd) : -1;
            }
        }
        std::sort(pts.begin(), pts.end());
        bool apart = true;
        for (size_t i = 1; apart && i < pts.size(); i++)
            apart = pts[i].q != pts[i - 1].q || pts[i].v == pts[i - 1].v;
        if (apart)
            return bits;
    }
    return 0;
}

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
static attr_plan plan_for(const api_attrs *a, int k, int q)
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
static int add_attribute(draco::Mesh &dm, draco::GeometryAttribute::Type type, int nc,
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

static std::vector<float> to_float(const double *v, size_t n)
{
    std::vector<float> f(n);
    for (size_t i = 0; i < n; i++)
        f[i] = static_cast<float>(v[i]);
    return f;
}

/* The points of the mesh to encode and, per attribute, each point's
 * value (empty: identity); corner_point: each face corner's point. */
struct point_map {
    std::vector<int32_t> pv, pt, pn, pc;   /* point -> value, per attribute */
    std::vector<uint32_t> corner_point;    /* face corner -> point (empty: F) */
};

static void map_points(draco::Mesh &dm, int nv, int nf, const int32_t *F,
                       const api__attr *tc, const api__attr *nm, const api__attr *co,
                       point_map *pm)
{
    if (!tc && !nm && !co) {
        /* Positions only: one point per vertex, unreferenced ones too. */
        dm.set_num_points(static_cast<uint32_t>(nv));
        return;
    }
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
    pm->corner_point.resize(nc);
    for (size_t c = 0; c < nc; c++)
        pm->corner_point[c] = static_cast<uint32_t>(
            std::lower_bound(uniq.begin(), uniq.end(), keys[c]) - uniq.begin());
    dm.set_num_points(static_cast<uint32_t>(uniq.size()));
    for (const point_key &k : uniq) {
        pm->pv.push_back(k.v);
        pm->pt.push_back(k.t);
        pm->pn.push_back(k.n);
        pm->pc.push_back(k.c);
    }
}

/* The faces of dm: F's corners, through corner_point when the points are
 * not the vertices. */
static void set_faces(draco::Mesh &dm, int nf, const int32_t *F,
                      const std::vector<uint32_t> &corner_point)
{
    dm.SetNumFaces(static_cast<size_t>(nf));
    for (int f = 0; f < nf; f++) {
        draco::Mesh::Face face;
        for (int k = 0; k < 3; k++)
            face[k] = draco::PointIndex(corner_point.empty()
                                            ? static_cast<uint32_t>(F[3 * f + k])
                                            : corner_point[3 * static_cast<size_t>(f) + k]);
        dm.SetFace(draco::FaceIndex(static_cast<uint32_t>(f)), face);
    }
}

/* The texcoords' quantization under plan: on the input's grid when the
 * plan keeps it and every value lies on it, else plan.bits. */
static void quantize_texcoords(draco::Encoder &enc, const api__attr &t, attr_plan plan)
{
    /* The input's grid only when every value lies on it: a hostile
     * stream's texcoord prediction can decode values far outside its
     * declared range (1.8e6 on a grid of range 1), and quantizing those
     * on that grid made libdraco's entropy coder ask for 4 GB. */
    bool on_grid = plan.grid && plan.bits == t.bits && t.qrange > 0.0f;
    draco_grid g{};
    if (on_grid) {
        g = grid_of(t.qorigin, 2, t.qrange, t.bits);
        on_grid = g.ok;
    }
    for (int i = 0; on_grid && i < t.nvalues; i++)
        for (int c = 0; c < 2; c++)
            on_grid = on_grid && on_draco_grid(static_cast<float>(t.values[2 * i + c]), c, g);
    if (on_grid) {
        /* The input's grid: every value comes back exactly. */
        set_explicit_grid(enc, draco::GeometryAttribute::TEX_COORD, t.bits, 2, t.qorigin,
                          t.qrange);
    } else {
        enc.SetAttributeQuantization(draco::GeometryAttribute::TEX_COORD, plan.bits);
    }
}

/* *qerr: the largest distance of an input corner from its counterpart in
 * eb decoded again (api_draco_measure.cc), within the tolerance the
 * stored precision allows (pos_bits: the positions' quantization, 0: raw;
 * rounded: raw float32 rounded some coordinate). EMESH when a face has no
 * counterpart within it. */
static mcf_status round_trip_error(const draco::EncoderBuffer &eb, int nv, const double *X,
                                   int nf, const int32_t *F, int pos_bits, bool rounded,
                                   double *qerr, mcf_error *err)
{
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
    if (pos_bits > 0 || rounded) {
        double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL},
               hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
        for (int i = 0; i < 3 * nv; i++) {
            lo[i % 3] = std::min(lo[i % 3], X[i]);
            hi[i % 3] = std::max(hi[i % 3], X[i]);
        }
        double range = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
        if (pos_bits > 0)
            tol = range / (std::ldexp(1.0, pos_bits) - 1.0);
        /* plus float32 rounding of the stored inputs themselves */
        double amax = std::max({std::fabs(lo[0]), std::fabs(lo[1]),
                                std::fabs(lo[2]), std::fabs(hi[0]),
                                std::fabs(hi[1]), std::fabs(hi[2])});
        tol += 4.0 * amax * FLT_EPSILON;
    }
    int bad = -1;
    if (!measure(nv, X, nf, F, *res.value(), tol, qerr, &bad))
        return api__fail(err, MCF_EMESH,
                         "draco: round-trip check failed: input face %d has no "
                         "decoded counterpart within %g",
                         bad, tol);
    return MCF_OK;
}

/* The attributes besides POSITION: texcoords and normals (recomputed
 * from the surface) as float32, colours as normalized bytes, each point
 * mapped to its value by pm. */
static mcf_status add_corner_attributes(draco::Mesh &dm, const mcf_mesh *m,
                                        const api_attrs *at, const api__attr *tc,
                                        const api__attr *nm, const api__attr *co,
                                        const point_map &pm, mcf_error *err)
{
    if (tc) {
        std::vector<float> v = to_float(tc->values, 2 * static_cast<size_t>(tc->nvalues));
        if (add_attribute(dm, draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32,
                          false, tc->nvalues, v.data(), pm.pt) < 0)
            return api__fail(err, MCF_ENOMEM, "draco: cannot add TEX_COORD");
    }
    if (nm) {
        double *N = nullptr;
        mcf_status rc = api__attrs_normals(at, m, &N, err);
        if (rc != MCF_OK)
            return rc;
        std::vector<float> v = to_float(N, 3 * static_cast<size_t>(nm->nvalues));
        std::free(N);
        if (add_attribute(dm, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32,
                          false, nm->nvalues, v.data(), pm.pn) < 0)
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
                          draco::DT_UINT8, true, co->nvalues, v.data(), pm.pc) < 0)
            return api__fail(err, MCF_ENOMEM, "draco: cannot add COLOR");
    }
    return MCF_OK;
}

/* The options' ranges: quantization_bits -1 (auto) to API_DRACO_MAX_BITS,
 * compression_level 0 to 10. */
static mcf_status check_options(const api_encode_opts *o, mcf_error *err)
{
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
    return MCF_OK;
}

/* How the positions are stored: pp their quantization (q: the options'
 * bits, auto turned lossless beyond the float range), as_float float32
 * rather than float64, rounded when float32 rounds some coordinate. */
struct position_plan {
    attr_plan pp;
    int q = 0;
    bool as_float = true, rounded = false;
};

/* Positions: float32 unless lossless needs more; quantization needs
 * float32. Auto falls back to lossless beyond the float range. */
static mcf_status plan_positions(const double *X, int nv, const api_attrs *at, int qopt,
                                 position_plan *pl, mcf_error *err)
{
    bool exact_float = true, in_range = true;
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (int i = 0; i < 3 * nv; i++) {
        const double x = X[i];
        lo[i % 3] = std::min(lo[i % 3], x);
        hi[i % 3] = std::max(hi[i % 3], x);
        if (std::fabs(x) > FLT_MAX)
            in_range = exact_float = false;
        else if (static_cast<double>(static_cast<float>(x)) != x)
            exact_float = false;
    }
    /* the range Draco quantizes on (step_underflows) */
    const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 0.0});
    pl->q = qopt;
    if (pl->q == -1 && !in_range)
        pl->q = 0;
    pl->pp = plan_for(at, API_ATTR_POSITION, pl->q);
    const bool too_fine = pl->pp.bits > 0 && step_underflows(extent, pl->pp.bits);
    if (too_fine && qopt == -1) {
        pl->q = 0; /* auto: lossless */
        pl->pp = plan_for(at, API_ATTR_POSITION, 0);
    } else if (too_fine)
        return api__fail(err, MCF_EINVAL,
                         "draco: the positions' extent %g is too small to quantize at "
                         "%d bits (float32 steps underflow; quantization_bits 0 is lossless)",
                         extent, pl->pp.bits);
    if (!in_range && pl->pp.bits > 0)
        return api__fail(err, MCF_EINVAL,
                         "draco: a coordinate exceeds the float range (quantized "
                         "Draco stores float32)");
    /* Raw: float32 when exact, or when auto keeps a raw float32 input raw;
     * float64 only for lossless doubles. */
    pl->as_float = pl->pp.bits > 0 || exact_float || (pl->q == -1 && in_range);
    pl->rounded = pl->as_float && !exact_float;
    return MCF_OK;
}

/* The encoder's settings: each attribute's quantization, the speed of
 * the compression level, edgebreaker or (preserve_order) sequential. */
static void configure_encoder(draco::Encoder &enc, const api_encode_opts *o,
                              const api_attrs *at, const position_plan &pl,
                              const api__attr *tc, const api__attr *nm)
{
    const attr_plan pt_plan = tc ? plan_for(at, API_ATTR_TEXCOORD, pl.q) : attr_plan();
    const attr_plan pn_plan = nm ? plan_for(at, API_ATTR_NORMAL, pl.q) : attr_plan();
    const int level = o->compression_level;
    if (pl.pp.bits > 0)
        enc.SetAttributeQuantization(draco::GeometryAttribute::POSITION, pl.pp.bits);
    if (tc && pt_plan.bits > 0)
        quantize_texcoords(enc, *tc, pt_plan);
    if (nm && pn_plan.bits > 0)
        enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, pn_plan.bits);
    enc.SetSpeedOptions(10 - level, 10 - level);
    enc.SetEncodingMethod(o->preserve_order ? draco::MESH_SEQUENTIAL_ENCODING
                                            : draco::MESH_EDGEBREAKER_ENCODING);
}

mcf_status encode(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                  double *max_quant_err, mcf_error *err)
{
    api_encode_opts defo;
    if (!o) {
        api_encode_opts_init(&defo);
        o = &defo;
    }
    mcf_status rc = check_options(o, err);
    if (rc != MCF_OK)
        return rc;
    const api_attrs *at = o->attrs;
    if ((rc = api__attrs_check(at, m, "draco", err)) != MCF_OK)
        return rc;

    const int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m);
    const double *X = mcf_mesh_positions(m);
    const int32_t *F = mcf_mesh_faces(m);
    position_plan pl;
    if ((rc = plan_positions(X, nv, at, o->quantization_bits, &pl, err)) != MCF_OK)
        return rc;

    const api__attr *tc = at && at->a[API_ATTR_TEXCOORD].corners ? &at->a[API_ATTR_TEXCOORD] : nullptr;
    const api__attr *nm = at && at->a[API_ATTR_NORMAL].corners ? &at->a[API_ATTR_NORMAL] : nullptr;
    const api__attr *co = at && at->a[API_ATTR_COLOR].corners ? &at->a[API_ATTR_COLOR] : nullptr;

    draco::Mesh dm;
    point_map pm;
    map_points(dm, nv, nf, F, tc, nm, co, &pm);

    int att;
    if (pl.as_float) {
        std::vector<float> v = to_float(X, 3 * static_cast<size_t>(nv));
        att = add_attribute(dm, draco::GeometryAttribute::POSITION, 3,
                            draco::DT_FLOAT32, false, nv, v.data(), pm.pv);
    } else {
        att = add_attribute(dm, draco::GeometryAttribute::POSITION, 3,
                            draco::DT_FLOAT64, false, nv, X, pm.pv);
    }
    if (att < 0)
        return api__fail(err, MCF_ENOMEM, "draco: cannot add the POSITION attribute");
    if ((rc = add_corner_attributes(dm, m, at, tc, nm, co, pm, err)) != MCF_OK)
        return rc;
    set_faces(dm, nf, F, pm.corner_point);

    draco::Encoder enc;
    configure_encoder(enc, o, at, pl, tc, nm);
    draco::EncoderBuffer eb;
    const draco::Status st = enc.EncodeMeshToBuffer(dm, &eb);
    if (!st.ok())
        return api__fail(err, MCF_EMESH, "draco: the encoder refused the mesh: %s",
                         st.error_msg());

    double qerr = 0.0;
    if (max_quant_err &&
        (rc = round_trip_error(eb, nv, X, nf, F, pl.pp.bits, pl.rounded, &qerr, err)) != MCF_OK)
        return rc;
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
        int bits = std::min(a.bits, API_DRACO_MAX_BITS);
        if (bits <= 0 || a.dtype != draco::DT_FLOAT32)
            continue;
        /* The input's grid when every value still lies on it (an attribute
         * nobody changed comes back exactly; see encode() on a hostile
         * stream's values far off its grid), else a new one. */
        bool on_grid = a.qrange > 0.0f && a.bits == bits && a.ncomp <= 4 &&
                       a.type != draco::GeometryAttribute::NORMAL;
        draco_grid g{};
        if (on_grid) {
            g = grid_of(a.qorigin, a.ncomp, a.qrange, bits);
            on_grid = g.ok;
        }
        for (int q = 0; on_grid && q < p->npoints; q++)
            for (int c = 0; c < a.ncomp; c++) {
                float v;
                std::memcpy(&v, a.data + static_cast<size_t>(q) * a.vsize + 4 * c, 4);
                on_grid = on_grid && on_draco_grid(v, c, g);
            }
        float vlo[4] = {FLT_MAX, FLT_MAX, FLT_MAX, FLT_MAX}, vhi[4] = {-FLT_MAX, -FLT_MAX, -FLT_MAX, -FLT_MAX};
        for (int q = 0; q < p->npoints; q++)
            for (int c = 0; c < a.ncomp && c < 4; c++) {
                float v;
                std::memcpy(&v, a.data + static_cast<size_t>(q) * a.vsize + 4 * c, 4);
                vlo[c] = std::min(vlo[c], v);
                vhi[c] = std::max(vhi[c], v);
            }
        double extent = 0.0;
        for (int c = 0; c < a.ncomp && c < 4; c++)
            extent = std::max(extent, static_cast<double>(vhi[c]) - vlo[c]);
        if (step_underflows(on_grid ? a.qrange : extent, bits))
            continue; /* raw float32 */
        if (!on_grid && a.type == draco::GeometryAttribute::POSITION && a.ncomp <= 4) {
            const int keep = bits_keeping_points(a.data, a.vsize, p->npoints, a.ncomp, vlo,
                                                 vhi, bits);
            if (keep == 0)
                continue; /* raw float32 */
            bits = keep;
        }
        if (on_grid)
            set_explicit_grid(enc, i, bits, a.ncomp, a.qorigin, a.qrange);
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

} // namespace api_draco
