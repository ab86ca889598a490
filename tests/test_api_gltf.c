/* SPDX-License-Identifier: MIT */
/*
 * test_api_gltf.c - glTF 2.0 and GLB (api_gltf_decode.c, api_gltf.cc,
 * api_gltf_encode.c).
 *
 * Files: tests/data/gltf/ (make_gltf.py: CGAL's sphere as two primitives
 * with their own vertices, normals, UVs, node transforms, a camera,
 * extras; the GLB with an interleaved view, an image and a LINES
 * primitive), Draco GLBs made here from tests/data/meshes' car.drc (UVs,
 * normals) and from bunny.drc wrapped by hand (a stream written by Draco's
 * own tools). What is checked: the weld (the two primitives are the 812
 * vertices of the sphere, and stay so after smoothing: no seam opens),
 * positions written back exactly (as float32), the recomputed normals,
 * POSITION's min and max, every other byte and JSON member unchanged,
 * containers kept or converted, Draco in -> Draco out with its attribute
 * ids and UVs bit for bit; the third-party reader (Debian's assimp) reads
 * every output with the expected counts; hostile documents each give
 * their own clear error; the memory estimate and the sandbox's record.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"
#include "../api/api_internal.h"

static char *data_file(const char *rel, size_t *len)
{
    char path[4096], *buf = NULL;
    snprintf(path, sizeof path, "%s/%s", tl_testdata_dir(), rel);
    if (tl_read_file(path, &buf, len) != 0)
        fail_msg("cannot read %s", path);
    return buf;
}

static void decode(const void *buf, size_t len, mcf_mesh **m, api_attrs **a)
{
    mcf_error err = {MCF_OK, ""};
    api_format f;
    mcf_status rc = api_mesh_decode_attrs(buf, len, NULL, m, a, &f, &err);
    if (rc != MCF_OK)
        fail_msg("decode: %s: %s", mcf_status_name(rc), err.msg);
    assert_true(f == API_FMT_GLB || f == API_FMT_GLTF || f == API_FMT_DRACO ||
                f == API_FMT_OBJ);
}

static char *encode(const mcf_mesh *m, const api_attrs *a, api_format fmt, size_t *len)
{
    api_encode_opts o;
    api_buf b;
    mcf_error err = {MCF_OK, ""};
    mcf_status rc;
    api_encode_opts_init(&o);
    o.format = fmt;
    o.attrs = a;
    api_buf_init(&b, 0);
    rc = api_mesh_encode(m, &o, &b, &err);
    if (rc != MCF_OK)
        fail_msg("encode %s: %s: %s", api_format_name(fmt), mcf_status_name(rc), err.msg);
    return api_buf_detach(&b, len);
}

/* The JSON and BIN chunks of a GLB (the JSON parsed). */
static cJSON *glb_parts(const char *buf, size_t len, const unsigned char **bin,
                        size_t *bin_len)
{
    const char *json;
    size_t jl;
    mcf_error err;
    cJSON *j;
    if (api__glb_split(buf, len, &json, &jl, bin, bin_len, &err) != MCF_OK)
        fail_msg("not a GLB: %s", err.msg);
    j = cJSON_ParseWithLength(json, jl);
    assert_non_null(j);
    return j;
}

static cJSON *item(const cJSON *root, const char *arr, int i)
{
    return cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, arr), i);
}

static int num(const cJSON *o, const char *k)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(x) ? x->valueint : 0;
}

/* ------------------------------------------------------------------ tests */

static void test_detect_and_names(void **state)
{
    size_t n1, n2;
    char *glb = data_file("gltf/sphere_2prims.glb", &n1);
    char *gltf = data_file("gltf/sphere_2prims.gltf", &n2);
    (void)state;
    assert_int_equal(api_format_detect(glb, n1), API_FMT_GLB);
    assert_int_equal(api_format_detect(gltf, n2), API_FMT_GLTF);
    assert_int_equal(api_format_from_name("scan.glb"), API_FMT_GLB);
    assert_int_equal(api_format_from_name("gltf"), API_FMT_GLTF);
    assert_string_equal(api_format_mime(API_FMT_GLB), "model/gltf-binary");
    assert_string_equal(api_format_mime(API_FMT_GLTF), "model/gltf+json");
    assert_string_equal(api_format_ext(API_FMT_GLTF), ".gltf");
    assert_int_equal(api_format_detect("{\"x\":1}", 7), API_FMT_UNKNOWN);
    free(glb);
    free(gltf);
}

