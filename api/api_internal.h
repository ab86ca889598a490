/*
 * api_internal.h - helpers shared by the files of the api layer, not
 * public (the server and the CLI use api.h only).
 *
 * Internal non-static functions carry the api__ prefix, as core's carry
 * mcf__. Most of them serve the mesh codecs (api_obj.c, api_off.c,
 * api_ply.c, api_stl.c): the text helpers (tokens, lines, numbers, tokens
 * quoted in error messages) live in api_text.c, the decode prologue and
 * encode epilogue in api_mesh.c, and the byte-level ones below are inline
 * because the binary readers call them for every value. This header is
 * also included (as C) by api_draco.cc, so what is inline here is valid
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

/* ----------------------------------------------------- codecs (api_mesh.c) */

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

struct api_attrs {
    int nv, nf;
    int float32;            /* positions were single precision */
    int pos_bits;           /* Draco position bits (0 raw, -1 not Draco) */
    api__attr a[API_ATTR_KINDS];
};

/* Takes ownership of values and corners (malloc'ed, corners not NULL;
 * both freed on failure too) as attribute k, after api_attrs_set's
 * checks. */
mcf_status api__attrs_take(api_attrs *a, api_attr_kind k, int ncomp,
                           int nvalues, double *values, int32_t *corners,
                           mcf_error *err);

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

#endif /* API_INTERNAL_H */
