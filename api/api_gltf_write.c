/* SPDX-License-Identifier: MIT */
/*
 * api_gltf_write.c - what both glTF writers use (api_gltf_encode.c, a glTF
 * input's document rewritten; api_gltf_fresh.c, a new one): members of
 * the JSON set and replaced, a position accessor's bounds, and the
 * document with its buffers written as GLB or .gltf. A leaf below them:
 * it calls neither.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* ----------------------------------------------------------- JSON helpers */

/* The items of array member k of o (NULL when none: *n = 0). */
cJSON **api__gltf_items(const cJSON *o, const char *k, int *n)
{
    cJSON *a = cJSON_GetObjectItemCaseSensitive(o, k), *c;
    cJSON **v;
    int i = 0;
    *n = cJSON_IsArray(a) ? cJSON_GetArraySize(a) : 0;
    v = malloc(sizeof *v * (size_t)(*n + 1));
    if (!v)
        return NULL;
    if (*n)
        cJSON_ArrayForEach(c, a) v[i++] = c;
    return v;
}

/* Sets member k of o to x (every earlier k removed). 0 on failure. */
int api__gltf_set_item(cJSON *o, const char *k, cJSON *x)
{
    if (!x || !cJSON_IsObject(o)) {
        cJSON_Delete(x);
        return 0;
    }
    while (cJSON_GetObjectItemCaseSensitive(o, k))
        cJSON_DeleteItemFromObjectCaseSensitive(o, k);
    cJSON_AddItemToObject(o, k, x);
    return 1;
}

int api__gltf_set_num(cJSON *o, const char *k, double v)
{
    return api__gltf_set_item(o, k, cJSON_CreateNumber(v));
}

/* Bounds as exact decimals: cJSON prints 15 significant digits whenever
 * they read back within a relative 2^-52, which can miss a float's value
 * by a double's ulp, and readers check min and max against the data. */
int api__gltf_set_vec3(cJSON *o, const char *k, const double v[3])
{
    char s[96];
    snprintf(s, sizeof s, "[%.17g,%.17g,%.17g]", v[0], v[1], v[2]);
    return api__gltf_set_item(o, k, cJSON_CreateRaw(s));
}

/* ------------------------------------------------------------- container */

/* "data:application/octet-stream;base64," and the bytes. */
static char *data_uri(const unsigned char *p, size_t n)
{
    static const char b64[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    static const char head[] = "data:application/octet-stream;base64,";
    size_t i, o = sizeof head - 1;
    char *s = malloc(sizeof head + (n + 2) / 3 * 4);
    if (!s)
        return NULL;
    memcpy(s, head, o);
    for (i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) |
                     (i + 2 < n ? p[i + 2] : 0);
        s[o++] = b64[v >> 18 & 63];
        s[o++] = b64[v >> 12 & 63];
        s[o++] = i + 1 < n ? b64[v >> 6 & 63] : '=';
        s[o++] = i + 2 < n ? b64[v & 63] : '=';
    }
    s[o] = '\0';
    return s;
}

/* Writes root and the buffers in container fmt to out: GLB (buffer 0
 * without a URI, or GLB-bound, as the BIN chunk) or .gltf (buffers that
 * changed or had no URI as data: URIs). */
mcf_status api__gltf_serialize(cJSON *root, unsigned char *const *buf,
                               const size_t *blen, const int *dirty, int nbuf,
                               api_format fmt, api_buf *out, mcf_error *err)
{
    cJSON **b;
    int nb, i, ok = 1, bin = 0;
    char *json;
    size_t jl, len0 = out->len;
    mcf_status rc = MCF_OK;

    if (!(b = api__gltf_items(root, "buffers", &nb)))
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    for (i = 0; i < nb && i < nbuf && ok; i++) {
        const cJSON *uri = cJSON_GetObjectItemCaseSensitive(b[i], "uri");
        ok = api__gltf_set_num(b[i], "byteLength", (double)blen[i]);
        if (fmt == API_FMT_GLB && i == 0) {
            bin = 1;
            while (cJSON_GetObjectItemCaseSensitive(b[i], "uri"))
                cJSON_DeleteItemFromObjectCaseSensitive(b[i], "uri");
        } else if (!uri || dirty[i] || (fmt == API_FMT_GLTF && !cJSON_IsString(uri))) {
            char *s = data_uri(buf[i], blen[i]);
            ok = ok && s && api__gltf_set_item(b[i], "uri", cJSON_CreateString(s));
            free(s);
        }
    }
    free(b);
    json = ok ? cJSON_PrintUnformatted(root) : NULL;
    if (!json)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory writing the JSON");
    jl = strlen(json);
    if (fmt == API_FMT_GLTF) {
        rc = api_buf_append(out, json, jl);
    } else {
        unsigned char h[28];
        size_t jp = (jl + 3) / 4 * 4, bp = bin ? (blen[0] + 3) / 4 * 4 : 0;
        size_t total = 12 + 8 + jp + (bin ? 8 + bp : 0);
        static const char spaces[4] = {' ', ' ', ' ', ' '}, zeros[4] = {0, 0, 0, 0};
        if (total > 0xffffffffu) {
            free(json);
            return api__fail(err, MCF_ELIMIT, "glb: %zu bytes exceed GLB's 4 GiB", total);
        }
        memcpy(h, "glTF", 4);
        api__put_le32(h + 4, 2);
        api__put_le32(h + 8, (uint32_t)total);
        api__put_le32(h + 12, (uint32_t)jp);
        api__put_le32(h + 16, 0x4E4F534Au);
        api__put_le32(h + 20, (uint32_t)bp);
        api__put_le32(h + 24, 0x004E4942u);
        if ((rc = api_buf_append(out, h, 20)) == MCF_OK &&
            (rc = api_buf_append(out, json, jl)) == MCF_OK &&
            (rc = api_buf_append(out, spaces, jp - jl)) == MCF_OK && bin &&
            (rc = api_buf_append(out, h + 20, 8)) == MCF_OK &&
            (rc = api_buf_append(out, buf[0], blen[0])) == MCF_OK)
            rc = api_buf_append(out, zeros, bp - blen[0]);
    }
    free(json);
    return api__encode_end(out, len0, rc, fmt == API_FMT_GLB ? "glb" : "gltf", 1,
                           "document", err);
}

/* ----------------------------------------------------------------- bounds */

static float get_f32(const unsigned char *p)
{
    uint32_t v = api__get_le32(p);
    float f;
    memcpy(&f, &v, 4);
    return f;
}

/* min and max over n VEC3 floats at p, stride apart. */
void api__gltf_bounds(const unsigned char *p, int n, size_t stride, double lo[3],
                   double hi[3])
{
    int i, c;
    for (c = 0; c < 3; c++) {
        lo[c] = HUGE_VAL;
        hi[c] = -HUGE_VAL;
    }
    for (i = 0; i < n; i++)
        for (c = 0; c < 3; c++) {
            double x = get_f32(p + stride * (size_t)i + 4 * (size_t)c);
            lo[c] = x < lo[c] ? x : lo[c];
            hi[c] = x > hi[c] ? x : hi[c];
        }
}