/* Two primitives with their own copies of the equator: one surface. */
static void test_weld_and_rewrite(void **state)
{
    size_t len, olen, blen, oblen;
    char *in = data_file("gltf/sphere_2prims.glb", &len), *out;
    const unsigned char *bin, *obin;
    mcf_mesh *m, *m2;
    api_attrs *a, *a2;
    cJSON *j, *oj;
    double *VN;
    const double *X, *X2;
    int nv, i, k, p;
    unsigned char *mask;
    (void)state;

    decode(in, len, &m, &a);
    nv = mcf_mesh_nvertices(m);
    assert_int_equal(nv, 812);           /* 866 glTF vertices, welded */
    assert_int_equal(mcf_mesh_nfaces(m), 1620);
    assert_true(api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, NULL, NULL));
    tl_smooth_a_little(m);
    out = encode(m, a, API_FMT_GLB, &olen);

    /* read back: the same 812 vertices at the smoothed positions */
    decode(out, olen, &m2, &a2);
    assert_int_equal(mcf_mesh_nvertices(m2), 812);
    X = mcf_mesh_positions(m);
    X2 = mcf_mesh_positions(m2);
    for (i = 0; i < 3 * nv; i++)
        assert_true(X2[i] == (double)(float)X[i]);

    /* every byte but POSITION and NORMAL values the same; those changed */
    j = glb_parts(in, len, &bin, &blen);
    oj = glb_parts(out, olen, &obin, &oblen);
    assert_int_equal(blen, oblen);
    mask = calloc(blen, 1);
    assert_non_null(mask);
    VN = malloc(sizeof *VN * 3 * (size_t)nv);
    assert_non_null(VN);
    api__vertex_normals(m, VN);
    for (p = 0; p < 2; p++) {
        const cJSON *prim = cJSON_GetArrayItem(
            cJSON_GetObjectItemCaseSensitive(item(j, "meshes", 0), "primitives"), p == 0 ? 0 : 2);
        const cJSON *at = cJSON_GetObjectItemCaseSensitive(prim, "attributes");
        int pa = num(at, "POSITION"), na = num(at, "NORMAL");
        const cJSON *acc = item(oj, "accessors", pa);
        const cJSON *view = item(j, "bufferViews", num(acc, "bufferView"));
        int stride = num(view, "byteStride") ? num(view, "byteStride") : 12;
        int off = num(view, "byteOffset") + num(acc, "byteOffset"), cnt = num(acc, "count");
        const cJSON *nacc = item(j, "accessors", na);
        const cJSON *nview = item(j, "bufferViews", num(nacc, "bufferView"));
        int nstride = num(nview, "byteStride") ? num(nview, "byteStride") : 12;
        int noff = num(nview, "byteOffset") + num(nacc, "byteOffset");
        double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
        for (i = 0; i < cnt; i++) {
            float x[3], n[3], ni[3];
            memset(mask + off + stride * i, 1, 12);
            memset(mask + noff + nstride * i, 1, 12);
            memcpy(x, obin + off + stride * i, 12);
            memcpy(n, obin + noff + nstride * i, 12);
            memcpy(ni, bin + noff + nstride * i, 12);
            for (k = 0; k < 3; k++) {
                lo[k] = fmin(lo[k], x[k]);
                hi[k] = fmax(hi[k], x[k]);
            }
            /* the normal: the smoothed surface's at that (welded) vertex,
             * as the input shared one normal across the seam; find the
             * vertex by its position */
            {
                int v;
                for (v = 0; v < nv; v++)
                    if ((float)X[3 * v] == x[0] && (float)X[3 * v + 1] == x[1] &&
                        (float)X[3 * v + 2] == x[2])
                        break;
                assert_true(v < nv);
                for (k = 0; k < 3; k++)
                    tl_assert_near(n[k], VN[3 * v + k], 1e-6, "recomputed normal");
                (void)ni;
            }
        }
        /* POSITION's min and max are the written values' */
        for (k = 0; k < 3; k++) {
            assert_true(cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(acc, "min"), k)->valuedouble == lo[k]);
            assert_true(cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(acc, "max"), k)->valuedouble == hi[k]);
        }
    }
    for (i = 0; i < (int)blen; i++)
        if (!mask[i] && bin[i] != obin[i])
            fail_msg("byte %d of the BIN chunk (not a position or normal) changed", i);
    /* the JSON: nodes, materials, cameras, images, extras, the LINES
     * primitive as they were */
    {
        static const char *const same[] = {"nodes", "materials", "cameras", "images",
                                           "extras", "scenes", "bufferViews", NULL};
        for (i = 0; same[i]; i++)
            assert_true(cJSON_Compare(cJSON_GetObjectItemCaseSensitive(j, same[i]),
                                      cJSON_GetObjectItemCaseSensitive(oj, same[i]), 1));
        assert_true(cJSON_Compare(cJSON_GetObjectItemCaseSensitive(item(j, "meshes", 0), "primitives"),
                                  cJSON_GetObjectItemCaseSensitive(item(oj, "meshes", 0), "primitives"), 1));
    }
    tl_assimp_reads(out, olen, "weld.glb", 966, 1670); /* assimp: lines count as faces */
    cJSON_Delete(j);
    cJSON_Delete(oj);
    free(mask);
    free(VN);
    free(in);
    free(out);
    mcf_mesh_free(m);
    mcf_mesh_free(m2);
    api_attrs_free(a);
    api_attrs_free(a2);
}

