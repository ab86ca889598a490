/* SPDX-License-Identifier: MIT */
/*
 * api_internal.h - helpers shared by the files of the api layer, not
 * public (the server and the CLI use api.h only).
 *
 * Internal non-static functions carry the api__ prefix, as core's carry
 * mcf__. Most of them serve the mesh codecs (api_obj.c, api_off.c,
 * api_ply.c, api_stl.c): the text helpers (tokens, lines, numbers, tokens
 * quoted in error messages) live in api_text.c, the decode prologue and
 * encode epilogue in api_codec.c (a leaf below the codecs), and the
 * byte-level ones below are inline because the binary readers call them
 * for every value. This header is
 * also included (as C) by api_draco*.cc, so what is inline here is valid
 * C++ too.
 */
#ifndef API_INTERNAL_H
#define API_INTERNAL_H

#include <stdint.h>
#include <string.h>

#include "api.h"

/* Fills err (if non-NULL) with a formatted one-line message and returns
 * code: return api__fail(err, MCF_EDECODE, "line %d: ...", line);
 * the core's public mcf_error_set, so both layers format errors alike. */
#define api__fail mcf_error_set

/* ------------------------------------------------------- JSON (api_json.c) */

/* Adds item under key of object o and returns 1; deletes item when it
 * cannot be attached and returns 0, as for a NULL item (an allocation
 * that failed), so a builder checks once. */
int api__json_put(cJSON *o, const char *key, cJSON *item);
/* A number under key, or null when v is not finite (NaN: "not known
 * here"). 1, or 0 as api__json_put. */
int api__json_num(cJSON *o, const char *key, double v);

/* The next byte of JSON text s (n bytes) at or after *i that lies outside
 * strings, moving *i past it; a string counts as its opening '"', and *i
 * then moves past its closing one (escapes skipped) or to the end. -1 at
 * the end. For scans that must not parse (nesting, value counts): no byte
 * at or past s + n is read (api_text.c). */
int api__json_next(const char *s, size_t n, size_t *i);

/* ------------------------------------------------------- text (api_text.c) */

/* White space within a line: ' ', '\t', '\r', '\f', '\v'. Not '\n', which
 * ends a line for every line-based reader ('\r' of a "\r\n" ending is
 * thus trailing white space). c is a char or an unsigned char value. */
static inline int api__is_space(int c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
}

/* Parses a decimal or scientific number from the n bytes at s (which need
 * not be NUL-terminated and are never read past s + n): the whole span
 * must be the number. Returns 0 and *out on success, -1 when the text is
 * not a number or too long (> 63 bytes). Non-finite values ("nan", "inf",
 * overflow to infinity) are returned as such: the caller decides. */
int api__parse_double(const char *s, size_t n, double *out);

/* Parses a signed decimal integer from the n bytes at s (not read past
 * s + n): optional '-', then digits only, the whole span. Returns 0 and
 * *out, or -1 (*out unchanged) when the text is empty, has a '+' sign or
 * leading white space, is longer than 31 bytes, is not an integer or
 * does not fit in a long long. */
int api__parse_int(const char *s, size_t n, long long *out);

/* Is the n-byte token t exactly the NUL-terminated word? */
int api__tok_is(const char *t, size_t n, const char *word);

/* The next token of the text [*s, e): skips api__is_space bytes, sets
 * *tok to the first byte after them and returns the length of the run of
 * non-space bytes there, moving *s past it. Returns 0 (with *s == e) when
 * only white space is left. No byte at or past e is read. */
size_t api__token(const char **s, const char *e, const char **tok);

/* A cursor over the lines of a buffer; set p and end to the buffer and
 * line to the number of the line before the first one (0 at the start). */
typedef struct {
    const char *p, *end;   /* the rest of the buffer */
    long line;             /* the number of the line last returned */
} api__lines;

