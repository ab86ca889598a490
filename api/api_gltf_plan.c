/* SPDX-License-Identifier: MIT */
/*
 * api_gltf_plan.c - the decoded glTF document (api__gltf_doc): its free,
 * and the plan record, the document as bytes, from the decoder (possibly
 * in the decode sandbox's child process, through api_mesh_pack) to the
 * encoder (api_gltf_encode.c).
 *
 * Layout, host byte order: "MCFGLTF1", the container, the JSON text, the
 * buffers, and per triangle primitive its location in the document, where
 * its POSITION and NORMAL lie, vmap and ngroup, and a Draco primitive's
 * decoded stream. Reading it back trusts nothing: every count against the
 * bytes left, every place the encoder writes against its buffer, every
 * Draco attribute's size against its data type.
 */
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

static const char MAGIC[8] = {'M', 'C', 'F', 'G', 'L', 'T', 'F', '1'};

/* --------------------------------------------------------------- document */

void api__gltf_doc_free(api__gltf_doc *d)
{
    int i;
    for (i = 0; i < d->nbuf; i++)
        free(d->buf[i]);
    free(d->buf);
    free(d->buf_len);
    free(d->json);
    for (i = 0; i < d->nprim; i++) {
        api__gltf_prim *g = &d->prim[i];
        api__draco_prim_free(&g->draco);
        free(g->tri);
        free(g->xyz);
        free(g->nxyz);
        free(g->uv);
        free(g->rgba);
        free(g->vmap);
        free(g->ngroup);
    }
    free(d->prim);
    memset(d, 0, sizeof *d);
}

/* ------------------------------------------------------------ plan record */

static mcf_status put(api_buf *o, const void *p, size_t n)
{
    return api_buf_append(o, p, n);
}

static mcf_status put_i32(api_buf *o, int32_t v)
{
    return put(o, &v, sizeof v);
}

static mcf_status put_u64(api_buf *o, uint64_t v)
{
    return put(o, &v, sizeof v);
}

static mcf_status put_prim(api_buf *o, const api__gltf_prim *g)
{
    const int32_t head[] = {g->mesh, g->index, g->mode, g->nvert, g->pos.acc,
                            g->pos.buf, g->pos.stride, g->nrm.acc, g->nrm.buf,
                            g->nrm.stride, g->draco_view, g->draco_pos,
                            g->draco_nrm, g->ngroup != NULL};
    const int64_t off[] = {g->pos.off, g->nrm.off};
    const size_t nv = (size_t)g->nvert;
    mcf_status rc;
    int i;
    if ((rc = put(o, head, sizeof head)) != MCF_OK || (rc = put(o, off, sizeof off)) ||
        (rc = put(o, g->vmap, 4 * nv)) != MCF_OK ||
        (g->ngroup && (rc = put(o, g->ngroup, 4 * nv)) != MCF_OK))
        return rc;
    if (g->draco_view < 0)
        return MCF_OK;
    if ((rc = put_i32(o, g->draco.npoints)) != MCF_OK ||
        (rc = put_i32(o, g->draco.nfaces)) != MCF_OK ||
        (rc = put_i32(o, g->draco.nattr)) != MCF_OK ||
        (rc = put(o, g->draco.faces, 12 * (size_t)g->draco.nfaces)) != MCF_OK)
        return rc;
    for (i = 0; i < g->draco.nattr; i++) {
        const api__draco_attr *a = &g->draco.attr[i];
        const int32_t ah[] = {a->id, a->type, a->dtype, a->ncomp, a->normalized,
                              a->bits, a->vsize};
        if ((rc = put(o, ah, sizeof ah)) != MCF_OK ||
            (rc = put(o, a->qorigin, sizeof a->qorigin)) != MCF_OK ||
            (rc = put(o, &a->qrange, sizeof a->qrange)) != MCF_OK ||
            (rc = put(o, a->data, (size_t)a->vsize * (size_t)g->draco.npoints)) != MCF_OK)
            return rc;
    }
    return MCF_OK;
}

