/* SPDX-License-Identifier: MIT */
/*
 * api_gltf_encode.c - glTF 2.0 encoding (api_gltf_encode): a glTF input's
 * document rewritten with the smoothed surface (a mesh from any other
 * format gets a new document: api_gltf_fresh.c); the JSON and container
 * helpers both use are api_gltf_write.c's.
 *
 * Rewriting changes only what the smoothing changed. Plain primitives:
 * POSITION and NORMAL values are overwritten in place in their buffers
 * (interleaved or not), so every other byte stays where it was; normals
 * are the recomputed ones (api__attrs_normals) of each (welded vertex,
 * input normal) group, vertices in no triangle keep theirs. Draco
 * primitives: the decoded stream's POSITION and NORMAL points are replaced
 * and the stream encoded again with every attribute id, type and
 * quantization it had (a texture grid kept, so UVs come back exactly),
 * at compression_level (quantization_bits > 0 sets the positions' bits,
 * 0 stores every attribute raw); the buffer that holds it is laid out
 * again (each view 4-aligned, keeping its offset mod 4) and the views'
 * offsets, the accessors' counts (what the new stream decodes to) follow.
 * Each touched POSITION accessor gets its min and max anew (required by
 * glTF), from the values written (Draco: as they decode). The JSON is
 * edited with cJSON, so members, extensions and extras nobody reads pass
 * through (a number is printed anew by cJSON, which may move it by a
 * double's last bit, far below the float32 precision of glTF's data). The
 * container is the output
 * format's: GLB (buffer 0 as its BIN chunk) or .gltf (every buffer a
 * base64 data: URI; one that was already a URI and did not change keeps
 * its text).
 *
 * The decoded document arrives as the plan record (api_gltf_plan.c).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* glTF's index component types */
#define GL_UINT 5125
#define GL_USHORT 5123

/* ----------------------------------------------------------- JSON helpers */

/* A non-negative integer member (-1: absent or not one). */
static long long int_of(const cJSON *o, const char *k)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, k);
    if (!cJSON_IsNumber(x) || x->valuedouble < 0 || x->valuedouble > 9e15 ||
        x->valuedouble != floor(x->valuedouble))
        return -1;
    return (long long)x->valuedouble;
}

/* ---------------------------------------------------------------- rewrite */

/* Rewrites Draco primitive g from the smoothed X and normals N, in new
 * (the stream); sets its accessors' counts and POSITION's bounds in the
 * JSON. */
static mcf_status redraco(api__gltf_prim *g, const double *X, const double *N,
                          const api_encode_opts *o, cJSON *prim, cJSON **acc,
                          int nacc, api_buf *stream, mcf_error *err)
{
    api__draco_attr *pa = &g->draco.attr[g->draco_pos];
    api__draco_attr *na = g->draco_nrm >= 0 ? &g->draco.attr[g->draco_nrm] : NULL;
    api__draco_prim back;
    const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes"), *c;
    double lo[3], hi[3];
    long long ix;
    mcf_status rc;
    int v, i, k;

    for (v = 0; v < g->nvert; v++)
        for (k = 0; k < 3; k++) {
            if (g->vmap[v] >= 0)
                api__put_f32(pa->data + 12 * (size_t)v + 4 * (size_t)k,
                             (float)X[3 * (size_t)g->vmap[v] + k]);
            if (na && N && g->ngroup && g->ngroup[v] >= 0)
                api__put_f32(na->data + 12 * (size_t)v + 4 * (size_t)k,
                             (float)N[3 * (size_t)g->ngroup[v] + k]);
        }
    for (i = 0; i < g->draco.nattr; i++) {
        if (o->quantization_bits == 0)
            g->draco.attr[i].bits = 0;
        else if (o->quantization_bits > 0 && i == g->draco_pos)
            g->draco.attr[i].bits = o->quantization_bits;
    }
    if ((rc = api__draco_prim_encode(&g->draco, o->compression_level, stream, err)) != MCF_OK)
        return rc;
    /* What the new stream decodes to: the accessors' counts and bounds. */
    if ((rc = api__draco_prim_decode(stream->data, stream->len, NULL, &back, err)) != MCF_OK) {
        api__draco_prim_free(&back);
        return api__fail(err, MCF_EMESH, "gltf: the re-encoded Draco stream of mesh %d "
                         "primitive %d does not decode", g->mesh, g->index);
    }
    for (i = 0; i < back.nattr; i++)
        if (back.attr[i].id == pa->id && back.attr[i].dtype == API__DRACO_FLOAT32 &&
            back.attr[i].ncomp == 3)
            break;
    if (i == back.nattr) {
        api__draco_prim_free(&back);
        return api__fail(err, MCF_EMESH, "gltf: the re-encoded stream lost POSITION");
    }
    api__gltf_bounds(back.attr[i].data, back.npoints, 12, lo, hi);
    cJSON_ArrayForEach(c, attrs)
        if (cJSON_IsNumber(c) && c->valuedouble >= 0 && c->valuedouble < nacc)
            api__gltf_set_num(acc[(int)c->valuedouble], "count", back.npoints);
    ix = int_of(prim, "indices");
    if (ix >= 0 && ix < nacc) {
        api__gltf_set_num(acc[ix], "count", 3.0 * back.nfaces);
        /* unsigned short indices where they fit (a type too narrow for
         * the new point count would be wrong; assimp 5.2 reads Draco's
         * unsigned int indices as none), unsigned int beyond */
        api__gltf_set_num(acc[ix], "componentType", back.npoints <= 65535 ? GL_USHORT : GL_UINT);
    }
    if (g->pos.acc >= 0 && g->pos.acc < nacc &&
        !(api__gltf_set_vec3(acc[g->pos.acc], "min", lo) && api__gltf_set_vec3(acc[g->pos.acc], "max", hi)))
        rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    api__draco_prim_free(&back);
    return rc;
}

