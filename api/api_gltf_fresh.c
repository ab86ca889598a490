/* SPDX-License-Identifier: MIT */
/*
 * api_gltf_fresh.c - a new glTF 2.0 document for a mesh from any format
 * but glTF (api__gltf_fresh; api_gltf_encode.c rewrites a glTF input's
 * own).
 *
 * A new document (any other input): one node, one mesh, one triangle
 * primitive, one buffer; a vertex per distinct (vertex, texcoord, normal,
 * colour) of the corners, float32 positions (with min and max), normals
 * recomputed, TEXCOORD_0 (v flipped to glTF's top-down convention),
 * COLOR_0, uint32 indices.
 *
 * A mesh that came from Draco leaves as a KHR_draco_mesh_compression
 * primitive (fresh_draco) when its positions are float32.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* glTF's component types and buffer view targets */
#define GL_FLOAT 5126
#define GL_UINT 5125
#define GL_USHORT 5123
#define GL_ARRAY 34962
#define GL_ELEMENTS 34963

/* A glTF vertex: one mesh vertex with one value of each attribute. */
typedef struct {
    int32_t k[4];           /* vertex, texcoord, normal, colour (-1: none) */
    int32_t corner;
} corner_key;

static int cmp_corner(const void *pa, const void *pb)
{
    const corner_key *a = pa, *b = pb;
    int i;
    for (i = 0; i < 4; i++)
        if (a->k[i] != b->k[i])
            return a->k[i] < b->k[i] ? -1 : 1;
    return (a->corner > b->corner) - (a->corner < b->corner);
}

/* Adds a bufferView over [off, off + n) of buffer 0 and an accessor of
 * count elements of type and component type ct; returns its index. */
static int add_accessor(cJSON *root, size_t off, size_t n, int count, const char *type,
                        int ct, int target)
{
    cJSON *views = cJSON_GetObjectItemCaseSensitive(root, "bufferViews");
    cJSON *accs = cJSON_GetObjectItemCaseSensitive(root, "accessors");
    cJSON *v = cJSON_CreateObject(), *a = cJSON_CreateObject();
    int id = cJSON_GetArraySize(accs);
    if (!v || !a || !cJSON_AddItemToArray(views, v) || !cJSON_AddItemToArray(accs, a)) {
        cJSON_Delete(v);
        cJSON_Delete(a);
        return -1;
    }
    if (!cJSON_AddNumberToObject(v, "buffer", 0) ||
        !cJSON_AddNumberToObject(v, "byteOffset", (double)off) ||
        !cJSON_AddNumberToObject(v, "byteLength", (double)n) ||
        !cJSON_AddNumberToObject(v, "target", target) ||
        !cJSON_AddNumberToObject(a, "bufferView", cJSON_GetArraySize(views) - 1) ||
        !cJSON_AddNumberToObject(a, "componentType", ct) ||
        !cJSON_AddNumberToObject(a, "count", count) ||
        !cJSON_AddStringToObject(a, "type", type))
        return -1;
    return id;
}


/* The attributes as the Draco stream of a glTF carries them: a copy of
 * o's, quantization kept, texture coordinates flipped to glTF's top-down
 * convention (their quantization grid's origin too), in *out. */
static mcf_status flipped_attrs(const mcf_mesh *m, const api_attrs *at, api_attrs **out,
                                mcf_error *err)
{
    api_attrs *flip = api_attrs_new(mcf_mesh_nvertices(m), mcf_mesh_nfaces(m));
    mcf_status rc;
    int i, k;

    if (!(*out = flip))
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    flip->float32 = at->float32;
    flip->pos_bits = at->pos_bits;
    for (k = 0; k < API_ATTR_KINDS; k++) {
        const api__attr *a = &at->a[k];
        api__attr *f = &flip->a[k];
        if (!a->corners)
            continue;
        if ((rc = api_attrs_set(flip, (api_attr_kind)k, a->ncomp, a->nvalues, a->values,
                                a->corners, err)) != MCF_OK) {
            api_attrs_free(flip);
            *out = NULL;
            return rc;
        }
        f->bits = a->bits;
        memcpy(f->qorigin, a->qorigin, sizeof f->qorigin);
        f->qrange = a->qrange;
        for (i = 0; k == API_ATTR_TEXCOORD && i < f->nvalues; i++)
            f->values[2 * (size_t)i + 1] = 1.0 - f->values[2 * (size_t)i + 1];
        if (k == API_ATTR_TEXCOORD)
            f->qorigin[1] = 1.0f - f->qorigin[1] - f->qrange;
    }
    return MCF_OK;
}

/* The KHR_draco_mesh_compression primitive's JSON for the stream of
 * slen bytes that decoded to back: the extension, accessors without data
 * whose counts and bounds are the stream's, buffer view 0 over it. 0 when
 * out of memory. */