/* .gltf in: .gltf out with a data: URI, and the containers convert. */
static void test_containers(void **state)
{
    size_t len, l1, l2, l3;
    char *in = data_file("gltf/sphere_2prims.gltf", &len), *o1, *o2, *o3;
    mcf_mesh *m, *m1, *m3;
    api_attrs *a, *a1;
    cJSON *j;
    int i;
    (void)state;
    decode(in, len, &m, &a);
    tl_smooth_a_little(m);
    o1 = encode(m, a, API_FMT_GLTF, &l1);
    assert_int_equal(api_format_detect(o1, l1), API_FMT_GLTF);
    j = cJSON_ParseWithLength(o1, l1);
    assert_non_null(j);
    assert_non_null(strstr(cJSON_GetObjectItemCaseSensitive(item(j, "buffers", 0), "uri")->valuestring,
                           "data:application/octet-stream;base64,"));
    cJSON_Delete(j);
    o2 = encode(m, a, API_FMT_GLB, &l2);
    assert_int_equal(api_format_detect(o2, l2), API_FMT_GLB);
    decode(o1, l1, &m1, &a1);
    o3 = encode(m1, a1, API_FMT_GLB, &l3); /* gltf -> glb from a decoded gltf */
    assert_int_equal(l2, l3); /* the same document (normals differ by rounding) */
    decode(o3, l3, &m3, NULL);
    for (i = 0; i < 3 * mcf_mesh_nvertices(m); i++)
        assert_true(mcf_mesh_positions(m3)[i] == (double)(float)mcf_mesh_positions(m)[i]);
    tl_assimp_reads(o1, l1, "c.gltf", 866, 1620);
    tl_assimp_reads(o2, l2, "c.glb", 866, 1620);
    free(in);
    free(o1);
    free(o2);
    free(o3);
    mcf_mesh_free(m);
    mcf_mesh_free(m1);
    mcf_mesh_free(m3);
    api_attrs_free(a);
    api_attrs_free(a1);
}

