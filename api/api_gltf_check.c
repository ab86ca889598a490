/* SPDX-License-Identifier: MIT */
/*
 * api_gltf_check.c - what a glTF document must pass before any parser
 * builds it (api__gltf_check_json), and the counts it declares for the
 * memory estimate (api__gltf_declared).
 *
 * A GLB's header and chunks exactly (api__glb_split: tinygltf 2.7 would
 * read 8 bytes past a BIN chunk that ends the input short); the JSON's
 * nesting (API_GLTF_MAX_DEPTH) and number of values (API_GLTF_MAX_VALUES),
 * scanned without a parser; then, parsed with cJSON: no duplicate key
 * anywhere (two readers must see the same document), asset.version 2.x,
 * no extension that stores geometry another way (KHR_mesh_quantization,
 * meshopt), every buffer embedded (GLB's BIN chunk or a data: URI: a
 * request carries one file, so a .gltf naming an external .bin is
 * refused, and no URI is ever opened), every buffer view inside its
 * buffer (tinygltf reads images from buffer views unchecked). And the
 * JSON tinygltf reads: without the indices of Draco primitives, which it
 * refuses (hide_draco_indices).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

/* ----------------------------------------------------------- container */

mcf_status api__glb_split(const void *buf, size_t len, const char **json,
                          size_t *json_len, const unsigned char **bin,
                          size_t *bin_len, mcf_error *err)
{
    const unsigned char *p = buf;
    uint32_t total, jlen, blen;
    if (len < 20 || memcmp(p, "glTF", 4) != 0)
        return api__fail(err, MCF_EDECODE, "glb: no \"glTF\" header (%zu bytes)", len);
    if (api__get_le32(p + 4) != 2)
        return api__fail(err, MCF_EDECODE, "glb: version %u (2 expected)",
                         (unsigned)api__get_le32(p + 4));
    total = api__get_le32(p + 8);
    jlen = api__get_le32(p + 12);
    if (total != len)
        return api__fail(err, MCF_EDECODE,
                         "glb: header says %u bytes, the input has %zu", (unsigned)total,
                         len);
    if (api__get_le32(p + 16) != 0x4E4F534Au || jlen == 0 || jlen % 4 != 0 ||
        jlen > len - 20)
        return api__fail(err, MCF_EDECODE,
                         "glb: the first chunk must be JSON, 4-aligned, inside the "
                         "input (%u bytes declared)", (unsigned)jlen);
    *json = (const char *)p + 20;
    *json_len = jlen;
    *bin = NULL;
    *bin_len = 0;
    if (len - 20 - jlen == 0)
        return MCF_OK;
    if (len - 20 - jlen < 8)
        return api__fail(err, MCF_EDECODE, "glb: %zu stray bytes after the JSON chunk",
                         len - 20 - jlen);
    blen = api__get_le32(p + 20 + jlen);
    if (api__get_le32(p + 24 + jlen) != 0x004E4942u || blen % 4 != 0 ||
        blen != len - 28 - jlen)
        return api__fail(err, MCF_EDECODE,
                         "glb: the second chunk must be BIN, 4-aligned and end the "
                         "input (%u bytes declared, %zu there)", (unsigned)blen,
                         len - 28 - jlen);
    *bin = p + 28 + jlen;
    *bin_len = blen;
    return MCF_OK;
}

/* ---------------------------------------------------------- JSON checks */

/* Nesting and the number of values, without parsing (strings skipped,
 * escapes included), so no parser meets a bomb. Malformed JSON passes
 * here: the parser names it. */
static mcf_status json_scan(const char *s, size_t n, mcf_error *err)
{
    size_t i = 0, values = 0;
    int depth = 0, c;
    while ((c = api__json_next(s, n, &i)) >= 0) {
        if (c == '"') {
            values++;
        } else if (c == '{' || c == '[') {
            if (++depth > API_GLTF_MAX_DEPTH)
                return api__fail(err, MCF_ELIMIT,
                                 "gltf: JSON nested deeper than %d levels",
                                 API_GLTF_MAX_DEPTH);
            values++;
        } else if (c == '}' || c == ']') {
            depth--;
        } else if (c == ',' || c == ':') {
            values++;
        }
        if (values > 2 * (size_t)API_GLTF_MAX_VALUES)
            return api__fail(err, MCF_ELIMIT, "gltf: JSON of more than %d values",
                             API_GLTF_MAX_VALUES);
    }
    return MCF_OK;
}