mcf_status api__gltf_plan(const api__gltf_doc *d, api_buf *out, mcf_error *err)
{
    mcf_status rc;
    int i;
    if ((rc = put(out, MAGIC, sizeof MAGIC)) != MCF_OK ||
        (rc = put_i32(out, d->container)) != MCF_OK ||
        (rc = put_u64(out, d->json_len)) != MCF_OK ||
        (rc = put(out, d->json, d->json_len)) != MCF_OK ||
        (rc = put_i32(out, d->nbuf)) != MCF_OK)
        goto fail;
    for (i = 0; i < d->nbuf; i++)
        if ((rc = put_u64(out, d->buf_len[i])) != MCF_OK ||
            (rc = put(out, d->buf[i], d->buf_len[i])) != MCF_OK)
            goto fail;
    if ((rc = put_i32(out, d->nprim)) != MCF_OK)
        goto fail;
    for (i = 0; i < d->nprim; i++)
        if ((rc = put_prim(out, &d->prim[i])) != MCF_OK)
            goto fail;
    return MCF_OK;
fail:
    return api__fail(err, rc, "gltf: out of memory for the document's record");
}

/* A malloc'ed copy of n bytes (extra spare bytes, zeroed), or NULL. */
static void *take_copy(api__reader *r, uint64_t n, size_t extra, int *oom)
{
    unsigned char *a;
    if ((uint64_t)(r->end - r->p) < n)
        return NULL;
    a = malloc((size_t)n + extra + 1);
    if (!a) {
        *oom = 1;
        return NULL;
    }
    memcpy(a, r->p, (size_t)n);
    memset(a + n, 0, extra + 1);
    r->p += n;
    return a;
}

/* Does a place of nvert VEC3 floats fit its buffer? */
static int fits(const api__gltf_doc *d, const api__gltf_at *at, int nvert)
{
    if (at->acc < 0 || at->buf < 0)
        return at->buf < 0;
    return at->buf < d->nbuf && at->stride >= 12 && at->stride <= 252 && at->off >= 0 &&
           nvert >= 1 &&
           (uint64_t)at->off + (uint64_t)at->stride * (uint64_t)(nvert - 1) + 12 <=
               d->buf_len[at->buf];
}

