/* SPDX-License-Identifier: MIT */
/*
 * api_pack.c - a decoded mesh and its attributes as one exact binary
 * record, and back: what the daemon's decode sandbox (server/sandbox/sandbox.c)
 * sends from its child process to the worker over a pipe.
 *
 * The record holds everything a decoder hands on to the rest of a job:
 * positions (doubles, bit for bit), triangles, and the api_attrs side
 * channel (values, corner indices, the input's precision and its Draco
 * quantization grid), so a job that decoded in a child process encodes
 * exactly as one that decoded in the worker. Layout, in the host's byte
 * order (parent and child are the same executable on the same machine):
 *
 *   "MCFPACK1"                          8 bytes
 *   int32 nv, nf, float32, pos_bits
 *   double X[3 nv]; int32 F[3 nf]
 *   per attribute kind (normal, texcoord, colour):
 *     int32 present; when 1: int32 ncomp, nvalues, bits;
 *     float qorigin[4], qrange; double values[ncomp nvalues];
 *     int32 corners[3 nf]
 *   uint64 bytes of a glTF input's document record (api__gltf_plan), the
 *   record
 *
 * An OBJ's, PLY's or OFF's polygons and OBJ statements are not in it: those
 * formats never decode in the sandbox.
 *
 * Unpacking trusts nothing: every count is checked against the bytes left
 * and the limits, the mesh goes through core's checks and every attribute
 * through api_attrs_set's (indices in range, finite values), so a child
 * that misbehaved yields EDECODE, never a bad mesh. One pass, no tuning.
 */
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

static const char MAGIC[8] = {'M', 'C', 'F', 'P', 'A', 'C', 'K', '1'};

static mcf_status put_i32(api_buf *out, int32_t v)
{
    return api_buf_append(out, &v, sizeof v);
}

mcf_status api_mesh_pack(const mcf_mesh *m, const api_attrs *attrs,
                         api_buf *out, mcf_error *err)
{
    int nv = mcf_mesh_nvertices(m), nf = mcf_mesh_nfaces(m), k;
    mcf_status rc;

    if ((rc = api_buf_append(out, MAGIC, sizeof MAGIC)) != MCF_OK ||
        (rc = put_i32(out, nv)) != MCF_OK || (rc = put_i32(out, nf)) != MCF_OK ||
        (rc = put_i32(out, api_attrs_float32(attrs))) != MCF_OK ||
        (rc = put_i32(out, attrs ? attrs->pos_bits : -1)) != MCF_OK ||
        (rc = api_buf_append(out, mcf_mesh_positions(m),
                             3 * sizeof(double) * (size_t)nv)) != MCF_OK ||
        (rc = api_buf_append(out, mcf_mesh_faces(m),
                             3 * sizeof(int32_t) * (size_t)nf)) != MCF_OK)
        goto fail;
    for (k = 0; k < API_ATTR_KINDS; k++) {
        const api__attr *at = attrs ? &attrs->a[k] : NULL;
        int present = at && at->corners;
        if ((rc = put_i32(out, present)) != MCF_OK)
            goto fail;
        if (!present)
            continue;
        if ((rc = put_i32(out, at->ncomp)) != MCF_OK ||
            (rc = put_i32(out, at->nvalues)) != MCF_OK ||
            (rc = put_i32(out, at->bits)) != MCF_OK ||
            (rc = api_buf_append(out, at->qorigin, sizeof at->qorigin)) != MCF_OK ||
            (rc = api_buf_append(out, &at->qrange, sizeof at->qrange)) != MCF_OK ||
            (rc = api_buf_append(out, at->values, sizeof(double) *
                                 (size_t)at->ncomp * (size_t)at->nvalues)) != MCF_OK ||
            (rc = api_buf_append(out, at->corners,
                                 3 * sizeof(int32_t) * (size_t)nf)) != MCF_OK)
            goto fail;
    }
    {
        uint64_t gl = attrs && attrs->gltf ? attrs->gltf_len : 0;
        if ((rc = api_buf_append(out, &gl, sizeof gl)) != MCF_OK ||
            (rc = api_buf_append(out, attrs && attrs->gltf ? attrs->gltf : NULL,
                                 (size_t)gl)) != MCF_OK)
            goto fail;
    }
    return MCF_OK;
fail:
    return api__fail(err, rc, "pack: %d vertices, %d faces: %s", nv, nf,
                     mcf_strerror(rc));
}

/* A malloc'ed copy of count items of size bytes, or NULL (short input,
 * overflow or no memory; *short_input says which). */
static void *take_array(api__reader *r, size_t count, size_t size, int *short_input)
{
    void *a;
    *short_input = 0;
    if (count != 0 && (size_t)(r->end - r->p) / count < size) {
        *short_input = 1;
        return NULL;
    }
    a = malloc(count != 0 ? count * size : 1);
    if (a) {
        memcpy(a, r->p, count * size);
        r->p += count * size;
    }
    return a;
}