static int draco_json(cJSON *root, cJSON *prim, const api__draco_prim *back, size_t slen)
{
    static const struct {
        int type;
        const char *name, *gtype;
    } names[] = {{0, "POSITION", "VEC3"}, {1, "NORMAL", "VEC3"}, {3, "TEXCOORD_0", "VEC2"},
                 {2, "COLOR_0", NULL}};
    static const char *const used[] = {"KHR_draco_mesh_compression"};
    cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
    cJSON *accs = cJSON_GetObjectItemCaseSensitive(root, "accessors");
    cJSON *views = cJSON_GetObjectItemCaseSensitive(root, "bufferViews");
    cJSON *ext = cJSON_CreateObject();
    double lo[3], hi[3];
    int i, k, id;
    int ok = ext && api__gltf_set_num(ext, "bufferView", 0) &&
             api__gltf_set_item(ext, "attributes", cJSON_CreateObject()) &&
             api__gltf_set_item(prim, "extensions", cJSON_CreateObject()) &&
             api__gltf_set_item(cJSON_GetObjectItemCaseSensitive(prim, "extensions"),
                      "KHR_draco_mesh_compression", ext);

    for (i = 0; ok && i < back->nattr; i++) {
        const api__draco_attr *a = &back->attr[i];
        cJSON *acc;
        for (k = 0; k < 4 && names[k].type != a->type; k++)
            ;
        if (k == 4)
            continue;
        if (a->type == 0)
            api__gltf_bounds(a->data, back->npoints, 12, lo, hi);
        id = cJSON_GetArraySize(accs);
        ok = (acc = cJSON_CreateObject()) != NULL && cJSON_AddItemToArray(accs, acc) &&
             api__gltf_set_num(acc, "componentType", a->dtype == API__DRACO_FLOAT32 ? GL_FLOAT : 5121) &&
             api__gltf_set_num(acc, "count", back->npoints) &&
             api__gltf_set_item(acc, "type", cJSON_CreateString(
                                       names[k].gtype ? names[k].gtype
                                                      : a->ncomp == 4 ? "VEC4" : "VEC3")) &&
             (a->dtype == API__DRACO_FLOAT32 || cJSON_AddTrueToObject(acc, "normalized")) &&
             (a->type != 0 || (api__gltf_set_vec3(acc, "min", lo) && api__gltf_set_vec3(acc, "max", hi))) &&
             api__gltf_set_num(attrs, names[k].name, id) &&
             api__gltf_set_num(cJSON_GetObjectItemCaseSensitive(ext, "attributes"), names[k].name,
                     a->id);
    }
    id = cJSON_GetArraySize(accs);
    return ok && (ext = cJSON_CreateObject()) != NULL && cJSON_AddItemToArray(accs, ext) &&
           api__gltf_set_num(ext, "componentType", back->npoints <= 65535 ? GL_USHORT : GL_UINT) &&
           api__gltf_set_num(ext, "count", 3.0 * back->nfaces) &&
           api__gltf_set_item(ext, "type", cJSON_CreateString("SCALAR")) && api__gltf_set_num(prim, "indices", id) &&
           api__gltf_set_item(root, "extensionsUsed", cJSON_CreateStringArray(used, 1)) &&
           api__gltf_set_item(root, "extensionsRequired", cJSON_CreateStringArray(used, 1)) &&
           cJSON_AddItemToArray(views, cJSON_CreateObject()) &&
           api__gltf_set_num(cJSON_GetArrayItem(views, 0), "buffer", 0) &&
           api__gltf_set_num(cJSON_GetArrayItem(views, 0), "byteLength", (double)slen);
}

/* A mesh that came from Draco, as a KHR_draco_mesh_compression
 * primitive: api_draco_encode's stream (its quantization kept, texture
 * coordinates flipped to glTF's convention first) in *bin, its JSON in
 * root and prim (draco_json). Returns 0 (nothing added) when the
 * stream's positions are not float32 (lossless doubles), which glTF
 * cannot carry: the caller writes plain. */