/* The next line [*s, *e) without its '\n' (a "\r\n" leaves its '\r',
 * which api__token skips as white space); counts it in c->line. A last
 * line without '\n' is returned as well. Returns 0 at the end of the
 * buffer (an empty buffer has no line, "\n" has one, empty). */
int api__line_next(api__lines *c, const char **s, const char **e);

/* The size of the buffer api__show and api__show_utf8 fill: 32 bytes of
 * token, "..." and the NUL. */
#define API__SHOWN 40

/* The n-byte token t made fit for a one-line error message, in out (also
 * returned): at most its first 32 bytes, followed by "..." when longer;
 * control bytes and bytes >= 0x7f as '?', so the message stays ASCII. */
const char *api__show(const char *t, size_t n, char out[API__SHOWN]);
/* The same, but bytes >= 0x80 are kept (only control bytes and 0x7f
 * become '?'), as the OBJ reader has always quoted its input (UTF-8 names
 * pass, though a cut after 32 bytes may split a character). */
const char *api__show_utf8(const char *t, size_t n, char out[API__SHOWN]);

/* --------------------------------------------------- little-endian bytes */

/* Stores v at p as 4 bytes, least significant first, whatever the host's
 * byte order. */
static inline void api__put_le32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16);
    p[3] = (unsigned char)(v >> 24);
}

/* The 4 bytes at p as a little-endian unsigned integer. */
static inline uint32_t api__get_le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16
           | (uint32_t)p[3] << 24;
}

/* Stores the IEEE 754 bit pattern of f at p, little-endian. */
static inline void api__put_f32(unsigned char *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    api__put_le32(p, v);
}

/* A cursor over a binary record (api_pack.c, api_gltf_plan.c). */
typedef struct {
    const unsigned char *p, *end;
} api__reader;

/* Copies n bytes out and moves on; 0 (nothing read) when fewer are left. */
static inline int api__take(api__reader *r, void *dst, size_t n)
{
    if ((size_t)(r->end - r->p) < n)
        return 0;
    memcpy(dst, r->p, n);
    r->p += n;
    return 1;
}

/* ---------------------------------------------------- codecs (api_codec.c) */

/* The checks every text or binary decoder makes first, with messages
 * prefixed by codec ("obj", ...): a NULL *lim is replaced by def filled
 * with api_limits_default; then EINVAL for a NULL buf with len > 0,
 * ELIMIT when len exceeds max_input_bytes, EDECODE for empty input.
 * Returns MCF_OK when decoding may start. */
mcf_status api__decode_begin(const char *codec, const void *buf, size_t len,
                             const api_limits **lim, api_limits *def,
                             mcf_error *err);

/* A decoder's last step: the core mesh from nv vertices X and nf
 * triangles F (copied; the caller still frees them). On success *out is
 * the new mesh (the caller's to free) and MCF_OK is returned; on failure
 * *out is unchanged and the status is core's (err filled by core), or
 * EMESH when core left none. */
mcf_status api__mesh_new(int nv, const double *X, int nf, const int32_t *F,
                         mcf_mesh **out, mcf_error *err);

/* A growable array of triangles (3 vertex indices each) for the readers
 * that cannot size it up front; start from {NULL, 0, 0}, free(F) at the
 * end. */
typedef struct {
    int32_t *F;
    long long n, cap;      /* triangles held, room for */
} api__tris;

/* Appends the triangle (a, b, c). A full array grows to `first`
 * triangles the first time, then doubles, never beyond max. Returns
 * MCF_OK; MCF_ELIMIT when it holds max triangles already; MCF_ENOMEM when
 * growing fails, with *want (may be NULL) the capacity it asked for. The
 * array is unchanged on failure and no message is written: the caller
 * names its line or element. */
mcf_status api__tris_add(api__tris *t, int32_t a, int32_t b, int32_t c,
                         long long max, long long first, long long *want);