/* Draco in, Draco out: car.drc as a KHR_draco_mesh_compression GLB. */
static void test_draco(void **state)
{
    size_t len, l1, l2;
    char *drc, *g1, *g2;
    mcf_mesh *m0, *m1, *m2;
    api_attrs *a0, *a1, *a2;
    int i;
    (void)state;
    drc = data_file("meshes/car.drc", &len);
    decode(drc, len, &m0, &a0);
    g1 = encode(m0, a0, API_FMT_GLB, &l1);
    assert_non_null(strstr(g1 + 20, "KHR_draco_mesh_compression"));
    assert_true(l1 < len + 2048); /* still compressed */
    decode(g1, l1, &m1, &a1);
    assert_int_equal(mcf_mesh_nvertices(m1), mcf_mesh_nvertices(m0));
    assert_int_equal(mcf_mesh_nfaces(m1), mcf_mesh_nfaces(m0));
    assert_int_equal(api_attrs_draco_bits(a1, API_ATTR_POSITION),
                     api_attrs_draco_bits(a0, API_ATTR_POSITION));
    tl_assimp_reads(g1, l1, "car.glb", 0, mcf_mesh_nfaces(m0));

    /* smoothed and rewritten: Draco again, UVs bit for bit */
    tl_smooth_a_little(m1);
    g2 = encode(m1, a1, API_FMT_GLB, &l2);
    assert_non_null(strstr(g2 + 20, "\"KHR_draco_mesh_compression\":{\"bufferView\""));
    decode(g2, l2, &m2, &a2);
    assert_int_equal(mcf_mesh_nvertices(m2), mcf_mesh_nvertices(m1));
    {
        /* the UV values are on the input's grid: every value of the output
         * is a value of the input */
        const double *v1, *v2;
        int n1, n2, j;
        assert_true(api_attrs_get(a1, API_ATTR_TEXCOORD, NULL, &n1, &v1, NULL));
        assert_true(api_attrs_get(a2, API_ATTR_TEXCOORD, NULL, &n2, &v2, NULL));
        for (i = 0; i < n2; i++) {
            for (j = 0; j < n1; j++)
                if (v1[2 * j] == v2[2 * i] && v1[2 * j + 1] == v2[2 * i + 1])
                    break;
            if (j == n1)
                fail_msg("texcoord %d (%g, %g) is not one of the input's", i, v2[2 * i],
                         v2[2 * i + 1]);
        }
    }
    /* positions: within the quantization step of the smoothed ones */
    {
        double lo = HUGE_VAL, hi = -HUGE_VAL, step;
        const double *X1 = mcf_mesh_positions(m1);
        for (i = 0; i < 3 * mcf_mesh_nvertices(m1); i++) {
            lo = fmin(lo, X1[i]);
            hi = fmax(hi, X1[i]);
        }
        step = (hi - lo) / ((1 << api_attrs_draco_bits(a1, API_ATTR_POSITION)) - 1);
        for (i = 0; i < 3 * mcf_mesh_nvertices(m1); i += 3) {
            int v, best = -1;
            double d = HUGE_VAL;
            for (v = 0; v < mcf_mesh_nvertices(m2); v++) {
                const double *y = mcf_mesh_positions(m2) + 3 * v;
                double e = fmax(fabs(y[0] - X1[i]), fmax(fabs(y[1] - X1[i + 1]), fabs(y[2] - X1[i + 2])));
                if (e < d) {
                    d = e;
                    best = v;
                }
            }
            assert_true(best >= 0);
            if (d > step)
                fail_msg("vertex %d moved %g by the re-encode (step %g)", i / 3, d, step);
        }
    }
    tl_assimp_reads(g2, l2, "car_s.glb", 0, mcf_mesh_nfaces(m0));
    free(drc);
    free(g1);
    free(g2);
    mcf_mesh_free(m0);
    mcf_mesh_free(m1);
    mcf_mesh_free(m2);
    api_attrs_free(a0);
    api_attrs_free(a1);
    api_attrs_free(a2);
}

/* A GLB around a stream written by Draco's own tools (bunny.drc, v1.x,
 * POSITION as attribute 0), as a third-party exporter would wrap it. */