static int cmp_str(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* The first key that an object of j (at any depth) holds twice, or NULL;
 * *oom on allocation failure. */
static const char *duplicate_key(const cJSON *j, int *oom)
{
    const cJSON *c;
    if (cJSON_IsObject(j)) {
        size_t n = 0, i;
        const char **k;
        const char *dup = NULL;
        for (c = j->child; c; c = c->next)
            n++;
        k = malloc(sizeof *k * (n ? n : 1));
        if (!k) {
            *oom = 1;
            return NULL;
        }
        for (i = 0, c = j->child; c; c = c->next)
            k[i++] = c->string ? c->string : "";
        qsort(k, n, sizeof *k, cmp_str);
        for (i = 1; i < n && !dup; i++)
            if (strcmp(k[i - 1], k[i]) == 0)
                dup = k[i];
        free(k);
        if (dup)
            return dup;
    }
    if (cJSON_IsObject(j) || cJSON_IsArray(j))
        for (c = j->child; c; c = c->next) {
            const char *d = duplicate_key(c, oom);
            if (d || *oom)
                return d;
        }
    return NULL;
}

/* Member k of o as an integer in [lo, hi]: 1 (in *v), 0 when absent (*v =
 * def), -1 when not such an integer. */
static int int_member(const cJSON *o, const char *k, long long lo, long long hi,
                      long long def, long long *v)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, k);
    *v = def;
    if (!x)
        return 0;
    if (!cJSON_IsNumber(x) || !(x->valuedouble >= (double)lo && x->valuedouble <= (double)hi) ||
        x->valuedouble != floor(x->valuedouble))
        return -1;
    *v = (long long)x->valuedouble;
    return 1;
}

static int has_string(const cJSON *arr, const char *s)
{
    const cJSON *c;
    cJSON_ArrayForEach(c, arr)
        if (cJSON_IsString(c) && strcmp(c->valuestring, s) == 0)
            return 1;
    return 0;
}

#define MAX_BYTES (1LL << 40)