/* Attribute kind k's record, when present, into a (nf faces). */
static mcf_status unpack_attr(api__reader *r, api_attrs *a, int k, int32_t nf, mcf_error *err)
{
    int32_t present, ncomp, nvalues, bits;
    float qo[4], qr;
    double *v;
    int32_t *c;
    mcf_status rc;
    int shrt;

    if (!api__take(r, &present, 4))
        return api__fail(err, MCF_EDECODE, "unpack: truncated attributes");
    if (!present)
        return MCF_OK;
    if (!api__take(r, &ncomp, 4) || !api__take(r, &nvalues, 4) ||
        !api__take(r, &bits, 4) || !api__take(r, qo, sizeof qo) ||
        !api__take(r, &qr, sizeof qr) || ncomp < 2 || ncomp > 4 ||
        nvalues < 0 || nvalues > 3 * nf)
        return api__fail(err, MCF_EDECODE, "unpack: bad attribute %d", k);
    v = take_array(r, (size_t)ncomp * (size_t)nvalues, sizeof *v, &shrt);
    c = v ? take_array(r, 3 * (size_t)nf, sizeof *c, &shrt) : NULL;
    if (!c) {
        free(v);
        return shrt ? api__fail(err, MCF_EDECODE, "unpack: truncated attributes")
                    : api__fail(err, MCF_ENOMEM, "unpack: out of memory");
    }
    if ((rc = api__attrs_take(a, (api_attr_kind)k, ncomp, nvalues, v, c, err)) != MCF_OK)
        return rc;
    a->a[k].bits = bits;
    memcpy(a->a[k].qorigin, qo, sizeof qo);
    a->a[k].qrange = qr;
    return MCF_OK;
}

/* The glTF plan record (its length, then its bytes) into a. */
static mcf_status unpack_gltf(api__reader *r, api_attrs *a, const api_limits *lim,
                              mcf_error *err)
{
    uint64_t gl = 0;
    int shrt;

    if (!api__take(r, &gl, sizeof gl) || gl > api_mesh_pack_max(lim))
        return api__fail(err, MCF_EDECODE, "unpack: bad glTF record");
    if (gl && !(a->gltf = take_array(r, (size_t)gl, 1, &shrt)))
        return shrt ? api__fail(err, MCF_EDECODE, "unpack: truncated glTF record")
                    : api__fail(err, MCF_ENOMEM, "unpack: out of memory");
    a->gltf_len = (size_t)gl;
    return MCF_OK;
}

mcf_status api_mesh_unpack(const void *buf, size_t len, const api_limits *lim,
                           mcf_mesh **out, api_attrs **attrs, mcf_error *err)
{
    api__reader r = {buf, (const unsigned char *)buf + len};
    char magic[8];
    int32_t nv, nf, f32, pbits;
    double *X = NULL;
    int32_t *F = NULL;
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    mcf_status rc = MCF_EDECODE;
    int k, shrt;

    if (!api__take(&r, magic, sizeof magic) || memcmp(magic, MAGIC, sizeof magic) ||
        !api__take(&r, &nv, 4) || !api__take(&r, &nf, 4) || !api__take(&r, &f32, 4) ||
        !api__take(&r, &pbits, 4))
        return api__fail(err, MCF_EDECODE, "unpack: no mesh record");
    if (nv <= 0 || nf <= 0 || nv > lim->max_vertices || nf > lim->max_faces)
        return api__fail(err, MCF_EDECODE, "unpack: %ld vertices, %ld faces",
                         (long)nv, (long)nf);
    X = take_array(&r, 3 * (size_t)nv, sizeof *X, &shrt);
    F = X ? take_array(&r, 3 * (size_t)nf, sizeof *F, &shrt) : NULL;
    if (!F) {
        rc = shrt ? api__fail(err, MCF_EDECODE, "unpack: truncated mesh")
                  : api__fail(err, MCF_ENOMEM, "unpack: out of memory");
        goto fail;
    }
    if ((rc = api__mesh_new(nv, X, nf, F, &m, err)) != MCF_OK)
        goto fail;
    if (!(a = api_attrs_new(nv, nf))) {
        rc = api__fail(err, MCF_ENOMEM, "unpack: out of memory");
        goto fail;
    }
    a->float32 = f32 != 0;
    a->pos_bits = pbits;
    for (k = 0; k < API_ATTR_KINDS; k++)
        if ((rc = unpack_attr(&r, a, k, nf, err)) != MCF_OK)
            goto fail;
    if ((rc = unpack_gltf(&r, a, lim, err)) != MCF_OK)
        goto fail;
    if (r.p != r.end) {
        rc = api__fail(err, MCF_EDECODE, "unpack: %zu bytes after the record",
                       (size_t)(r.end - r.p));
        goto fail;
    }
    free(X);
    free(F);
    *out = m;
    if (attrs)
        *attrs = a;
    else
        api_attrs_free(a);
    return MCF_OK;
fail:
    free(X);
    free(F);
    mcf_mesh_free(m);
    api_attrs_free(a);
    return rc;
}

size_t api_mesh_pack_max(const api_limits *lim)
{
    size_t nv = (size_t)lim->max_vertices, nf = (size_t)lim->max_faces;
    /* the mesh, every attribute at its largest (a value per corner, 4
     * components), and a glTF record (API_GLTF_RECORD_MAX) */
    return 64 + 24 * nv + 12 * nf + 3 * (48 + 3 * nf * 4 * sizeof(double) + 12 * nf) +
           API_GLTF_RECORD_MAX(lim);
}