/* Lays buffer b out again with view dv's bytes replaced by stream
 * (several such views: streams[i] for view sv[i]); views' offsets and
 * lengths in the JSON follow. */
static mcf_status relayout(api__gltf_doc *d, int b, cJSON **view, int nview,
                           const int *sv, api_buf *streams, int ns, mcf_error *err)
{
    size_t cap = d->buf_len[b] + 16 * (size_t)nview + 1, len = 0;
    unsigned char *nb;
    int v, i;
    for (i = 0; i < ns; i++)
        cap += streams[i].len;
    if (!(nb = calloc(cap, 1)))
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory laying out buffer %d", b);
    /* views in their order in the JSON (their offsets are only kept mod 4) */
    for (v = 0; v < nview; v++) {
        long long off = int_of(view[v], "byteOffset"), n = int_of(view[v], "byteLength");
        const unsigned char *src;
        if (int_of(view[v], "buffer") != b)
            continue;
        off = off < 0 ? 0 : off;
        src = d->buf[b] + off;
        for (i = 0; i < ns; i++)
            if (sv[i] == v) {
                src = (const unsigned char *)streams[i].data;
                n = (long long)streams[i].len;
            }
        if (n < 0 || (src == d->buf[b] + off && (size_t)(off + n) > d->buf_len[b])) {
            free(nb);
            return api__fail(err, MCF_EDECODE, "gltf: buffer view %d outside buffer %d", v, b);
        }
        len = (len + 3) / 4 * 4 + (size_t)(off % 4);
        memcpy(nb + len, src, (size_t)n);
        if (!api__gltf_set_num(view[v], "byteOffset", (double)len) ||
            !api__gltf_set_num(view[v], "byteLength", (double)n)) {
            free(nb);
            return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        }
        len += (size_t)n;
    }
    free(d->buf[b]);
    d->buf[b] = nb;
    d->buf_len[b] = len;
    return MCF_OK;
}

/* The JSON primitive of g, checked: its record names this mesh's
 * vertices (nv) and normal groups (nn), its POSITION accessor is one of
 * nacc. */
static mcf_status prim_of(const api__gltf_prim *g, int nv, int nn, cJSON **mesh, int nmesh,
                          int nacc, cJSON **prim, mcf_error *err)
{
    int v;

    *prim = g->mesh < nmesh
                ? cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(mesh[g->mesh], "primitives"),
                                     g->index)
                : NULL;
    for (v = 0; v < g->nvert; v++)
        if (g->vmap[v] >= nv || (g->ngroup && g->ngroup[v] >= nn && nn))
            return api__fail(err, MCF_EINVAL, "gltf: the document's record does not "
                             "belong to this mesh");
    if (!*prim || g->pos.acc < 0 || g->pos.acc >= nacc)
        return api__fail(err, MCF_EDECODE, "gltf: mesh %d primitive %d is not in the "
                         "document", g->mesh, g->index);
    return MCF_OK;
}

/* A plain primitive: its POSITION (and NORMAL) values overwritten in
 * place, their buffers marked dirty, then POSITION's bounds over the
 * whole accessor (pos). */
static mcf_status rewrite_plain(api__gltf_doc *d, const api__gltf_prim *g, const double *X,
                                const double *N, cJSON *pos, int *dirty, mcf_error *err)
{
    double lo[3], hi[3];
    int v, k;

    for (v = 0; v < g->nvert; v++)
        for (k = 0; k < 3; k++) {
            if (g->vmap[v] >= 0)
                api__put_f32(d->buf[g->pos.buf] + g->pos.off +
                                 (size_t)g->pos.stride * (size_t)v + 4 * (size_t)k,
                             (float)X[3 * (size_t)g->vmap[v] + k]);
            if (N && g->ngroup && g->ngroup[v] >= 0 && g->nrm.buf >= 0)
                api__put_f32(d->buf[g->nrm.buf] + g->nrm.off +
                                 (size_t)g->nrm.stride * (size_t)v + 4 * (size_t)k,
                             (float)N[3 * (size_t)g->ngroup[v] + k]);
        }
    dirty[g->pos.buf] = 1;
    if (g->nrm.buf >= 0)
        dirty[g->nrm.buf] = 1;
    api__gltf_bounds(d->buf[g->pos.buf] + g->pos.off, g->nvert, (size_t)g->pos.stride, lo, hi);
    if (!api__gltf_set_vec3(pos, "min", lo) || !api__gltf_set_vec3(pos, "max", hi))
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    return MCF_OK;
}