static char *wrap_drc(const char *drc, size_t n, int npoints, int nfaces, size_t *len)
{
    char json[1024], *g;
    size_t jl, jp, bp = (n + 3) / 4 * 4;
    snprintf(json, sizeof json,
             "{\"asset\":{\"version\":\"2.0\",\"generator\":\"hand\"},"
             "\"extensionsUsed\":[\"KHR_draco_mesh_compression\"],"
             "\"extensionsRequired\":[\"KHR_draco_mesh_compression\"],"
             "\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,"
             "\"extensions\":{\"KHR_draco_mesh_compression\":{\"bufferView\":0,"
             "\"attributes\":{\"POSITION\":0}}}}]}],"
             "\"accessors\":[{\"componentType\":5126,\"count\":%d,\"type\":\"VEC3\","
             "\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
             "{\"componentType\":5125,\"count\":%d,\"type\":\"SCALAR\"}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu}],"
             "\"buffers\":[{\"byteLength\":%zu}]}",
             npoints, 3 * nfaces, n, bp);
    jl = strlen(json);
    jp = (jl + 3) / 4 * 4;
    *len = 28 + jp + bp;
    g = calloc(*len, 1);
    assert_non_null(g);
    memcpy(g, "glTF", 4);
    api__put_le32((unsigned char *)g + 4, 2);
    api__put_le32((unsigned char *)g + 8, (uint32_t)*len);
    api__put_le32((unsigned char *)g + 12, (uint32_t)jp);
    api__put_le32((unsigned char *)g + 16, 0x4E4F534Au);
    memcpy(g + 20, json, jl);
    memset(g + 20 + jl, ' ', jp - jl);
    api__put_le32((unsigned char *)g + 20 + jp, (uint32_t)bp);
    api__put_le32((unsigned char *)g + 24 + jp, 0x004E4942u);
    memcpy(g + 28 + jp, drc, n);
    return g;
}

static void test_foreign_draco(void **state)
{
    size_t len, gl, ol;
    char *drc = data_file("meshes/bunny.drc", &len), *g, *o;
    mcf_mesh *m0, *m;
    api_attrs *a;
    (void)state;
    decode(drc, len, &m0, NULL);
    g = wrap_drc(drc, len, mcf_mesh_nvertices(m0), mcf_mesh_nfaces(m0), &gl);
    decode(g, gl, &m, &a);
    assert_int_equal(mcf_mesh_nvertices(m), mcf_mesh_nvertices(m0));
    assert_int_equal(mcf_mesh_nfaces(m), mcf_mesh_nfaces(m0));
    tl_smooth_a_little(m);
    o = encode(m, a, API_FMT_GLB, &ol);
    /* assimp counts Draco's points: the re-encode splits a few more */
    tl_assimp_reads(o, ol, "bunny_s.glb", 0, mcf_mesh_nfaces(m0));
    free(drc);
    free(g);
    free(o);
    mcf_mesh_free(m0);
    mcf_mesh_free(m);
    api_attrs_free(a);
}

/* Any other format: a new document that reads back. */
static void test_new_document(void **state)
{
    size_t len, ol;
    char *obj = data_file("meshes/sphere_cgal.obj", &len), *o;
    mcf_mesh *m, *m2;
    api_attrs *a;
    int i;
    (void)state;
    decode(obj, len, &m, &a);
    o = encode(m, a, API_FMT_GLB, &ol);
    decode(o, ol, &m2, NULL);
    assert_int_equal(mcf_mesh_nvertices(m2), mcf_mesh_nvertices(m));
    for (i = 0; i < 3 * mcf_mesh_nvertices(m); i++)
        assert_true(mcf_mesh_positions(m2)[i] == (double)(float)mcf_mesh_positions(m)[i]);
    assert_memory_equal(mcf_mesh_faces(m2), mcf_mesh_faces(m), 12 * (size_t)mcf_mesh_nfaces(m));
    tl_assimp_reads(o, ol, "new.glb", 812, 1620);
    free(obj);
    free(o);
    mcf_mesh_free(m);
    mcf_mesh_free(m2);
    api_attrs_free(a);
}