static mcf_status fresh_draco(const mcf_mesh *m, const api_encode_opts *o, cJSON *root,
                              cJSON *prim, unsigned char **bin, size_t *blen,
                              int *done, mcf_error *err)
{
    api_attrs *flip;
    api_encode_opts eo = *o;
    api_buf stream;
    api__draco_prim back;
    mcf_status rc = flipped_attrs(m, o->attrs, &flip, err);
    int i;

    *done = 0;
    if (rc != MCF_OK)
        return rc;
    memset(&back, 0, sizeof back);
    api_buf_init(&stream, (size_t)-1);
    eo.format = API_FMT_DRACO;
    eo.attrs = flip;
    if ((rc = api_draco_encode(m, &eo, &stream, NULL, err)) == MCF_OK &&
        (rc = api__draco_prim_decode(stream.data, stream.len, NULL, &back, err)) == MCF_OK) {
        for (i = 0; i < back.nattr; i++)
            if (back.attr[i].type == 0 &&
                (back.attr[i].dtype != API__DRACO_FLOAT32 || back.attr[i].ncomp != 3))
                goto plain;
        if (!draco_json(root, prim, &back, stream.len))
            rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        else {
            *bin = (unsigned char *)api_buf_detach(&stream, blen);
            *done = 1;
        }
    }
plain:
    api__draco_prim_free(&back);
    api_buf_free(&stream);
    api_attrs_free(flip);
    return rc;
}

/* A new document's plain primitive: its glTF vertices (one per distinct
 * corner_key) and where each attribute lies in buffer 0. */
typedef struct {
    const api__attr *tc, *nm, *co;  /* texcoords, normals, colours (NULL: none) */
    int ncol;                       /* colour components */
    size_t nc, np;                  /* corners, glTF vertices */
    size_t off[5];                  /* positions, normals, texcoords, colours, indices */
    size_t blen;                    /* buffer 0's bytes */
    double lo[3], hi[3];            /* the positions' bounds, as float32 */
} fresh_plan;

/* The glTF vertex of each corner (point) and the buffer's layout. */
static void weld(const mcf_mesh *m, fresh_plan *L, corner_key *keys, int32_t *point)
{
    const int32_t *F = mcf_mesh_faces(m);
    size_t i, np = 0;

    for (i = 0; i < L->nc; i++) {
        keys[i].k[0] = F[i];
        keys[i].k[1] = L->tc ? L->tc->corners[i] : -1;
        keys[i].k[2] = L->nm ? L->nm->corners[i] : -1;
        keys[i].k[3] = L->co ? L->co->corners[i] : -1;
        keys[i].corner = (int32_t)i;
    }
    qsort(keys, L->nc, sizeof *keys, cmp_corner);
    for (i = 0; i < L->nc; i++) {
        if (i > 0 && memcmp(keys[i].k, keys[i - 1].k, sizeof keys[i].k) != 0)
            np++;
        point[keys[i].corner] = (int32_t)np;
    }
    L->np = ++np;
    /* positions, normals, texcoords, colours, indices: 4-aligned each */
    L->off[0] = 0;
    L->off[1] = 12 * np;
    L->off[2] = L->off[1] + (L->nm ? 12 * np : 0);
    L->off[3] = L->off[2] + (L->tc ? 8 * np : 0);
    L->off[4] = L->off[3] + 4 * (size_t)L->ncol * np;
    L->blen = L->off[4] + 4 * L->nc;
}

/* Buffer 0's values (texcoords' v flipped to glTF's top-down convention)
 * and the positions' bounds. */
static void fill(const mcf_mesh *m, const double *N, fresh_plan *L, const corner_key *keys,
                 const int32_t *point, unsigned char *bin)
{
    const double *X = mcf_mesh_positions(m);
    const size_t *off = L->off;
    const int ncol = L->ncol;
    size_t i;
    int c;

    for (c = 0; c < 3; c++) {
        L->lo[c] = HUGE_VAL;
        L->hi[c] = -HUGE_VAL;
    }
    for (i = 0; i < L->nc; i++) {
        const corner_key *k = &keys[i];
        size_t pt = (size_t)point[k->corner];
        for (c = 0; c < 3; c++) {
            double x = X[3 * (size_t)k->k[0] + c];
            api__put_f32(bin + off[0] + 12 * pt + 4 * (size_t)c, (float)x);
            L->lo[c] = (float)x < L->lo[c] ? (float)x : L->lo[c];
            L->hi[c] = (float)x > L->hi[c] ? (float)x : L->hi[c];
            if (L->nm)
                api__put_f32(bin + off[1] + 12 * pt + 4 * (size_t)c,
                             (float)N[3 * (size_t)k->k[2] + c]);
        }
        if (L->tc) {
            api__put_f32(bin + off[2] + 8 * pt, (float)L->tc->values[2 * (size_t)k->k[1]]);
            api__put_f32(bin + off[2] + 8 * pt + 4,
                         (float)(1.0 - L->tc->values[2 * (size_t)k->k[1] + 1]));
        }
        for (c = 0; c < ncol; c++)
            api__put_f32(bin + off[3] + 4 * (size_t)ncol * pt + 4 * (size_t)c,
                         (float)L->co->values[(size_t)ncol * (size_t)k->k[3] + c]);
        api__put_le32(bin + off[4] + 4 * (size_t)k->corner, (uint32_t)pt);
    }
}