/* The triangles a mesh of nv vertices and nf faces (as declared, or
 * counted: OBJ's `f` lines) may fan its polygons into: the admission
 * charges the faces declared and, per vertex, up to 2 faces a vertex
 * (api_estimate_job_bytes), the triangles of a closed surface fanned
 * without new vertices (2V - 4 + 4 x genus: Euler); an eighth and 1024
 * above for the genus and small meshes. A reader refuses (ELIMIT) the
 * polygon that would pass it, before building it: one polygon of 10M
 * corners in a 9 MB PLY peaked at 474 MiB before the job's 422 (issue
 * 28). */
long long api__fan_max(long long nv, long long nf);

/* An encoder's last step. rc is the status of its appends to out since
 * out->len was len0: MCF_OK is returned as is; otherwise out is cut back
 * to len0 (what the encoder appended is dropped, earlier content kept)
 * and err says "<codec>: out of memory writing <n> <what>" for ENOMEM or
 * "<codec>: output exceeds its maximum of <max> bytes", and rc is
 * returned. */
mcf_status api__encode_end(api_buf *out, size_t len0, mcf_status rc,
                           const char *codec, int n, const char *what,
                           mcf_error *err);

/* --------------------------------------------------- attributes (api_attrs.c) */

/* One attribute of an api_attrs (api.h): nvalues values of ncomp doubles,
 * and the value index of each of the 3*nf face corners; corners NULL:
 * absent. bits: the Draco input's quantization bits (0 raw, -1 not from
 * Draco); when qrange > 0 (a quantized Draco input), qorigin/qrange are
 * its quantization grid, which the Draco encoder reuses so texture
 * coordinates come back on the very same values. */
typedef struct {
    int ncomp, nvalues;
    double *values;
    int32_t *corners;
    int bits;
    float qorigin[4], qrange;
} api__attr;

typedef struct {
    int32_t at;
    char *text;             /* the statement's line, NUL-terminated */
} api__stmt;

/* A per-vertex scalar the attributes do not model, passed through as it
 * came (a PLY vertex property: quality, confidence, intensity, ...):
 * its name, its PLY type (api_ply_internal.h's ptype) and nv values. */
typedef struct {
    char *name;
    int type;
    double *values;
} api__scalar;
#define API__SCALARS_MAX 16     /* more are named in not_kept */

struct api_attrs {
    int nv, nf;
    int float32;            /* positions were single precision */
    int pos_bits;           /* Draco position bits (0 raw, -1 not Draco) */
    api__attr a[API_ATTR_KINDS];
    /* A glTF input's plan record (api__gltf_plan): the document and where
     * each welded vertex came from, which the glTF encoder rewrites. */
    unsigned char *gltf;
    size_t gltf_len;
    /* The input's polygons (OBJ, PLY, OFF): polygon p has poly[p] >= 3
     * corners and became the next poly[p] - 2 faces of the mesh, a fan
     * (c0, ck, ck+1); NULL when every face was a triangle. */
    int32_t *poly;
    int npoly, maxpoly;
    /* OBJ's g, o, s, usemtl and mtllib statements, in order, each written
     * back before polygon stmt[i].at (npoly: after the last). */
    api__stmt *stmt;
    int nstmt;
    /* PLY vertex scalars passed through (the PLY encoder writes them back;
     * other formats cannot), and what the input had that no output keeps
     * ("vertex flags (a list), element edge"; NULL: nothing). */
    api__scalar *scal;
    int nscal;
    char *not_kept;
    int nnot_kept;
};

/* Takes ownership of values and corners (malloc'ed, corners not NULL;
 * both freed on failure too) as attribute k, after api_attrs_set's
 * checks. */
mcf_status api__attrs_take(api_attrs *a, api_attr_kind k, int ncomp,
                           int nvalues, double *values, int32_t *corners,
                           mcf_error *err);

/* Takes ownership of values (malloc'ed, nv of them; freed on failure
 * too) as the pass-through scalar `name` (n bytes) of PLY type `type`.
 * ENOMEM. */
mcf_status api__attrs_scalar(api_attrs *a, const char *name, size_t n, int type,
                             double *values, mcf_error *err);