/* ------------------------------------------------------------- hostile */

/* A one-triangle .gltf whose parts can be replaced: %s are the accessors,
 * the buffer views and the buffers. */
static const char TRI_BUF[] =
    "data:application/octet-stream;base64,"
    "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA=";

static mcf_status try_doc(const char *doc, mcf_error *err)
{
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    mcf_status rc = api_mesh_decode_attrs(doc, strlen(doc), NULL, &m, &a, NULL, err);
    mcf_mesh_free(m);
    api_attrs_free(a);
    return rc;
}

static void expect(const char *doc, const char *want)
{
    mcf_error err = {MCF_OK, ""};
    mcf_status rc = try_doc(doc, &err);
    if (rc == MCF_OK || !strstr(err.msg, want))
        fail_msg("expected an error with '%s', got %s: %s\n  in %.300s", want,
                 mcf_status_name(rc), err.msg, doc);
}

static char *tri(const char *extra_root, const char *accessors, const char *views,
                 const char *buffers)
{
    static char d[8192];
    snprintf(d, sizeof d,
             "{\"asset\":{\"version\":\"2.0\"}%s,"
             "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
             "\"accessors\":%s,\"bufferViews\":%s,\"buffers\":%s}",
             extra_root, accessors, views, buffers);
    return d;
}

#define ACC_OK "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"}," \
               "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]"
#define VIEWS_OK "[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,\"byteOffset\":36,\"byteLength\":6}]"

static void test_hostile(void **state)
{
    char buffers[512], deep[600], *doc;
    mcf_error err;
    int i;
    (void)state;
    snprintf(buffers, sizeof buffers, "[{\"byteLength\":44,\"uri\":\"%s\"}]", TRI_BUF);
    /* the base document decodes */
    assert_int_equal(try_doc(tri("", ACC_OK, VIEWS_OK, buffers), &err), MCF_OK);
    expect(tri("", ACC_OK, VIEWS_OK, "[{\"byteLength\":44,\"uri\":\"tri.bin\"}]"),
           "never opens a URI");
    expect(tri("", ACC_OK, VIEWS_OK, "[{\"byteLength\":44,\"uri\":\"/etc/passwd\"}]"),
           "'/etc/passwd'");
    expect(tri("", ACC_OK, VIEWS_OK, "[{\"byteLength\":44,\"uri\":\"http://x/y.bin\"}]"),
           "never opens a URI");
    expect(tri("", ACC_OK, "[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,\"byteOffset\":40,"
                           "\"byteLength\":6}]", buffers), "outside its buffer");
    expect(tri("", ACC_OK, "[{\"buffer\":1,\"byteLength\":36}]", buffers), "outside its buffer");
    expect(tri("", "[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
                   "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]",
               VIEWS_OK, buffers), "does not fit");
    expect(tri("", "[{\"bufferView\":0,\"componentType\":5121,\"count\":3,\"type\":\"VEC3\"},"
                   "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]",
               VIEWS_OK, buffers), "not one glTF allows");
    expect(tri("", "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
                   "\"sparse\":{\"count\":1,\"indices\":{\"bufferView\":1,\"componentType\":5123},"
                   "\"values\":{\"bufferView\":0}}},"
                   "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]",
               VIEWS_OK, buffers), "sparse");
    expect(tri("", "[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},"
                   "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\","
                   "\"byteOffset\":2}]",
               VIEWS_OK, buffers), "does not fit");
    expect(tri("", "[{\"bufferView\":0,\"componentType\":5126,\"count\":2000000000,"
                   "\"type\":\"VEC3\"},"
                   "{\"bufferView\":1,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]",
               VIEWS_OK, buffers), "elements");
    expect(tri(",\"extensionsUsed\":[\"KHR_mesh_quantization\"]", ACC_OK, VIEWS_OK, buffers),
           "KHR_mesh_quantization");
    expect(tri(",\"asset\":{\"version\":\"3.0\"}", ACC_OK, VIEWS_OK, buffers), "appears twice");
    doc = tri("", ACC_OK, VIEWS_OK, buffers);
    memcpy(strstr(doc, "\"2.0\""), "\"1.0\"", 5);
    expect(doc, "asset.version");
    /* nesting past 64 levels in extras */
    strcpy(deep, ",\"extras\":");
    for (i = 0; i < 100; i++)
        strcat(deep, "[");
    for (i = 0; i < 100; i++)
        strcat(deep, "]");
    expect(tri(deep, ACC_OK, VIEWS_OK, buffers), "nested deeper");
    expect("{\"asset\":{\"version\":\"2.0\"},\"meshes\":[]}", "no triangle primitive");
    expect("{\"asset\":{\"version\":\"2.0\"}, \"meshes\": [", "malformed JSON");
    /* a Draco primitive mapping NORMAL and POSITION to one stream
     * attribute (fuzz_gltf's find, 2026-11-29, its seed in
     * tests/fuzz/corpus_gltf/draco_shared_attribute.glb): decoded, its
     * rewrite's positions were the normals */
    {
        size_t len = 0;
        char *buf = data_file("../fuzz/corpus_gltf/draco_shared_attribute.glb", &len);
        mcf_mesh *m = NULL;
        assert_int_not_equal(api_mesh_decode_attrs(buf, len, NULL, &m, NULL, NULL, &err), MCF_OK);
        assert_non_null(strstr(err.msg, "name the same Draco attribute 0"));
        mcf_mesh_free(m);
        free(buf);
    }
    /* an index past the vertices: the indices 0 1 2 become 0 1 7 */
    {
        char b2[512];
        snprintf(b2, sizeof b2, "[{\"byteLength\":44,\"uri\":\"%s\"}]", TRI_BUF);
        memcpy(strstr(b2, "ABAAIAAAA="), "ABAAcAAAA=", 10);
        expect(tri("", ACC_OK, VIEWS_OK, b2), "past its 3 vertices");
    }
}

