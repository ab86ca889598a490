/* SPDX-License-Identifier: MIT */
/*
 * api_mesh.c - format detection and naming, and the decode/encode
 * dispatchers over the per-format codecs.
 *
 * Detection looks at the bytes only, in an order where no rule can steal
 * another format's file: Draco's "DRACO" magic, "ply" + newline, the
 * binary STL size rule (84 + 50 n bytes: a binary STL may begin with
 * "solid" in its free-form header, so this comes before the ASCII rule),
 * an OFF keyword (after blank and '#' comment lines, as the OFF reader
 * allows), "solid" followed by "facet"/"endsolid", then text whose first
 * statement (after blank and comment lines too) is an OBJ keyword. The
 * OFF and OBJ keyword sets are disjoint, so the comment skipping of the
 * one rule cannot take the other's files.
 *
 * The steps every codec shares, and the encoder options' defaults, are
 * api_codec.c's: the codecs call them and this file calls the codecs.
 */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "api_internal.h"

/* Index = api_format. */
static const struct {
    const char *name, *ext, *mime;
} formats[] = {
    {"unknown", "", "application/octet-stream"},
    {"obj", ".obj", "model/obj"},
    {"draco", ".drc", "model/x-draco"},
    {"ply", ".ply", "model/x-ply"},
    {"stl", ".stl", "model/stl"},
    {"off", ".off", "model/x-off"},
    {"glb", ".glb", "model/gltf-binary"},
    {"gltf", ".gltf", "model/gltf+json"},
};
#define NFORMATS (sizeof formats / sizeof formats[0])

/* How far the "solid" rule looks for "facet"/"endsolid", and the OFF rule
 * for its keyword past leading comment lines: real headers are short,
 * and a large input that is none of these is not scanned to its end. */
#define DETECT_WINDOW 65536

/* White space across lines. */
static int sp(int c)
{
    return api__is_space(c) || c == '\n';
}

/* Does the n bytes at p start with the word w, followed by white space
 * or the end of the buffer? */
static int starts_word(const char *p, size_t n, const char *w)
{
    size_t k = strlen(w);
    return n >= k && memcmp(p, w, k) == 0 && (n == k || sp((unsigned char)p[k]));
}

static int contains(const char *p, size_t n, const char *w)
{
    size_t k = strlen(w), i;
    if (n < k)
        return 0;
    for (i = 0; i + k <= n; i++)
        if (p[i] == w[0] && memcmp(p + i, w, k) == 0)
            return 1;
    return 0;
}

/* The offset of the first byte of p[i, n) that is neither white space
 * (newlines included) nor in a line whose first other byte is '#'; n when
 * there is none. *open is set when the input ends inside such a comment
 * line (no newline after it before n). */
static size_t skip_comment_lines(const char *p, size_t n, size_t i, int *open)
{
    *open = 0;
    while (i < n) {
        const char *nl;
        while (i < n && sp((unsigned char)p[i]))
            i++;
        if (i >= n || p[i] != '#')
            break;
        nl = memchr(p + i, '\n', n - i);
        if (!nl) {
            *open = 1;
            return n;
        }
        i = (size_t)(nl - p) + 1;
    }
    return i;
}

static int looks_off(const char *p, size_t n)
{
    /* OFF and its variants: [ST][C][N][4][n]OFF, e.g. COFF, NOFF, CNOFF. */
    static const char *const kw[] = {"OFF", "COFF", "NOFF", "CNOFF", "STOFF",
                                     "4OFF", "nOFF", NULL};
    int i;
    for (i = 0; kw[i]; i++)
        if (starts_word(p, n, kw[i]))
            return 1;
    return 0;
}

static int looks_obj(const char *p, size_t n)
{
    static const char *const kw[] = {"v", "vt", "vn", "vp", "f", "g", "o",
                                     "s", "l", "p", "usemtl", "mtllib", NULL};
    size_t i = 0;
    int open;
    if (n >= 3 && memcmp(p, "\xEF\xBB\xBF", 3) == 0) /* UTF-8 BOM */
        i = 3;
    /* Skip blank and comment lines, then look at the first statement. */
    i = skip_comment_lines(p, n, i, &open);
    if (open)
        return 1; /* only comments: let the OBJ reader say so */
    if (i >= n)
        return 0;
    for (int k = 0; kw[k]; k++)
        if (starts_word(p + i, n - i, kw[k]))
            return 1;
    return 0;
}

/* A JSON object whose window holds an "asset" member: a .gltf. */
static int looks_gltf(const char *p, size_t n)
{
    return n > 0 && p[0] == '{' &&
           contains(p, n < DETECT_WINDOW ? n : DETECT_WINDOW, "\"asset\"");
}

api_format api_format_detect(const void *buf, size_t len)
{
    const char *p = buf;
    size_t i = 0, j;
    int open;

    if (!p || len == 0)
        return API_FMT_UNKNOWN;
    if (len >= 5 && memcmp(p, "DRACO", 5) == 0)
        return API_FMT_DRACO;
    if (len >= 4 && memcmp(p, "glTF", 4) == 0)
        return API_FMT_GLB;
    if ((len >= 4 && memcmp(p, "ply\n", 4) == 0)
        || (len >= 5 && memcmp(p, "ply\r\n", 5) == 0))
        return API_FMT_PLY;
    if (len >= 84
        && 84 + 50 * (uint64_t)api__get_le32((const unsigned char *)p + 80)
               == (uint64_t)len)
        return API_FMT_STL;
    while (i < len && sp((unsigned char)p[i]))
        i++;
    /* The OFF keyword may follow comment lines, within the window. */
    j = skip_comment_lines(p, len - i > DETECT_WINDOW ? i + DETECT_WINDOW : len, i,
                           &open);
    if (!open && looks_off(p + j, len - j))
        return API_FMT_OFF;
    if (starts_word(p + i, len - i, "solid")) {
        size_t win = len - i < DETECT_WINDOW ? len - i : DETECT_WINDOW;
        if (contains(p + i, win, "facet") || contains(p + i, win, "endsolid"))
            return API_FMT_STL;
    }
    if (looks_obj(p, len))
        return API_FMT_OBJ;
    if (looks_gltf(p + i, len - i))
        return API_FMT_GLTF;
    return API_FMT_UNKNOWN;
}