/* The buffers holding the ns new Draco streams (streams[i] for view
 * sv[i]), each laid out again once (dirty 2). */
static mcf_status relayout_streams(api__gltf_doc *d, cJSON **view, int nview, const int *sv,
                                   api_buf *streams, int ns, int *dirty, mcf_error *err)
{
    mcf_status rc;
    int p;

    for (p = 0; p < ns; p++) {
        long long b = int_of(view[sv[p]], "buffer");
        if (b < 0 || b >= d->nbuf)
            return api__fail(err, MCF_EDECODE, "gltf: buffer view %d has no buffer", sv[p]);
        if (dirty[b] != 2) {
            if ((rc = relayout(d, (int)b, view, nview, sv, streams, ns, err)) != MCF_OK)
                return rc;
            dirty[b] = 2;
        }
    }
    return MCF_OK;
}

static mcf_status rewrite(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                          mcf_error *err)
{
    const api_attrs *at = o->attrs;
    const double *X = mcf_mesh_positions(m);
    const int nv = mcf_mesh_nvertices(m);
    const int nn = at->a[API_ATTR_NORMAL].corners ? at->a[API_ATTR_NORMAL].nvalues : 0;
    api__gltf_doc d;
    cJSON *root = NULL, **acc = NULL, **view = NULL, **mesh = NULL, *prim;
    double *N = NULL;
    int *dirty = NULL, *sv = NULL, nacc, nview, nmesh, p, ns = 0;
    api_buf *streams = NULL;
    mcf_status rc = api__gltf_unplan(at->gltf, at->gltf_len, &d, err);

    if (rc != MCF_OK)
        return rc;
    if (nn && (rc = api__attrs_normals(at, m, &N, err)) != MCF_OK)
        goto done;
    root = cJSON_ParseWithLength(d.json, d.json_len);
    acc = root ? api__gltf_items(root, "accessors", &nacc) : NULL;
    view = acc ? api__gltf_items(root, "bufferViews", &nview) : NULL;
    mesh = view ? api__gltf_items(root, "meshes", &nmesh) : NULL;
    dirty = calloc((size_t)d.nbuf + 1, sizeof *dirty);
    sv = calloc((size_t)d.nprim, sizeof *sv);
    streams = calloc((size_t)d.nprim, sizeof *streams);
    if (!mesh || !dirty || !sv || !streams) {
        rc = root ? api__fail(err, MCF_ENOMEM, "gltf: out of memory")
                  : api__fail(err, MCF_EDECODE, "gltf: the document's JSON does not parse");
        goto done;
    }
    for (p = 0; p < d.nprim; p++) {
        api__gltf_prim *g = &d.prim[p];
        if ((rc = prim_of(g, nv, nn, mesh, nmesh, nacc, &prim, err)) != MCF_OK)
            goto done;
        if (g->draco_view < 0)
            rc = rewrite_plain(&d, g, X, N, acc[g->pos.acc], dirty, err);
        else if (g->draco_view >= nview)
            rc = api__fail(err, MCF_EDECODE, "gltf: no buffer view %d", g->draco_view);
        else {
            api_buf_init(&streams[ns], (size_t)-1);
            sv[ns] = g->draco_view;
            rc = redraco(g, X, N, o, prim, acc, nacc, &streams[ns++], err);
        }
        if (rc != MCF_OK)
            goto done;
    }
    if ((rc = relayout_streams(&d, view, nview, sv, streams, ns, dirty, err)) != MCF_OK)
        goto done;
    rc = api__gltf_serialize(root, d.buf, d.buf_len, dirty, d.nbuf,
                   o->format == API_FMT_GLB || o->format == API_FMT_GLTF ? o->format
                                                                          : d.container,
                   out, err);
done:
    for (p = 0; p < ns; p++)
        api_buf_free(&streams[p]);
    free(streams);
    free(sv);
    free(dirty);
    free(acc);
    free(view);
    free(mesh);
    free(N);
    cJSON_Delete(root);
    api__gltf_doc_free(&d);
    return rc;
}

mcf_status api_gltf_encode(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                           mcf_error *err)
{
    api_encode_opts def;
    mcf_status rc;
    if (!o) {
        api_encode_opts_init(&def);
        def.format = API_FMT_GLB;
        o = &def;
    }
    if (o->format != API_FMT_GLB && o->format != API_FMT_GLTF)
        return api__fail(err, MCF_EINVAL, "gltf: output format must be glb or gltf");
    if ((rc = api__attrs_check(o->attrs, m, "gltf", err)) != MCF_OK)
        return rc;
    if (o->compression_level < 0 || o->compression_level > 10)
        return api__fail(err, MCF_EINVAL,
                         "gltf: compression_level %d out of range (0..10)",
                         o->compression_level);
    return o->attrs && o->attrs->gltf ? rewrite(m, o, out, err) : api__gltf_fresh(m, o, out, err);
}