/* Appends "what" (n bytes) to the list of what no output keeps. ENOMEM. */
mcf_status api__attrs_drop(api_attrs *a, const char *what, size_t n, mcf_error *err);

/* The input's polygon sizes (npoly of them, each >= 3, their triangles
 * summing to the handle's face count; copied, and kept only when one has
 * more than 3 corners). EINVAL, ENOMEM. */
mcf_status api__attrs_polys(api_attrs *a, const int32_t *sizes, int npoly,
                            mcf_error *err);
/* Appends an OBJ statement line (n bytes at s) before polygon at. ENOMEM. */
mcf_status api__attrs_stmt(api_attrs *a, int32_t at, const char *s, size_t n,
                           mcf_error *err);

/* Walks the polygons a mesh of nf triangles came from (a NULL handle or
 * one without polygons: each triangle its own): start with it zeroed; each
 * call gives the next polygon's corner count *n and its corners as
 * indices c[] (3 x face + slot) into the face and attribute corner
 * arrays (room for api__attrs_maxpoly(a)), and returns 0 after the last. */
typedef struct {
    int p, face;
} api__poly_it;
int api__poly_next(const api_attrs *a, int nf, api__poly_it *it, size_t *c, int *n);
int api__attrs_maxpoly(const api_attrs *a);

/* EINVAL (named, prefixed by codec) unless a is NULL or was made for a
 * mesh with m's vertex and face counts. */
mcf_status api__attrs_check(const api_attrs *a, const mcf_mesh *m,
                            const char *codec, mcf_error *err);

/* The normals of m's surface for the normal attribute's values: each value
 * gets the sum of the area-weighted normals of the faces whose corners
 * use it, normalized ((0, 0, 1) where that sum vanishes). *N: 3*nvalues,
 * malloc'ed, the caller's. ENOMEM only. */
mcf_status api__attrs_normals(const api_attrs *a, const mcf_mesh *m,
                              double **N, mcf_error *err);

/* Stores each distinct value of at once (bitwise-equal doubles; the
 * table comes out sorted) and renumbers its ncorners corner indices.
 * ENOMEM only (at unchanged then). */
mcf_status api__attr_dedupe(api__attr *at, size_t ncorners, mcf_error *err);

/* Per-vertex normals of m (area-weighted, (0, 0, 1) where they vanish)
 * into N (3*nv). */
void api__vertex_normals(const mcf_mesh *m, double *N);

/* When every vertex of m has one value of attribute at at all its corners
 * (vertex attributes, or corner attributes without seams), fills out
 * (nv * ncomp, unreferenced vertices 0) and returns 1; else (or out of
 * memory) 0, out then partly filled. */
int api__attr_per_vertex(const api__attr *at, const mcf_mesh *m, double *out);

/* ------------------------------------------------ Draco header (api_draco.cc) */

/* The vertex and face counts a Draco stream's header declares (the ones
 * check_counts bounds), without decoding it: 1 when both were read, else
 * 0. For the memory estimate (api_estimate.c). */
int api__draco_declared(const void *buf, size_t len, uint32_t *nv,
                        uint32_t *nf);

/* ------------------------------------- Draco primitives (api_draco.cc) */

/* A Draco mesh as it came, for glTF's KHR_draco_mesh_compression (every
 * attribute kept, not only the first normal, texcoord and colour that
 * api_draco_decode_attrs keeps): points, triangles of point indices, and
 * per attribute its Draco unique id (what the glTF extension's attribute
 * map names), type, data type and each point's value as the raw bytes of
 * that data type (vsize = ncomp x the type's size). bits: the stream's
 * quantization of the attribute (0 raw; octahedron bits for a normal);
 * qrange > 0: the grid of a quantized one (origin qorigin), which the
 * encoder reuses so an attribute nobody changed comes back exactly. */
typedef struct {
    int id, type, dtype, ncomp, normalized, bits;
    int vsize;
    float qorigin[4], qrange;
    unsigned char *data;            /* npoints x vsize */
} api__draco_attr;