api_format api_format_from_name(const char *name)
{
    const char *base, *dot, *ext;
    size_t i;

    if (!name || !*name)
        return API_FMT_UNKNOWN;
    base = strrchr(name, '/');
    base = base ? base + 1 : name;
    dot = strrchr(base, '.');
    ext = dot ? dot + 1 : base;
    if (strcasecmp(ext, "drc") == 0)
        return API_FMT_DRACO;
    for (i = 1; i < NFORMATS; i++)
        if (strcasecmp(ext, formats[i].name) == 0)
            return (api_format)i;
    return API_FMT_UNKNOWN;
}

const char *api_format_name(api_format f)
{
    return (unsigned)f < NFORMATS ? formats[f].name : formats[0].name;
}

const char *api_format_ext(api_format f)
{
    return (unsigned)f < NFORMATS ? formats[f].ext : formats[0].ext;
}

const char *api_format_mime(api_format f)
{
    return (unsigned)f < NFORMATS ? formats[f].mime : formats[0].mime;
}

mcf_status api_mesh_decode(const void *buf, size_t len, const api_limits *lim,
                           mcf_mesh **out, api_format *fmt, mcf_error *err)
{
    return api_mesh_decode_attrs(buf, len, lim, out, NULL, fmt, err);
}

/* An empty attribute handle for the format that carries none (STL);
 * a binary STL's positions are single precision. */
static mcf_status empty_attrs(mcf_mesh *m, int float32, api_attrs **attrs,
                              mcf_error *err)
{
    api_attrs *a = api_attrs_new(mcf_mesh_nvertices(m), mcf_mesh_nfaces(m));
    if (!a)
        return api__fail(err, MCF_ENOMEM, "attributes: out of memory");
    a->float32 = float32;
    *attrs = a;
    return MCF_OK;
}

mcf_status api_mesh_decode_attrs(const void *buf, size_t len,
                                 const api_limits *lim, mcf_mesh **out,
                                 api_attrs **attrs, api_format *fmt,
                                 mcf_error *err)
{
    api_limits def;
    api_format f;
    mcf_mesh *m = NULL;
    mcf_status rc;

    if (!lim) {
        api_limits_default(&def);
        lim = &def;
    }
    if (len > lim->max_input_bytes)
        return api__fail(err, MCF_ELIMIT,
                         "input of %zu bytes exceeds max_input_bytes (%zu)",
                         len, lim->max_input_bytes);
    if (!buf || len == 0)
        return api__fail(err, MCF_EDECODE, "empty input (0 bytes)");
    f = api_format_detect(buf, len);
    if (fmt)
        *fmt = f;
    switch (f) {
    case API_FMT_OBJ:
        return api_obj_decode_attrs(buf, len, lim, out, attrs, err);
    case API_FMT_DRACO:
        return api_draco_decode_attrs(buf, len, lim, out, attrs, err);
    case API_FMT_PLY:
        return api_ply_decode_attrs(buf, len, lim, out, attrs, err);
    case API_FMT_GLB:
    case API_FMT_GLTF:
        return api_gltf_decode_attrs(buf, len, lim, out, attrs, err);
    case API_FMT_OFF:
        return api_off_decode_attrs(buf, len, lim, out, attrs, err);
    case API_FMT_STL:
        rc = api_stl_decode(buf, len, lim, &m, err);
        if (rc == MCF_OK && attrs) {
            /* The size rule of api_format_detect: a binary STL (float32). */
            int bin = len >= 84
                      && 84 + 50 * (uint64_t)api__get_le32(
                                  (const unsigned char *)buf + 80)
                             == (uint64_t)len;
            rc = empty_attrs(m, bin, attrs, err);
        }
        if (rc != MCF_OK) {
            mcf_mesh_free(m);
            return rc;
        }
        *out = m;
        return MCF_OK;
    case API_FMT_UNKNOWN:
        break;
    }
    return api__fail(err, MCF_EFORMAT,
                     "unknown mesh format (accepted: obj, draco, ply, stl, off, glb, gltf)");
}

mcf_status api_mesh_encode(const mcf_mesh *m, const api_encode_opts *o,
                           api_buf *out, mcf_error *err)
{
    if (!m || !o || !out)
        return api__fail(err, MCF_EINVAL, "encode: NULL argument");
    switch (o->format) {
    case API_FMT_OBJ:
        return api_obj_encode_opts(m, o, out, err);
    case API_FMT_DRACO:
        return api_draco_encode(m, o, out, NULL, err);
    case API_FMT_PLY:
        return api_ply_encode(m, o, out, err);
    case API_FMT_STL:
        return api_stl_encode(m, o, out, err);
    case API_FMT_OFF:
        return api_off_encode_opts(m, o, out, err);
    case API_FMT_GLB:
    case API_FMT_GLTF:
        return api_gltf_encode(m, o, out, err);
    case API_FMT_UNKNOWN:
        break;
    }
    return api__fail(err, MCF_EINVAL, "encode: no output format given");
}