/* Draco primitives whose quantization grid the rewrite cannot keep (fuzz
 * seeds, found by fuzz_gltf on 2026-11-29): a grid at the float32
 * resolution of its values (origin (-1, -1, 3.5e-37), range 8e-15, 11
 * bits), and a 7-bit grid its decoded values lie far outside, with points
 * 6e-17 apart. Each rewrite as GLB must decode to the same vertices and
 * faces: no two points may fall on one point of the new grid (the reader
 * welds them and drops their triangles; both came back with every
 * triangle degenerate). */
static void test_draco_grids_rewrite(void **state)
{
    static const char *const seeds[] = {"draco_grid_below_resolution.gltf",
                                        "draco_grid_off_values.gltf"};
    (void)state;
    for (size_t i = 0; i < sizeof seeds / sizeof *seeds; i++) {
        char rel[128];
        size_t len = 0;
        mcf_mesh *m = NULL, *m2 = NULL;
        api_attrs *a = NULL;
        api_encode_opts o;
        api_buf out;
        mcf_error err;
        char *buf;
        snprintf(rel, sizeof rel, "../fuzz/corpus_gltf/%s", seeds[i]);
        buf = data_file(rel, &len);
        assert_int_equal(api_gltf_decode_attrs(buf, len, NULL, &m, &a, &err), MCF_OK);
        api_encode_opts_init(&o);
        o.format = API_FMT_GLB;
        o.attrs = a;
        api_buf_init(&out, (size_t)-1);
        assert_int_equal(api_mesh_encode(m, &o, &out, &err), MCF_OK);
        if (api_gltf_decode_attrs(out.data, out.len, NULL, &m2, NULL, &err) != MCF_OK)
            fail_msg("%s: the rewrite does not decode: %s", seeds[i], err.msg);
        assert_int_equal(mcf_mesh_nvertices(m2), mcf_mesh_nvertices(m));
        assert_int_equal(mcf_mesh_nfaces(m2), mcf_mesh_nfaces(m));
        mcf_mesh_free(m);
        mcf_mesh_free(m2);
        api_attrs_free(a);
        api_buf_free(&out);
        free(buf);
    }
}

