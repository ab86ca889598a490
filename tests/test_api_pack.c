/* SPDX-License-Identifier: MIT */
/*
 * test_api_pack.c - the decode sandbox's record (api_pack.c) and the
 * memory estimate (api_estimate.c).
 *
 * Pack: car.drc (texcoords, normals, a quantization grid) and bunny.drc
 * and knot1.obj come back bit for bit, attributes included, and encode to the same
 * Draco bytes as the meshes they were packed from; a truncated, extended
 * or lying record is EDECODE at every length, never a bad mesh.
 * Estimate: the counts each format declares (Draco header, PLY header,
 * OFF header, binary STL, OBJ lines with polygons split) and the model's
 * order (explicit schemes cheaper, a target costs more).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

static char *read_mesh(const char *name, size_t *len)
{
    char *buf = NULL;
    assert_int_equal(tl_read_file(tl_need_mesh(name), &buf, len), 0);
    return buf;
}

/* Encodes m with attrs as Draco under the default options. */
static void encode(const mcf_mesh *m, const api_attrs *a, api_buf *out)
{
    api_encode_opts o;
    mcf_error err = {MCF_OK, ""};
    api_encode_opts_init(&o);
    o.format = API_FMT_DRACO;
    o.attrs = a;
    api_buf_init(out, (size_t)1 << 30);
    assert_int_equal(api_draco_encode(m, &o, out, NULL, &err), MCF_OK);
}

static void roundtrip(const char *name)
{
    size_t len;
    char *buf = read_mesh(name, &len);
    api_limits lim;
    mcf_mesh *m = NULL, *m2 = NULL;
    api_attrs *a = NULL, *a2 = NULL;
    mcf_error err = {MCF_OK, ""};
    api_buf rec, e1, e2;
    size_t cut;
    int k;

    api_limits_default(&lim);
    assert_int_equal(api_mesh_decode_attrs(buf, len, &lim, &m, &a, NULL, &err),
                     MCF_OK);
    api_buf_init(&rec, (size_t)1 << 30);
    assert_int_equal(api_mesh_pack(m, a, &rec, &err), MCF_OK);
    assert_int_equal(api_mesh_unpack(rec.data, rec.len, &lim, &m2, &a2, &err),
                     MCF_OK);
    assert_int_equal(mcf_mesh_nvertices(m2), mcf_mesh_nvertices(m));
    assert_int_equal(mcf_mesh_nfaces(m2), mcf_mesh_nfaces(m));
    assert_memory_equal(mcf_mesh_positions(m2), mcf_mesh_positions(m),
                        3 * sizeof(double) * (size_t)mcf_mesh_nvertices(m));
    assert_memory_equal(mcf_mesh_faces(m2), mcf_mesh_faces(m),
                        3 * sizeof(int32_t) * (size_t)mcf_mesh_nfaces(m));
    assert_int_equal(api_attrs_float32(a2), api_attrs_float32(a));
    for (k = 0; k <= API_ATTR_KINDS; k++)
        assert_int_equal(api_attrs_draco_bits(a2, k), api_attrs_draco_bits(a, k));
    for (k = 0; k < API_ATTR_KINDS; k++) {
        int n1 = 0, c1 = 0, n2 = 0, c2 = 0;
        const double *v1, *v2;
        const int32_t *i1, *i2;
        int h1 = api_attrs_get(a, (api_attr_kind)k, &c1, &n1, &v1, &i1);
        int h2 = api_attrs_get(a2, (api_attr_kind)k, &c2, &n2, &v2, &i2);
        assert_int_equal(h1, h2);
        if (!h1)
            continue;
        assert_int_equal(c1, c2);
        assert_int_equal(n1, n2);
        assert_memory_equal(v1, v2, sizeof(double) * (size_t)c1 * (size_t)n1);
        assert_memory_equal(i1, i2, 3 * sizeof(int32_t) *
                                        (size_t)mcf_mesh_nfaces(m));
    }
    /* the same Draco bytes out: quantization grids travel too */
    encode(m, a, &e1);
    encode(m2, a2, &e2);
    assert_int_equal(e1.len, e2.len);
    assert_memory_equal(e1.data, e2.data, e1.len);
    api_buf_free(&e1);
    api_buf_free(&e2);
    mcf_mesh_free(m2);
    api_attrs_free(a2);
    /* every truncation, and one byte too many, is refused */
    for (cut = 0; cut < rec.len; cut += cut < 64 ? 1 : rec.len / 97 + 1) {
        m2 = NULL;
        assert_int_equal(api_mesh_unpack(rec.data, cut, &lim, &m2, &a2, &err),
                         MCF_EDECODE);
        assert_null(m2);
    }
    assert_int_equal(api_buf_append(&rec, "x", 1), MCF_OK);
    assert_int_equal(api_mesh_unpack(rec.data, rec.len, &lim, &m2, &a2, &err),
                     MCF_EDECODE);
    assert_non_null(strstr(err.msg, "after the record"));
    /* a vertex count over the limit is refused before any allocation */
    lim.max_vertices = mcf_mesh_nvertices(m) - 1;
    assert_int_equal(api_mesh_unpack(rec.data, rec.len - 1, &lim, &m2, &a2, &err),
                     MCF_EDECODE);
    api_buf_free(&rec);
    mcf_mesh_free(m);
    api_attrs_free(a);
    free(buf);
}

static void test_pack_roundtrip(void **state)
{
    (void)state;
    roundtrip("car.drc");
    roundtrip("bunny.drc");
    roundtrip("knot1.obj");
}