/* The document-level checks of the file comment on the parsed JSON. */
static mcf_status check_doc(const cJSON *root, int glb, mcf_error *err)
{
    static const char *const refused[] = {"KHR_mesh_quantization",
                                          "EXT_meshopt_compression",
                                          "KHR_meshopt_compression", NULL};
    const cJSON *asset = cJSON_GetObjectItemCaseSensitive(root, "asset");
    const cJSON *ver = cJSON_GetObjectItemCaseSensitive(asset, "version");
    const cJSON *used = cJSON_GetObjectItemCaseSensitive(root, "extensionsUsed");
    const cJSON *buffers = cJSON_GetObjectItemCaseSensitive(root, "buffers");
    const cJSON *views = cJSON_GetObjectItemCaseSensitive(root, "bufferViews");
    const cJSON *b, *v;
    long long *blen = NULL, x, off, n;
    int nb = cJSON_GetArraySize(buffers), i;

    if (!cJSON_IsString(ver) || strncmp(ver->valuestring, "2.", 2) != 0)
        return api__fail(err, MCF_EDECODE,
                         "gltf: asset.version must be \"2.x\" (glTF 2.0)");
    for (i = 0; refused[i]; i++)
        if (has_string(used, refused[i]))
            return api__fail(err, MCF_EDECODE,
                             "gltf: extension %s stores geometry in a way mcfd does not "
                             "read (plain accessors and KHR_draco_mesh_compression are)",
                             refused[i]);
    if (buffers && !cJSON_IsArray(buffers))
        return api__fail(err, MCF_EDECODE, "gltf: buffers is not an array");
    blen = malloc(sizeof *blen * (size_t)(nb ? nb : 1));
    if (!blen)
        return api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    i = 0;
    cJSON_ArrayForEach(b, buffers) {
        const cJSON *uri = cJSON_GetObjectItemCaseSensitive(b, "uri");
        if (int_member(b, "byteLength", 1, MAX_BYTES, -1, &blen[i]) != 1) {
            free(blen);
            return api__fail(err, MCF_EDECODE,
                             "gltf: buffer %d has no byteLength of at least 1", i);
        }
        if (uri ? !cJSON_IsString(uri) || strncmp(uri->valuestring, "data:", 5) != 0
                : !(glb && i == 0)) {
            char shown[API__SHOWN];
            free(blen);
            return api__fail(err, MCF_EDECODE,
                             "gltf: buffer %d refers to the file '%s': mcfd reads one "
                             "file per request and never opens a URI; send a GLB, or a "
                             ".gltf with its buffers embedded as data: URIs", i,
                             cJSON_IsString(uri)
                                 ? api__show(uri->valuestring, strlen(uri->valuestring), shown)
                                 : "(none)");
        }
        i++;
    }
    if (views && !cJSON_IsArray(views)) {
        free(blen);
        return api__fail(err, MCF_EDECODE, "gltf: bufferViews is not an array");
    }
    i = 0;
    cJSON_ArrayForEach(v, views) {
        long long bi;
        if (int_member(v, "buffer", 0, nb - 1, -1, &bi) != 1 ||
            int_member(v, "byteOffset", 0, MAX_BYTES, 0, &off) < 0 ||
            int_member(v, "byteLength", 1, MAX_BYTES, -1, &n) != 1 ||
            int_member(v, "byteStride", 4, 252, 0, &x) < 0 ||
            off + n > blen[bi]) {
            free(blen);
            return api__fail(err, MCF_EDECODE,
                             "gltf: buffer view %d lies outside its buffer (or names "
                             "none, or a bad offset, length or stride)", i);
        }
        i++;
    }
    free(blen);
    n = cJSON_GetArraySize(views);
    i = 0;
    cJSON_ArrayForEach(v, cJSON_GetObjectItemCaseSensitive(root, "images")) {
        if (int_member(v, "bufferView", 0, n - 1, 0, &x) < 0)
            return api__fail(err, MCF_EDECODE,
                             "gltf: image %d names a buffer view that does not exist", i);
        i++;
    }
    return MCF_OK;
}

/* tinygltf 2.7 refuses a primitive whose indices accessor has no buffer
 * view, which every KHR_draco_mesh_compression primitive has (the stream
 * holds the faces): the JSON it reads leaves such indices out (the
 * document the encoder rewrites keeps them). Returns 1 when it removed
 * one. */
static int hide_draco_indices(cJSON *root)
{
    const cJSON *mesh;
    cJSON *prim;
    int n = 0;
    cJSON_ArrayForEach(mesh, cJSON_GetObjectItemCaseSensitive(root, "meshes"))
        cJSON_ArrayForEach(prim, cJSON_GetObjectItemCaseSensitive(mesh, "primitives"))
            if (cJSON_GetObjectItemCaseSensitive(
                    cJSON_GetObjectItemCaseSensitive(prim, "extensions"),
                    "KHR_draco_mesh_compression") &&
                cJSON_GetObjectItemCaseSensitive(prim, "indices")) {
                cJSON_DeleteItemFromObjectCaseSensitive(prim, "indices");
                n = 1;
            }
    return n;
}