static int take_prim(api__reader *r, api__gltf_doc *d, api__gltf_prim *g, int *oom)
{
    int32_t h[14];
    int64_t off[2];
    int i;
    if (!api__take(r, h, sizeof h) || !api__take(r, off, sizeof off) || h[3] < 1)
        return 0;
    g->mesh = h[0];
    g->index = h[1];
    g->mode = h[2];
    g->nvert = h[3];
    g->pos = (api__gltf_at){h[4], h[5], h[6], off[0]};
    g->nrm = (api__gltf_at){h[7], h[8], h[9], off[1]};
    g->draco_view = h[10];
    g->draco_pos = h[11];
    g->draco_nrm = h[12];
    g->draco_nrm = g->draco_view >= 0 ? g->draco_nrm : -1;
    if (g->mesh < 0 || g->index < 0 || !fits(d, &g->pos, g->nvert) ||
        !fits(d, &g->nrm, g->nvert) || (g->draco_view < 0 && g->pos.buf < 0) ||
        !(g->vmap = take_copy(r, 4 * (uint64_t)g->nvert, 0, oom)) ||
        (h[13] && !(g->ngroup = take_copy(r, 4 * (uint64_t)g->nvert, 0, oom))))
        return 0;
    if (g->draco_view < 0)
        return 1;
    if (!api__take(r, &g->draco.npoints, 4) || !api__take(r, &g->draco.nfaces, 4) ||
        !api__take(r, &g->draco.nattr, 4) || g->draco.npoints != g->nvert ||
        g->draco.nfaces < 1 || g->draco.nattr < 1 || g->draco.nattr > 256 ||
        !(g->draco.faces = take_copy(r, 12 * (uint64_t)g->draco.nfaces, 0, oom)) ||
        !(g->draco.attr = calloc((size_t)g->draco.nattr, sizeof *g->draco.attr)))
        return *oom = *oom || (g->draco.faces && !g->draco.attr), 0;
    for (i = 0; i < g->draco.nattr; i++) {
        api__draco_attr *a = &g->draco.attr[i];
        int32_t ah[7];
        if (!api__take(r, ah, sizeof ah) || !api__take(r, a->qorigin, sizeof a->qorigin) ||
            !api__take(r, &a->qrange, sizeof a->qrange))
            return 0;
        a->id = ah[0];
        a->type = ah[1];
        a->dtype = ah[2];
        a->ncomp = ah[3];
        a->normalized = ah[4];
        a->bits = ah[5];
        a->vsize = ah[6];
        /* Draco's data types 1..10 are 1, 1, 2, 2, 4, 4, 8, 8, 4, 8 bytes */
        if (a->dtype < 1 || a->dtype > 10 || a->ncomp < 1 || a->ncomp > 4 ||
            a->vsize != a->ncomp * (a->dtype == 9 ? 4 : a->dtype == 10 ? 8
                                                 : 1 << ((a->dtype - 1) / 2)) ||
            !(a->data = take_copy(r, (uint64_t)a->vsize * (uint64_t)g->nvert, 0, oom)))
            return 0;
    }
    return g->draco_pos >= 0 && g->draco_pos < g->draco.nattr &&
           g->draco.attr[g->draco_pos].dtype == API__DRACO_FLOAT32 &&
           g->draco.attr[g->draco_pos].ncomp == 3 &&
           (g->draco_nrm < 0 || (g->draco_nrm < g->draco.nattr &&
                                 g->draco.attr[g->draco_nrm].dtype == API__DRACO_FLOAT32 &&
                                 g->draco.attr[g->draco_nrm].ncomp == 3));
}

mcf_status api__gltf_unplan(const void *buf, size_t len, api__gltf_doc *d,
                            mcf_error *err)
{
    api__reader r = {buf, (const unsigned char *)buf + len};
    char magic[8];
    int32_t c, n;
    uint64_t jl;
    int oom = 0, i;

    memset(d, 0, sizeof *d);
    if (!api__take(&r, magic, 8) || memcmp(magic, MAGIC, 8) != 0 || !api__take(&r, &c, 4) ||
        (c != API_FMT_GLB && c != API_FMT_GLTF) || !api__take(&r, &jl, 8) ||
        !(d->json = take_copy(&r, jl, 0, &oom)) || !api__take(&r, &n, 4) || n < 0 ||
        (size_t)n > len / 8)
        goto bad;
    d->container = (api_format)c;
    d->json_len = (size_t)jl;
    d->buf = calloc((size_t)n + 1, sizeof *d->buf);
    d->buf_len = calloc((size_t)n + 1, sizeof *d->buf_len);
    if (!d->buf || !d->buf_len)
        goto nomem;
    for (i = 0; i < n; i++, d->nbuf++)
        if (!api__take(&r, &jl, 8) || !(d->buf[i] = take_copy(&r, jl, 0, &oom)))
            goto bad;
        else
            d->buf_len[i] = (size_t)jl;
    if (!api__take(&r, &n, 4) || n < 1 || n > API_GLTF_MAX_PRIMS ||
        !(d->prim = calloc((size_t)n, sizeof *d->prim)))
        goto bad;
    for (i = 0; i < n; i++) {
        d->nprim++;
        if (!take_prim(&r, d, &d->prim[i], &oom))
            goto bad;
    }
    if (r.p == r.end)
        return MCF_OK;
bad:
    if (oom)
        goto nomem;
    api__gltf_doc_free(d);
    return api__fail(err, MCF_EDECODE, "gltf: the document's record is corrupt");
nomem:
    api__gltf_doc_free(d);
    return api__fail(err, MCF_ENOMEM, "gltf: out of memory reading the document's record");
}