/* A corner index out of range in a record is caught by api_attrs' checks. */
static void test_pack_bad_index(void **state)
{
    size_t len;
    char *buf = read_mesh("car.drc", &len);
    api_limits lim;
    mcf_mesh *m = NULL, *m2 = NULL;
    api_attrs *a = NULL, *a2 = NULL;
    mcf_error err = {MCF_OK, ""};
    api_buf rec;
    int32_t bad = 0x7fffffff;

    (void)state;
    api_limits_default(&lim);
    assert_int_equal(api_mesh_decode_attrs(buf, len, &lim, &m, &a, NULL, &err),
                     MCF_OK);
    api_buf_init(&rec, (size_t)1 << 30);
    assert_int_equal(api_mesh_pack(m, a, &rec, &err), MCF_OK);
    /* the last 4 bytes are the last corner index of the last attribute */
    memcpy(rec.data + rec.len - 4, &bad, 4);
    assert_int_not_equal(api_mesh_unpack(rec.data, rec.len, &lim, &m2, &a2, &err),
                         MCF_OK);
    assert_null(m2);
    api_buf_free(&rec);
    mcf_mesh_free(m);
    api_attrs_free(a);
    free(buf);
}

static void test_estimate_counts(void **state)
{
    static const char obj[] = "v 0 0 0\nv 1 0 0\nv 1 1 0\n v 0 1 0\n"
                              "vt 0 0\nvn 0 0 1\nf 1 2 3 4\nf 1/1 2/1 3/1\n";
    static const char ply[] = "ply\nformat ascii 1.0\nelement vertex 4\n"
                              "property float x\nproperty float y\n"
                              "property float z\nelement face 2\n"
                              "property list uchar int vertex_indices\n"
                              "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
                              "3 0 1 2\n3 0 2 3\n";
    static const char off[] = "# c\nOFF\n# more\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n"
                              "0 1 0\n3 0 1 2\n3 0 2 3\n";
    api_mem_estimate e;
    size_t len;
    double d2;
    char *buf;
    api_params p;
    api_limits lim;

    (void)state;
    api_estimate_memory(obj, sizeof obj - 1, NULL, &e);
    assert_int_equal(e.format, API_FMT_OBJ);
    assert_int_equal(e.vertices, 4);
    assert_int_equal(e.faces, 3); /* the quad is two triangles */
    api_estimate_memory(ply, sizeof ply - 1, NULL, &e);
    assert_int_equal(e.format, API_FMT_PLY);
    assert_int_equal(e.vertices, 4);
    assert_int_equal(e.faces, 2);
    api_estimate_memory(off, sizeof off - 1, NULL, &e);
    assert_int_equal(e.format, API_FMT_OFF);
    assert_int_equal(e.vertices, 4);
    assert_int_equal(e.faces, 2);
    buf = read_mesh("bunny.drc", &len);
    api_estimate_memory(buf, len, NULL, &e);
    assert_int_equal(e.format, API_FMT_DRACO);
    assert_int_equal(e.vertices, 34834);
    assert_int_equal(e.faces, 69451);
    /* the default request: fairing, 2,900 B per vertex (api_estimate.c) */
    tl_assert_near(e.job_bytes / 1048576.0, 100.6, 0.1, "bunny.drc estimate");
    api_params_init(&p);
    api_limits_default(&lim);
    /* the README's figure: 57.5 MiB for bunny.drc, desbrun2 */
    assert_int_equal(api_params_set(&p, "scheme", "desbrun2", &lim, NULL), MCF_OK);
    d2 = api_estimate_job_bytes(e.vertices, e.faces, len, &p);
    tl_assert_near(d2 / 1048576.0, 57.5, 0.1, "bunny.drc estimate, desbrun2");
    assert_int_equal(api_params_set(&p, "scheme", "euler", &lim, NULL), MCF_OK);
    /* euler's automatic amount (no amount named) factorizes: desbrun2's
     * charge; with an amount it factorizes nothing */
    tl_assert_near(api_estimate_job_bytes(e.vertices, e.faces, len, &p), d2, 1.0,
                   "euler with the automatic amount");
    assert_int_equal(api_params_set(&p, "strength", "0.33", &lim, NULL), MCF_OK);
    assert_true(api_estimate_job_bytes(e.vertices, e.faces, len, &p) < d2 / 2);
    api_params_free(&p);
    free(buf);
    buf = read_mesh("knot1.obj", &len);
    api_estimate_memory(buf, len, NULL, &e);
    assert_int_equal(e.vertices, 3200);
    assert_int_equal(e.faces, 6400);
    free(buf);
    /* a binary STL of a closed scan declares a vertex per facet: 300,000
     * facets weld to about 150,000 vertices, where the default request
     * runs the implicit filter (api_default_scheme): charged for it, not
     * for the explicit one on 300,000 (183 MiB before) */
    assert_int_equal(api_default_scheme(150000), MCF_FAIRING);
    assert_int_equal(api_default_scheme(300000), MCF_FAIRING_EXPLICIT);
    assert_true(api_estimate_job_bytes(300000, 300000, 0, NULL) >= 2900.0 * 150000);
    /* declared vertices that are the mesh's own (nf ~ 2 nv): unchanged */
    tl_assert_near(api_estimate_job_bytes(300000, 600000, 0, NULL), 640.0 * 300000 + 4.0 * 1048576, 1.0,
                   "explicit default on 300,000 vertices");
    /* nothing declared: the size term only */
    api_estimate_memory("garbage", 7, NULL, &e);
    assert_int_equal(e.faces, 0);
    assert_true(e.job_bytes > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pack_roundtrip),
        cmocka_unit_test(test_pack_bad_index),
        cmocka_unit_test(test_estimate_counts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