mcf_status api__gltf_check_json(const void *in, size_t in_len, const char *json, size_t n,
                             int glb, char **tiny, size_t *tiny_len, mcf_error *err)
{
    cJSON *root;
    const char *dup;
    int oom = 0;
    mcf_status rc = json_scan(json, n, err);
    *tiny = NULL;
    if (rc != MCF_OK)
        return rc;
    root = cJSON_ParseWithLength(json, n);
    if (!root) {
        const char *at = cJSON_GetErrorPtr();
        char shown[API__SHOWN];
        size_t left = at && at >= json && at < json + n ? (size_t)(json + n - at) : 0;
        return api__fail(err, MCF_EDECODE, "gltf: malformed JSON near '%s'",
                         left ? api__show(at, left < 32 ? left : 32, shown) : "the end");
    }
    if (!cJSON_IsObject(root))
        rc = api__fail(err, MCF_EDECODE, "gltf: the JSON is not an object");
    else if ((dup = duplicate_key(root, &oom)) != NULL) {
        char shown[API__SHOWN];
        rc = api__fail(err, MCF_EDECODE, "gltf: key '%s' appears twice in one object",
                       api__show(dup, strlen(dup), shown));
    } else if (oom)
        rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
    else
        rc = check_doc(root, glb, err);
    if (rc == MCF_OK && hide_draco_indices(root)) {
        char *j = cJSON_PrintUnformatted(root);
        size_t jl = j ? strlen(j) : 0, jp = (jl + 3) / 4 * 4;
        const size_t rest = glb ? in_len - 20 - n : 0; /* the BIN chunk */
        *tiny_len = glb ? 20 + jp + rest : jl;
        *tiny = j && *tiny_len <= 0xffffffffu ? malloc(*tiny_len + 1) : NULL;
        if (!*tiny) {
            rc = api__fail(err, MCF_ENOMEM, "gltf: out of memory");
        } else if (!glb) {
            memcpy(*tiny, j, jl);
        } else {
            memcpy(*tiny, in, 20);
            api__put_le32((unsigned char *)*tiny + 8, (uint32_t)*tiny_len);
            api__put_le32((unsigned char *)*tiny + 12, (uint32_t)jp);
            memcpy(*tiny + 20, j, jl);
            memset(*tiny + 20 + jl, ' ', jp - jl);
            memcpy(*tiny + 20 + jp, (const char *)in + 20 + n, rest);
        }
        free(j);
    }
    cJSON_Delete(root);
    return rc;
}

int api__gltf_declared(const void *buf, size_t len, long long *nv, long long *nf,
                       int *draco)
{
    const char *json = buf;
    size_t json_len = len;
    const unsigned char *bin;
    size_t bin_len;
    const cJSON *mesh, *prim;
    cJSON *root;
    int na;
    *nv = *nf = 0;
    *draco = 0;
    if (len >= 4 && memcmp(buf, "glTF", 4) == 0 &&
        api__glb_split(buf, len, &json, &json_len, &bin, &bin_len, NULL) != MCF_OK)
        return 0;
    if (json_scan(json, json_len, NULL) != MCF_OK ||
        !(root = cJSON_ParseWithLength(json, json_len)))
        return 0;
    na = cJSON_GetArraySize(cJSON_GetObjectItemCaseSensitive(root, "accessors"));
    cJSON_ArrayForEach(mesh, cJSON_GetObjectItemCaseSensitive(root, "meshes"))
        cJSON_ArrayForEach(prim, cJSON_GetObjectItemCaseSensitive(mesh, "primitives")) {
            const cJSON *acc = cJSON_GetObjectItemCaseSensitive(root, "accessors");
            long long mode, pa, ia, n, idx;
            int_member(prim, "mode", 0, 6, 4, &mode);
            if (mode < 4)
                continue;
            *draco |= cJSON_GetObjectItemCaseSensitive(
                          cJSON_GetObjectItemCaseSensitive(prim, "extensions"),
                          "KHR_draco_mesh_compression") != NULL;
            if (int_member(cJSON_GetObjectItemCaseSensitive(prim, "attributes"),
                           "POSITION", 0, na - 1, -1, &pa) != 1 ||
                int_member(cJSON_GetArrayItem(acc, (int)pa), "count", 0, 1LL << 40, 0,
                           &n) != 1)
                continue;
            idx = n;
            if (int_member(prim, "indices", 0, na - 1, -1, &ia) == 1)
                int_member(cJSON_GetArrayItem(acc, (int)ia), "count", 0, 1LL << 40, 0, &idx);
            *nv += n;
            *nf += mode == 4 ? idx / 3 : idx > 2 ? idx - 2 : 0;
        }
    cJSON_Delete(root);
    return 1;
}
