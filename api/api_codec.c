/* SPDX-License-Identifier: MIT */
/*
 * api_codec.c - what every mesh codec shares (api_internal.h): the
 * decoders' argument and size checks, the core mesh at the end of a
 * decode, the triangle list a fan grows, the encoders' roll-back on
 * failure, and the encoder options' defaults. A leaf below the codecs
 * (api_obj.c, api_off.c, api_ply*.c, api_stl.c, api_gltf*.c,
 * api_draco*.cc): they call it, and api_mesh.c calls them.
 */
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

void api_encode_opts_init(api_encode_opts *o)
{
    memset(o, 0, sizeof *o);
    o->format = API_FMT_UNKNOWN;
    o->quantization_bits = -1; /* auto: the input's, else 16 bits */
    o->compression_level = 7;
    o->preserve_order = 0;
    o->ply_binary = 1;
    o->ply_curvature = 0;
    o->ply_mean_curvature = NULL;
    o->ply_gaussian_curvature = NULL;
    o->stl_binary = 1;
    o->attrs = NULL;
}

mcf_status api__decode_begin(const char *codec, const void *buf, size_t len,
                             const api_limits **lim, api_limits *def,
                             mcf_error *err)
{
    if (!*lim) {
        api_limits_default(def);
        *lim = def;
    }
    if (!buf && len)
        return api__fail(err, MCF_EINVAL, "%s: NULL buffer", codec);
    if (len > (*lim)->max_input_bytes)
        return api__fail(err, MCF_ELIMIT,
                         "%s: input of %zu bytes exceeds max_input_bytes (%zu)",
                         codec, len, (*lim)->max_input_bytes);
    if (len == 0)
        return api__fail(err, MCF_EDECODE, "%s: empty input", codec);
    return MCF_OK;
}

mcf_status api__mesh_new(int nv, const double *X, int nf, const int32_t *F,
                         mcf_mesh **out, mcf_error *err)
{
    mcf_mesh *m = mcf_mesh_new(nv, X, nf, F, err);
    if (!m)
        return (err && err->status != MCF_OK) ? err->status : MCF_EMESH;
    *out = m;
    return MCF_OK;
}

long long api__fan_max(long long nv, long long nf)
{
    long long base = nf > 2 * nv ? nf : 2 * nv;
    return base + base / 8 + 1024;
}

mcf_status api__tris_add(api__tris *t, int32_t a, int32_t b, int32_t c,
                         long long max, long long first, long long *want)
{
    if (t->n >= max)
        return MCF_ELIMIT;
    if (t->n == t->cap) {
        long long ncap = t->cap ? 2 * t->cap : first;
        int32_t *p;
        if (ncap > max)
            ncap = max;
        if (want)
            *want = ncap;
        p = realloc(t->F, 3 * sizeof *p * (size_t)ncap);
        if (!p)
            return MCF_ENOMEM;
        t->F = p;
        t->cap = ncap;
    }
    t->F[3 * t->n] = a;
    t->F[3 * t->n + 1] = b;
    t->F[3 * t->n + 2] = c;
    t->n++;
    return MCF_OK;
}

mcf_status api__encode_end(api_buf *out, size_t len0, mcf_status rc,
                           const char *codec, int n, const char *what,
                           mcf_error *err)
{
    if (rc == MCF_OK)
        return MCF_OK;
    out->len = len0;
    if (out->data)
        out->data[len0] = '\0';
    if (rc == MCF_ENOMEM)
        return api__fail(err, rc, "%s: out of memory writing %d %s", codec, n,
                         what);
    return api__fail(err, rc, "%s: output exceeds its maximum of %zu bytes",
                     codec, out->max);
}