/* Every truncation and many corruptions of a real GLB: an error or a
 * mesh, never a crash (the sanitizer build watches). */
static void test_truncated_and_corrupted(void **state)
{
    size_t len, n;
    char *in = data_file("gltf/sphere_2prims.glb", &len), *c;
    mcf_error err;
    (void)state;
    for (n = 0; n < len; n += n < 2000 ? 7 : 997) {
        mcf_mesh *m = NULL;
        assert_int_not_equal(api_mesh_decode(in, n, NULL, &m, NULL, &err), MCF_OK);
        mcf_mesh_free(m);
    }
    c = malloc(len);
    assert_non_null(c);
    for (n = 8; n < 2000 && n < len; n += 13) {
        mcf_mesh *m = NULL;
        memcpy(c, in, len);
        c[n] ^= 0x5a;
        api_mesh_decode(c, len, NULL, &m, NULL, &err);
        mcf_mesh_free(m);
    }
    free(c);
    free(in);
}

/* What the daemon sizes and where it decodes. */
static void test_estimate_and_record(void **state)
{
    size_t len, l1, l2, l3;
    char *drc = data_file("meshes/car.drc", &len), *g, *o1, *o2;
    mcf_mesh *m, *m2, *m3;
    api_attrs *a, *a2, *a3 = NULL;
    api_mem_estimate e;
    api_buf pack;
    mcf_error err;
    api_limits lim;
    (void)state;
    decode(drc, len, &m, &a);
    g = encode(m, a, API_FMT_GLB, &l1);
    api_estimate_memory(g, l1, NULL, &e);
    assert_int_equal(e.format, API_FMT_GLB);
    assert_int_equal(e.draco, 1);
    assert_true(e.faces == mcf_mesh_nfaces(m));
    free(drc);
    drc = data_file("gltf/sphere_2prims.gltf", &len);
    api_estimate_memory(drc, len, NULL, &e);
    assert_int_equal(e.draco, 0);
    assert_int_equal(e.vertices, 866);
    assert_int_equal(e.faces, 1620);

    /* through the sandbox's record: the same output */
    decode(g, l1, &m2, &a2);
    api_buf_init(&pack, 0);
    assert_int_equal(api_mesh_pack(m2, a2, &pack, &err), MCF_OK);
    api_limits_default(&lim);
    assert_int_equal(api_mesh_unpack(pack.data, pack.len, &lim, &m3, &a3, &err), MCF_OK);
    o1 = encode(m2, a2, API_FMT_GLB, &l2);
    o2 = encode(m3, a3, API_FMT_GLB, &l3);
    assert_int_equal(l2, l3);
    assert_memory_equal(o1, o2, l2);
    /* a corrupt record is refused, not trusted */
    a3->gltf[20] ^= 0x7f;
    {
        api_buf b;
        api_encode_opts o;
        api_encode_opts_init(&o);
        o.format = API_FMT_GLB;
        o.attrs = a3;
        api_buf_init(&b, 0);
        /* either refused or a document: never a crash */
        api_mesh_encode(m3, &o, &b, &err);
        api_buf_free(&b);
    }
    api_buf_free(&pack);
    free(drc);
    free(g);
    free(o1);
    free(o2);
    mcf_mesh_free(m);
    mcf_mesh_free(m2);
    mcf_mesh_free(m3);
    api_attrs_free(a);
    api_attrs_free(a2);
    api_attrs_free(a3);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_detect_and_names),
        cmocka_unit_test(test_weld_and_rewrite),
        cmocka_unit_test(test_containers),
        cmocka_unit_test(test_draco),
        cmocka_unit_test(test_foreign_draco),
        cmocka_unit_test(test_draco_grids_rewrite),
        cmocka_unit_test(test_new_document),
        cmocka_unit_test(test_hostile),
        cmocka_unit_test(test_truncated_and_corrupted),
        cmocka_unit_test(test_estimate_and_record),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