typedef struct {
    int npoints, nfaces, nattr;
    int32_t *faces;                 /* 3 x nfaces point indices */
    api__draco_attr *attr;
} api__draco_prim;

/* Draco's type numbers the glTF code needs (draco::GeometryAttribute and
 * draco::DataType). */
#define API__DRACO_POSITION 0
#define API__DRACO_NORMAL 1
#define API__DRACO_FLOAT32 9

/* Decodes a Draco mesh stream into *out (zeroed first; free with
 * api__draco_prim_free, also after a failure). The header's counts are
 * bounded by lim as api_draco_decode bounds them. EDECODE (a point
 * cloud, an unreadable attribute), ELIMIT, ENOMEM. */
mcf_status api__draco_prim_decode(const void *buf, size_t len,
                                  const api_limits *lim, api__draco_prim *out,
                                  mcf_error *err);
/* Encodes p (ids kept, each attribute quantized as its bits and grid say,
 * compression level 0..10, edgebreaker) and appends the stream to out. */
mcf_status api__draco_prim_encode(const api__draco_prim *p, int level,
                                  api_buf *out, mcf_error *err);
void api__draco_prim_free(api__draco_prim *p);

/* ------- glTF (api_gltf_check.c, api_gltf.cc, api_gltf_decode.c, api_gltf_plan.c,
 * api_gltf_encode.c) */

/* Where a primitive's POSITION or NORMAL values lie in a buffer (a dense
 * float VEC3 accessor): buf -1 when they have no buffer view (a Draco
 * primitive's accessors). */
typedef struct {
    int acc, buf, stride;       /* accessor index (-1: none) */
    long long off;              /* first value's byte in the buffer */
} api__gltf_at;

/* One triangle primitive (mode 4, 5 or 6) of a glTF document. The bridge
 * (api__gltf_parse) fills the read part; the decoder's weld (api_gltf_decode.c)
 * the plan part, which is all the encoder needs besides the document. */
typedef struct {
    int mesh, index, mode;      /* meshes[mesh].primitives[index] */
    int nvert;                  /* its vertices (accessor count, Draco points) */
    api__gltf_at pos, nrm;
    int draco_view;             /* KHR_draco_mesh_compression's view, else -1 */
    int draco_pos, draco_nrm;   /* slots in draco.attr (-1: none) */
    api__draco_prim draco;      /* the decoded stream (Draco primitives) */
    /* read (the bridge): */
    int ntri;
    int32_t *tri;               /* 3 ntri vertex indices (strips, fans unrolled) */
    double *xyz, *nxyz, *uv, *rgba; /* nvert x 3, 3, 2, 4 (NULL: absent) */
    /* plan (the weld): */
    int32_t *vmap;              /* vertex -> mesh vertex (-1: in no triangle) */
    int32_t *ngroup;            /* vertex -> normal value (-1: none), or NULL */
} api__gltf_prim;

/* A glTF document: its container (GLB or .gltf), the JSON text as it came,
 * every buffer's bytes (GLB's BIN chunk, data: URIs decoded), and its
 * triangle primitives. */
typedef struct {
    api_format container;
    char *json;
    size_t json_len;
    int nbuf;
    unsigned char **buf;
    size_t *buf_len;
    int nprim;
    api__gltf_prim *prim;
} api__gltf_doc;

/* The limits of a glTF document's structure, beyond api_limits. */
#define API_GLTF_MAX_DEPTH 64            /* JSON nesting */
#define API_GLTF_MAX_VALUES 1000000      /* JSON values (objects, numbers, ...) */
#define API_GLTF_MAX_PRIMS 65536         /* triangle primitives */

/* The largest plan record a decode within lim writes: the document (at
 * most the input), the weld (8 bytes per vertex) and Draco primitives'
 * decoded attributes (generously 256 bytes per vertex); ELIMIT beyond. */