/* The primitive's accessors and views over buffer 0; 0 when out of memory. */
static int add_accessors(cJSON *root, cJSON *prim, const fresh_plan *L)
{
    cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
    cJSON *accs = cJSON_GetObjectItemCaseSensitive(root, "accessors");
    const size_t np = L->np;
    int a = add_accessor(root, L->off[0], 12 * np, (int)np, "VEC3", GL_FLOAT, GL_ARRAY);
    int ok = a >= 0 && cJSON_AddNumberToObject(attrs, "POSITION", a) &&
             api__gltf_set_vec3(cJSON_GetArrayItem(accs, a), "min", L->lo) &&
             api__gltf_set_vec3(cJSON_GetArrayItem(accs, a), "max", L->hi);

    if (ok && L->nm)
        ok = (a = add_accessor(root, L->off[1], 12 * np, (int)np, "VEC3", GL_FLOAT, GL_ARRAY)) >= 0 &&
             cJSON_AddNumberToObject(attrs, "NORMAL", a);
    if (ok && L->tc)
        ok = (a = add_accessor(root, L->off[2], 8 * np, (int)np, "VEC2", GL_FLOAT, GL_ARRAY)) >= 0 &&
             cJSON_AddNumberToObject(attrs, "TEXCOORD_0", a);
    if (ok && L->co)
        ok = (a = add_accessor(root, L->off[3], 4 * (size_t)L->ncol * np, (int)np,
                               L->ncol == 4 ? "VEC4" : "VEC3", GL_FLOAT, GL_ARRAY)) >= 0 &&
             cJSON_AddNumberToObject(attrs, "COLOR_0", a);
    if (ok)
        ok = (a = add_accessor(root, L->off[4], 4 * L->nc, (int)L->nc, "SCALAR", GL_UINT,
                               GL_ELEMENTS)) >= 0 &&
             cJSON_AddNumberToObject(prim, "indices", a);
    return ok;
}

mcf_status api__gltf_fresh(const mcf_mesh *m, const api_encode_opts *o, api_buf *out,
                           mcf_error *err)
{
    const api_attrs *at = o->attrs;
    fresh_plan L = {0};
    corner_key *keys = NULL;
    int32_t *point = NULL;
    double *N = NULL;
    unsigned char *bin = NULL;
    size_t blen;
    cJSON *root = cJSON_Parse("{\"asset\":{\"version\":\"2.0\",\"generator\":\"mcfd\"},"
                              "\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
                              "\"meshes\":[{\"primitives\":[{\"attributes\":{},\"mode\":4}]}],"
                              "\"accessors\":[],\"bufferViews\":[],\"buffers\":[{}]}");
    cJSON *prim;
    int dirty = 1;
    mcf_status rc = MCF_OK;

    L.tc = at && at->a[API_ATTR_TEXCOORD].corners ? &at->a[API_ATTR_TEXCOORD] : NULL;
    L.nm = at && at->a[API_ATTR_NORMAL].corners ? &at->a[API_ATTR_NORMAL] : NULL;
    L.co = at && at->a[API_ATTR_COLOR].corners ? &at->a[API_ATTR_COLOR] : NULL;
    L.ncol = L.co ? L.co->ncomp : 0;
    L.nc = 3 * (size_t)mcf_mesh_nfaces(m);
    keys = malloc(sizeof *keys * L.nc);
    point = malloc(sizeof *point * L.nc);
    if (!keys || !point || !root) {
        rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        goto done;
    }
    prim = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(
                                  cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "meshes"), 0),
                                  "primitives"), 0);
    if (at && at->pos_bits >= 0) {
        /* it came from Draco: it leaves as Draco */
        int done = 0;
        if ((rc = fresh_draco(m, o, root, prim, &bin, &blen, &done, err)) != MCF_OK)
            goto done;
        if (done) {
            rc = api__gltf_serialize(root, &bin, &blen, &dirty, 1, o->format, out, err);
            goto done;
        }
    }
    if (L.nm && (rc = api__attrs_normals(at, m, &N, err)) != MCF_OK)
        goto done;
    weld(m, &L, keys, point);
    blen = L.blen;
    if (!(bin = calloc(blen + 1, 1))) {
        rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory for %zu bytes", blen);
        goto done;
    }
    fill(m, N, &L, keys, point, bin);
    if (!add_accessors(root, prim, &L)) {
        rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        goto done;
    }
    rc = api__gltf_serialize(root, &bin, &blen, &dirty, 1, o->format, out, err);
done:
    free(keys);
    free(point);
    free(N);
    free(bin);
    cJSON_Delete(root);
    return rc;
}