#define API_GLTF_RECORD_MAX(lim) \
    (2 * (lim)->max_input_bytes + 264 * (size_t)(lim)->max_vertices + 4096)

/* For the memory estimate: the vertices (POSITION counts) and triangles a
 * glTF's triangle primitives declare, and whether one is Draco; 0 when
 * the JSON cannot be read. */
int api__gltf_declared(const void *buf, size_t len, long long *nv, long long *nf,
                       int *draco);

/* The JSON and BIN chunks of a GLB (strictly: header length = input
 * length, chunks 4-aligned and inside it); the bin span is NULL/0 without
 * a BIN chunk. EDECODE naming what is wrong. */
mcf_status api__glb_split(const void *buf, size_t len, const char **json,
                          size_t *json_len, const unsigned char **bin,
                          size_t *bin_len, mcf_error *err);

/* Every check before tinygltf (api_gltf_check.c) on the input (in,
 * in_len) whose JSON text is (json, n); *tiny (NULL: the input as it is)
 * the input tinygltf reads instead, malloc'ed, *tiny_len bytes: the JSON,
 * or for a GLB the same GLB with that JSON. EDECODE, ELIMIT, ENOMEM. */
mcf_status api__gltf_check_json(const void *in, size_t in_len, const char *json,
                                size_t n, int glb, char **tiny, size_t *tiny_len,
                                mcf_error *err);

/* Parses a glTF or GLB (container set by the caller's detection) whose
 * JSON passed api_gltf_decode.c's checks with tinygltf (no file is ever
 * opened: built without file system access), checks every accessor it
 * reads and fills doc's document (json: the input's JSON text, kept as
 * it came) and each triangle primitive's read part, Draco primitives
 * decoded. EDECODE, ELIMIT, ENOMEM; free doc either way. */
mcf_status api__gltf_parse(const void *buf, size_t len, const char *json,
                           size_t json_len, const api_limits *lim,
                           api__gltf_doc *doc, mcf_error *err);
/* Frees what doc holds (api_gltf_plan.c); doc is left empty. */
void api__gltf_doc_free(api__gltf_doc *doc);

/* The plan record the decoder leaves in api_attrs (api__gltf_plan) and
 * what reads it for the encoder (api_gltf_plan.c). */
mcf_status api__gltf_plan(const api__gltf_doc *doc, api_buf *out,
                          mcf_error *err);
mcf_status api__gltf_unplan(const void *buf, size_t len, api__gltf_doc *doc,
                            mcf_error *err);

/* The glTF writers' helpers (api_gltf_write.c), shared by the rewrite
 * (api_gltf_encode.c) and the new document (api_gltf_fresh.c). items:
 * the items of array member k of o (NULL when none: *n = 0; NULL too out
 * of memory), to free. set_item sets member k of o to x
 * (every earlier k removed; x deleted on failure), set_num a number,
 * set_vec3 a VEC3 as exact decimals (min, max); 0 on failure. bounds: min
 * and max over n VEC3 floats at p, stride apart. serialize: root and the
 * nbuf buffers in container fmt (GLB: buffer 0 as its BIN chunk; .gltf:
 * data: URIs, a buffer not dirty that was a URI keeps its text) to out. */
cJSON **api__gltf_items(const cJSON *o, const char *k, int *n);
int api__gltf_set_item(cJSON *o, const char *k, cJSON *x);
int api__gltf_set_num(cJSON *o, const char *k, double v);
int api__gltf_set_vec3(cJSON *o, const char *k, const double v[3]);
void api__gltf_bounds(const unsigned char *p, int n, size_t stride, double lo[3],
                      double hi[3]);
mcf_status api__gltf_serialize(cJSON *root, unsigned char *const *buf,
                               const size_t *blen, const int *dirty, int nbuf,
                               api_format fmt, api_buf *out, mcf_error *err);
/* A new document for a mesh from any format but glTF (api_gltf_fresh.c). */
mcf_status api__gltf_fresh(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                           mcf_error *err);

#endif /* API_INTERNAL_H */
