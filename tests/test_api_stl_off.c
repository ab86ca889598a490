/* SPDX-License-Identifier: MIT */
/*
 * test_api_stl_off.c - the STL (api_stl.c) and OFF (api_off.c) codecs.
 *
 * STL: welding by exact position rebuilds the connectivity of closed
 * meshes (same V, F, closed, manifold, genus as the source), of car.drc
 * (920 distinct positions, as SOURCES.md counts), keeps degenerate welded
 * faces, merges -0 with +0; binary files whose header starts with "solid"
 * are binary; ASCII variants (several solids, one line, CRLF, polygons).
 * OFF: exact round trips, header/comment/colour variants, polygons.
 * Both: hostile input (truncation at every offset, wrong counts, bad
 * indices, NaN, huge counts over tiny bodies, garbage, empty) fails with
 * the message checked here.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

static mcf_status dec(tl_decoder fn, const void *buf, size_t len, mcf_mesh **m,
                      mcf_error *err)
{
    api_limits lim;
    api_limits_default(&lim);
    return tl_decode_copy(fn, buf, len, &lim, m, err);
}

static void expect_fail_lim(tl_decoder fn, const void *buf, size_t len,
                            const api_limits *lim, mcf_status code,
                            const char *want)
{
    mcf_mesh *m = NULL;
    mcf_error err;
    mcf_status rc = tl_decode_copy(fn, buf, len, lim, &m, &err);
    if (rc != code || !strstr(err.msg, want))
        fail_msg("input \"%.40s\"... (%zu bytes): got %s \"%s\", want %s "
                 "containing \"%s\"",
                 (const char *)buf, len, mcf_status_name(rc), err.msg,
                 mcf_status_name(code), want);
    assert_null(m);
    assert_int_equal(err.status, code);
}

static void expect_fail(tl_decoder fn, const char *text, mcf_status code,
                        const char *want)
{
    api_limits lim;
    api_limits_default(&lim);
    expect_fail_lim(fn, text, strlen(text), &lim, code, want);
}

static void expect_ok(tl_decoder fn, const char *text, int nv, int nf,
                      const int32_t *faces)
{
    mcf_mesh *m;
    mcf_error err;
    if (dec(fn, text, strlen(text), &m, &err) != MCF_OK)
        fail_msg("input \"%.40s\"...: %s", text, err.msg);
    assert_int_equal(mcf_mesh_nvertices(m), nv);
    assert_int_equal(mcf_mesh_nfaces(m), nf);
    if (faces)
        assert_memory_equal(mcf_mesh_faces(m), faces, sizeof(int32_t) * 3 * (size_t)nf);
    mcf_mesh_free(m);
}

static api_buf encode(const mcf_mesh *m, api_format f, int binary)
{
    api_encode_opts o;
    api_buf b;
    mcf_error err;
    api_encode_opts_init(&o);
    o.format = f;
    o.stl_binary = binary;
    api_buf_init(&b, 0);
    if (api_mesh_encode(m, &o, &b, &err) != MCF_OK)
        fail_msg("encode %s: %s", api_format_name(f), err.msg);
    return b;
}

/* ================================================================== STL */

/* Welding gives back the source's connectivity: same counts and, face by
 * face, the same corner positions (exact in ASCII, float32 in binary). */
static void stl_roundtrip(const char *file, int binary)
{
    mcf_mesh *m = tl_load(file), *d = NULL;
    api_buf b = encode(m, API_FMT_STL, binary);
    mcf_mesh_info a, c;
    mcf_error err;
    api_format f;
    int i;
    if (api_mesh_decode(b.data, b.len, NULL, &d, &f, &err) != MCF_OK)
        fail_msg("%s: %s", file, err.msg);
    assert_int_equal(f, API_FMT_STL);
    assert_int_equal(mcf_mesh_nvertices(d), mcf_mesh_nvertices(m));
    assert_int_equal(mcf_mesh_nfaces(d), mcf_mesh_nfaces(m));
    for (i = 0; i < 3 * mcf_mesh_nfaces(m); i++) {
        const double *p = mcf_mesh_positions(d) + 3 * mcf_mesh_faces(d)[i];
        const double *q = mcf_mesh_positions(m) + 3 * mcf_mesh_faces(m)[i];
        int k;
        for (k = 0; k < 3; k++)
            if (p[k] != (binary ? (double)(float)q[k] : q[k]))
                fail_msg("%s corner %d: %.17g vs %.17g", file, i, p[k], q[k]);
    }
    assert_int_equal(mcf_mesh_inspect(m, &a, &err), MCF_OK);
    assert_int_equal(mcf_mesh_inspect(d, &c, &err), MCF_OK);
    assert_true(c.closed && c.manifold);
    assert_int_equal(c.components, 1);
    assert_int_equal(c.genus, a.genus);
    assert_int_equal(c.ne, a.ne);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
    api_buf_free(&b);
}

static void test_stl_roundtrip(void **state)
{
    (void)state;
    stl_roundtrip("sphere_cgal.obj", 1);
    stl_roundtrip("sphere_cgal.obj", 0);
    stl_roundtrip("knot1.obj", 1);       /* genus 1 */
    stl_roundtrip("knot1.obj", 0);
    stl_roundtrip("bunny_npm_closed.obj", 1);
}

/* The same on the large scans of $MCF_MESHES. */
static void test_stl_roundtrip_scans(void **state)
{
    (void)state;
    stl_roundtrip("fertility.obj", 1);   /* genus 4 */
    stl_roundtrip("fertility.obj", 0);
    stl_roundtrip("armadillo.obj", 1);
}

/* car.drc's 1,856 points hold 920 distinct positions (SOURCES.md). */
static void test_stl_weld_car(void **state)
{
    mcf_mesh *m = tl_load("car.drc"), *d;
    api_buf b = encode(m, API_FMT_STL, 1);
    mcf_error err;
    (void)state;
    assert_int_equal(dec(api_stl_decode, b.data, b.len, &d, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nvertices(d), 920);
    assert_int_equal(mcf_mesh_nfaces(d), 1744);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
    api_buf_free(&b);
}

/* Binary STL bytes for triangles given as 9 floats each. */
static api_buf stl_bin(const char *header, const float *tri, int n)
{
    api_buf b;
    unsigned char head[84], rec[50];
    uint32_t cnt = (uint32_t)n;
    int i, k;
    api_buf_init(&b, 0);
    memset(head, 0, sizeof head);
    memcpy(head, header, strlen(header) < 80 ? strlen(header) : 80);
    memcpy(head + 80, &cnt, 4); /* test hosts are little-endian */
    api_buf_append(&b, head, sizeof head);
    for (i = 0; i < n; i++) {
        memset(rec, 0, sizeof rec);
        for (k = 0; k < 9; k++)
            memcpy(rec + 12 + 4 * k, &tri[9 * i + k], 4);
        api_buf_append(&b, rec, sizeof rec);
    }
    return b;
}

static void test_stl_binary_cases(void **state)
{
    /* second triangle: two corners equal after welding; -0 meets +0 */
    static const float tri[] = {0, 0, 0, 1, 0, 0, 0, 1, 0,
                                -0.0f, 0, 0, 1, 0, 0, 0, 0, 0};
    static const int32_t want[] = {0, 1, 2, 0, 1, 0};
    float bad[18];
    api_buf b;
    mcf_mesh *m;
    mcf_mesh_info info;
    mcf_error err;
    api_limits lim;
    size_t cut;
    (void)state;

    /* a header beginning with "solid": still binary by the size rule */
    b = stl_bin("solid but binary", tri, 2);
    assert_int_equal(dec(api_stl_decode, b.data, b.len, &m, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nvertices(m), 3);
    assert_int_equal(mcf_mesh_nfaces(m), 2);
    assert_memory_equal(mcf_mesh_faces(m), want, sizeof want);
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_int_equal(info.degenerate_faces, 1);
    mcf_mesh_free(m);
    {
        mcf_mesh *d;
        api_format f;
        assert_int_equal(api_mesh_decode(b.data, b.len, NULL, &d, &f, &err), MCF_OK);
        assert_int_equal(f, API_FMT_STL);
        mcf_mesh_free(d);
    }
    /* every truncation: a size mismatch (or, "solid" + control bytes, the
     * same), or too short */
    for (cut = 0; cut < b.len; cut++) {
        mcf_status rc = dec(api_stl_decode, b.data, cut, &m, &err);
        /* "solid but binary" cut within its text looks like ASCII */
        const char *want_msg = cut == 0 ? "stl: empty input"
                               : (cut >= 5 && cut <= 16) ? "stl: line 1: input ends "
                                                           "inside solid 1"
                               : cut < 84 ? "neither ASCII ('solid') nor binary"
                                          : "stl: binary header announces 2 "
                                            "triangles (184 bytes) but the input has";
        if (rc != MCF_EDECODE || !strstr(err.msg, want_msg))
            fail_msg("cut %zu: %s \"%s\"", cut, mcf_status_name(rc), err.msg);
    }
    api_limits_default(&lim);
    lim.max_faces = 1;
    expect_fail_lim(api_stl_decode, b.data, b.len, &lim, MCF_ELIMIT,
                    "stl: 2 triangles exceed max_faces (1)");
    api_limits_default(&lim);
    lim.max_vertices = 2;
    expect_fail_lim(api_stl_decode, b.data, b.len, &lim, MCF_ELIMIT,
                    "stl: more than max_vertices (2) distinct vertices");
    api_buf_free(&b);

    memcpy(bad, tri, sizeof bad);
    bad[13] = NAN;
    b = stl_bin("x", bad, 2);
    expect_fail_lim(api_stl_decode, b.data, b.len, NULL, MCF_EDECODE,
                    "stl: triangle 1: vertex 2 has a non-finite coordinate");
    api_buf_free(&b);
    bad[13] = INFINITY;
    b = stl_bin("x", bad, 2);
    expect_fail_lim(api_stl_decode, b.data, b.len, NULL, MCF_EDECODE,
                    "stl: triangle 1: vertex 2 has a non-finite coordinate");
    api_buf_free(&b);
    b = stl_bin("x", tri, 0);
    expect_fail_lim(api_stl_decode, b.data, b.len, NULL, MCF_EDECODE,
                    "stl: binary STL with 0 triangles");
    api_buf_free(&b);
    /* a count far beyond the body */
    b = stl_bin("x", tri, 2);
    b.data[83] = 0x7f;
    expect_fail_lim(api_stl_decode, b.data, b.len, NULL, MCF_EDECODE,
                    "stl: binary header announces 2130706434 triangles "
                    "(106535321784 bytes) but the input has 184 bytes");
    api_buf_free(&b);
}

static void test_stl_ascii_variants(void **state)
{
    static const int32_t quad[] = {0, 1, 2, 0, 2, 3};
    (void)state;
    expect_ok(api_stl_decode,
              "solid my part name\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
              "vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid my part name\n",
              3, 1, NULL);
    /* everything on one line, CRLF elsewhere, two solids sharing vertices */
    expect_ok(api_stl_decode,
              "solid a facet normal 0 0 1 outer loop vertex 0 0 0 vertex 1 0 0 "
              "vertex 0 1 0 endloop endfacet endsolid a\r\n"
              "solid b\r\n  facet normal 0 0 0\r\n    outer loop\r\n"
              "      vertex 1 0 0\r\n      vertex 0 1 0\r\n      vertex 1 1 0\r\n"
              "    endloop\r\n  endfacet\r\nendsolid\r\n",
              4, 2, NULL);
    /* a quad loop is fanned */
    expect_ok(api_stl_decode,
              "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
              "vertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n",
              4, 2, quad);
}

#define FACET "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n" \
              "vertex 0 1 0\nendloop\nendfacet\n"

static void test_stl_ascii_errors(void **state)
{
    static const char good[] = "solid t\n" FACET "endsolid t\n";
    size_t cut;
    api_limits lim;
    (void)state;
    expect_fail(api_stl_decode, "", MCF_EDECODE, "stl: empty input");
    expect_fail(api_stl_decode, "solid x\n", MCF_EDECODE,
                "stl: line 2: input ends inside solid 1 ('endsolid' missing)");
    expect_fail(api_stl_decode, "solid x\nendsolid x\n", MCF_EDECODE, "stl: no facets");
    expect_fail(api_stl_decode, "solid x\n" FACET, MCF_EDECODE,
                "stl: line 9: input ends inside solid 1 ('endsolid' missing)");
    expect_fail(api_stl_decode, "solid x\nfacett normal\n", MCF_EDECODE,
                "stl: line 2: 'facet' or 'endsolid' expected, found 'facett'");
    expect_fail(api_stl_decode, "solid x\nfacet normal 0 0\nouter loop\n", MCF_EDECODE,
                "stl: line 3: bad number 'outer'");
    expect_fail(api_stl_decode, "solid x\nfacet normal 0 0 1\nouter lop\n",
                MCF_EDECODE, "stl: line 3: 'loop' expected, found 'lop'");
    expect_fail(api_stl_decode, "solid x\nfacet\n", MCF_EDECODE,
                "stl: line 3: input ends, 'normal' expected");
    expect_fail(api_stl_decode,
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                "endloop\nendfacet\nendsolid\n",
                MCF_EDECODE, "stl: line 6: facet has 2 vertices, at least 3 needed");
    expect_fail(api_stl_decode,
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                "vertex 0 1 0\nendfacet\n",
                MCF_EDECODE, "stl: line 7: 'vertex' or 'endloop' expected, found "
                             "'endfacet'");
    expect_fail(api_stl_decode,
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                "vertex 0 1 nan\nendloop\nendfacet\nendsolid\n",
                MCF_EDECODE, "stl: line 6: coordinate is not finite");
    expect_fail(api_stl_decode,
                "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                "vertex 0 1 q\nendloop\nendfacet\nendsolid\n",
                MCF_EDECODE, "stl: line 6: bad number 'q'");
    expect_fail(api_stl_decode, "solid x\n" FACET "endloop\nendsolid\n", MCF_EDECODE,
                "stl: line 9: 'facet' or 'endsolid' expected, found 'endloop'");
    expect_fail(api_stl_decode, "solid x\n" FACET "endsolid\nvertex\n", MCF_EDECODE,
                "stl: line 10: 'solid' expected, found 'vertex'");
    expect_fail(api_stl_decode, "hello", MCF_EDECODE,
                "stl: 5 bytes: neither ASCII ('solid') nor binary (84 bytes at least)");
    /* every prefix fails with a line-numbered message */
    for (cut = 1; cut + 1 < sizeof good - 1; cut++) {
        mcf_mesh *m;
        mcf_error err;
        mcf_status rc = dec(api_stl_decode, good, cut, &m, &err);
        if (rc == MCF_OK) {
            /* only the trailing name and newline may be cut */
            assert_true(cut >= sizeof good - 1 - 3);
            mcf_mesh_free(m);
            continue;
        }
        if (rc != MCF_EDECODE || strncmp(err.msg, "stl: ", 5) != 0)
            fail_msg("cut %zu: %s \"%s\"", cut, mcf_status_name(rc), err.msg);
    }
    api_limits_default(&lim);
    lim.max_faces = 1;
    expect_fail_lim(api_stl_decode, "solid\n" FACET FACET "endsolid\n",
                    strlen("solid\n" FACET FACET "endsolid\n"), &lim, MCF_ELIMIT,
                    "stl: more than max_faces (1) triangles");
}

static void test_stl_writer(void **state)
{
    static const double X[] = {0, 0, 0, 1e300, 0, 0, 0, 1, 0};
    static const int32_t F[] = {0, 1, 2};
    mcf_error err;
    mcf_mesh *m = mcf_mesh_new(3, X, 1, F, &err), *s = tl_load("sphere_cgal.obj");
    api_encode_opts o;
    api_buf b;
    (void)state;
    assert_non_null(m);
    api_encode_opts_init(&o);
    api_buf_init(&b, 0);
    assert_int_equal(api_stl_encode(m, &o, &b, &err), MCF_EINVAL);
    assert_string_equal(err.msg, "stl: vertex 1 coordinate 1e+300 exceeds the float "
                                 "range of binary STL");
    assert_int_equal(b.len, 0);
    o.stl_binary = 0; /* ASCII holds any double */
    assert_int_equal(api_stl_encode(m, &o, &b, &err), MCF_OK);
    assert_true(strncmp(b.data, "solid mcfd\nfacet normal 0 0 1\n", 30) == 0);
    api_buf_free(&b);
    /* binary: 84 + 50 n bytes, a header not starting with "solid", unit
     * normals */
    o.stl_binary = 1;
    api_buf_init(&b, 0);
    assert_int_equal(api_stl_encode(s, &o, &b, &err), MCF_OK);
    assert_int_equal(b.len, 84 + 50 * (size_t)mcf_mesh_nfaces(s));
    assert_true(strncmp(b.data, "solid", 5) != 0);
    {
        float n[3];
        memcpy(n, b.data + 84, sizeof n);
        /* float32 normal of a unit vector: within a few float ulps */
        tl_assert_near(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6,
                       "normal length");
    }
    api_buf_free(&b);
    api_buf_init(&b, 1000);
    assert_int_equal(api_stl_encode(s, &o, &b, &err), MCF_ELIMIT);
    assert_int_equal(b.len, 0);
    api_buf_free(&b);
    mcf_mesh_free(s);
    mcf_mesh_free(m);
}

/* ================================================================== OFF */

static void off_roundtrip(const char *file)
{
    mcf_mesh *m = tl_load(file), *d = NULL;
    api_buf b = encode(m, API_FMT_OFF, 0);
    mcf_error err;
    api_format f;
    if (api_mesh_decode(b.data, b.len, NULL, &d, &f, &err) != MCF_OK)
        fail_msg("%s: %s", file, err.msg);
    assert_int_equal(f, API_FMT_OFF);
    tl_assert_same_mesh(m, d);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
    api_buf_free(&b);
}

static void test_off_roundtrip(void **state)
{
    (void)state;
    off_roundtrip("knot1.obj");
    off_roundtrip("test_nm.obj");        /* unreferenced vertices */
    off_roundtrip("bunny.drc");
}

static void test_off_roundtrip_scans(void **state)
{
    (void)state;
    off_roundtrip("stanford-bunny.obj"); /* unreferenced vertices */
    off_roundtrip("snowden.obj");
}

static void test_off_variants(void **state)
{
    static const int32_t fan[] = {0, 1, 2, 0, 2, 3};
    (void)state;
    expect_ok(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", 3, 1, NULL);
    /* counts on the keyword line, two counts, comments, blank lines, CRLF */
    expect_ok(api_off_decode,
              "# made by hand\r\nOFF 4 1 # counts here\r\n\r\n0 0 0 # v0\r\n"
              "1 0 0\r\n  1 1 0\r\n# comment line\r\n0 1 0\r\n4 0 1 2 3\r\n",
              4, 2, fan);
    expect_ok(api_off_decode, "OFF\n4 1\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", 4,
              2, fan);
    /* COFF: vertex colours; face colours after the indices */
    expect_ok(api_off_decode,
              "COFF\n4 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n"
              "0 1 0 9 9 9 9\n4 0 1 2 3 0.5 0.5 0.5 1\n",
              4, 2, fan);
    expect_ok(api_off_decode, "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n"
                              "3 0 1 2\n",
              3, 1, NULL);
    expect_ok(api_off_decode, "STCNOFF\n3 1 0\n0 0 0 0 0 1 1 1 1 1 0 0\n"
                              "1 0 0 0 0 1 1 1 1 1 0 0\n0 1 0 0 0 1 1 1 1 1 0 0\n"
                              "3 0 1 2\n",
              3, 1, NULL);
}

static void test_off_errors(void **state)
{
    static const char good[] = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    api_limits lim;
    size_t cut;
    (void)state;
    expect_fail(api_off_decode, "", MCF_EDECODE, "off: empty input");
    expect_fail(api_off_decode, "# nothing\n\n", MCF_EDECODE,
                "off: no OFF keyword (only comments)");
    expect_fail(api_off_decode, "ply\n", MCF_EDECODE,
                "off: line 1: 'OFF' expected, found 'ply'");
    expect_fail(api_off_decode, "4OFF\n3 1 0\n", MCF_EDECODE,
                "off: line 1: '4OFF' (not 3-D) is not supported");
    expect_fail(api_off_decode, "nOFF\n4\n", MCF_EDECODE,
                "off: line 1: 'nOFF' (not 3-D) is not supported");
    expect_fail(api_off_decode, "OFF BINARY\n", MCF_EDECODE,
                "off: line 1: binary OFF is not supported");
    expect_fail(api_off_decode, "OFF\n", MCF_EDECODE,
                "off: line 1: input ends before the counts line");
    expect_fail(api_off_decode, "OFF\n3\n", MCF_EDECODE,
                "off: line 2: 'nv nf [ne]' counts expected");
    expect_fail(api_off_decode, "OFF\n3 x 0\n", MCF_EDECODE,
                "off: line 2: 'nv nf [ne]' counts expected, found 'x'");
    expect_fail(api_off_decode, "OFF\n3 -1 0\n", MCF_EDECODE,
                "off: line 2: 'nv nf [ne]' counts expected, found '-1'");
    expect_fail(api_off_decode, "OFF\n3 1 0 7\n", MCF_EDECODE,
                "off: line 2: 'nv nf [ne]' counts expected, found '7'");
    /* huge counts over a tiny body */
    expect_fail(api_off_decode, "OFF\n2000000000 1 0\n0 0 0\n", MCF_EDECODE,
                "off: line 2: 2000000000 vertices and 1 faces cannot fit in the "
                "remaining 6 bytes");
    expect_fail(api_off_decode, "OFF\n3 9223372036854775807 0\n0 0 0\n", MCF_EDECODE,
                "off: line 2: 3 vertices and 9223372036854775807 faces cannot fit");
    expect_fail(api_off_decode, "OFF\n0 0 0\n", MCF_EDECODE, "off: no vertices");
    expect_fail(api_off_decode, "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n", MCF_EDECODE,
                "off: no faces: 3 vertices only");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2      \n",
                MCF_EDECODE, "off: line 4: vertex 1 has 2 coordinates, 3 needed");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 y\n0 1 0\n3 0 1 2\n",
                MCF_EDECODE, "off: line 4: bad number 'y'");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n",
                MCF_EDECODE, "off: line 4: coordinate 'inf' is not finite");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1    \n",
                MCF_EDECODE, "off: line 6: face 0 has 2 vertices, at least 3 needed");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
                MCF_EDECODE, "off: line 6: face 0: index 3 out of range (0..2)");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n",
                MCF_EDECODE, "off: line 6: face 0: index -1 out of range (0..2)");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n",
                MCF_EDECODE, "off: line 6: bad index '2.5'");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\nthree 0 1 2\n",
                MCF_EDECODE, "off: line 6: bad vertex count 'three'");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n",
                MCF_EDECODE, "off: line 6: face 0 lists 3 of 4 vertices");
    expect_fail(api_off_decode, "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n\n\n\n\n\n\n\n\n",
                MCF_EDECODE, "off: line 14: input ends at face 1 of 2");
    /* one vertex line short: the face line is read as a vertex with an
     * extra value (OFF allows extras), then the face is missing */
    expect_fail(api_off_decode, "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2        \n",
                MCF_EDECODE, "off: line 6: input ends at face 0 of 1");
    expect_fail(api_off_decode, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n",
                MCF_EDECODE, "off: line 7: data after the last face");
    api_limits_default(&lim);
    lim.max_vertices = 2;
    expect_fail_lim(api_off_decode, good, strlen(good), &lim, MCF_ELIMIT,
                    "off: 3 vertices exceed max_vertices (2)");
    api_limits_default(&lim);
    lim.max_faces = 1;
    expect_fail_lim(api_off_decode, "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
                    strlen("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"), &lim,
                    MCF_ELIMIT, "off: line 7: more than max_faces (1) triangles");
    lim.max_faces = 0;
    expect_fail_lim(api_off_decode, good, strlen(good), &lim, MCF_ELIMIT,
                    "off: 1 faces exceed max_faces (0)");
    /* every prefix fails with an "off: " message, except the one missing
     * only the final newline */
    for (cut = 1; cut < sizeof good - 1; cut++) {
        mcf_mesh *m;
        mcf_error err;
        mcf_status rc = dec(api_off_decode, good, cut, &m, &err);
        if (cut == sizeof good - 2) {
            assert_int_equal(rc, MCF_OK);
            mcf_mesh_free(m);
            continue;
        }
        if (rc != MCF_EDECODE || strncmp(err.msg, "off: ", 5) != 0)
            fail_msg("cut %zu: %s \"%s\"", cut, mcf_status_name(rc), err.msg);
    }
}

/* Binary garbage after each keyword and in bodies: a message, no crash. */
static void test_garbage(void **state)
{
    static const char *const starts[] = {"OFF\n", "solid x\n", "COFF 3 1 0\n"};
    uint64_t s = 0x9e3779b97f4a7c15ull;
    int trial;
    (void)state;
    for (trial = 0; trial < 600; trial++) {
        unsigned char buf[400];
        const char *st = starts[trial % 3];
        size_t n0 = strlen(st), len = n0 + (size_t)(trial * 13 % 380), i;
        mcf_mesh *m;
        mcf_error err;
        mcf_status rc;
        memcpy(buf, st, n0);
        for (i = n0; i < len; i++) {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            /* half the trials: digits, spaces and newlines only */
            buf[i] = (trial & 1) ? (unsigned char)" 0123456789\n-."[s % 14]
                                 : (unsigned char)s;
        }
        rc = dec(trial % 3 == 1 ? api_stl_decode : api_off_decode, buf, len, &m, &err);
        if (rc == MCF_OK) {
            mcf_mesh_free(m);
            continue;
        }
        if (rc != MCF_EDECODE && rc != MCF_ELIMIT && rc != MCF_EMESH)
            fail_msg("trial %d: %s \"%s\"", trial, mcf_status_name(rc), err.msg);
        assert_true(err.msg[0] != '\0');
    }
}

/* STL and OFF carry no attributes: api_mesh_decode_attrs gives an empty
 * handle, single precision for a binary STL only; the PLY written from
 * it is float for the binary STL, double for OFF and ASCII STL. */
static void test_attrs_stl_off(void **state)
{
    static const char off[] = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    static const char astl[] =
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    unsigned char bin[84 + 50];
    const char *in[3] = {off, astl, (const char *)bin};
    size_t len[3] = {sizeof off - 1, sizeof astl - 1, sizeof bin};
    int want[3] = {0, 0, 1}, i, k;
    (void)state;
    memset(bin, 0, sizeof bin);
    bin[80] = 1;
    for (k = 0; k < 3; k++) { /* vertices (0,0,0) (1,0,0) (0,1,0) */
        float v[3] = {k == 1 ? 1.0f : 0.0f, k == 2 ? 1.0f : 0.0f, 0.0f};
        memcpy(bin + 84 + 12 + 12 * k, v, 12);
    }
    for (i = 0; i < 3; i++) {
        mcf_mesh *m = NULL;
        api_attrs *a = NULL;
        api_format f;
        mcf_error err;
        api_encode_opts o;
        api_buf b;
        if (api_mesh_decode_attrs(in[i], len[i], NULL, &m, &a, &f, &err) != MCF_OK)
            fail_msg("input %d: %s", i, err.msg);
        assert_int_equal(api_attrs_float32(a), want[i]);
        for (k = 0; k < API_ATTR_KINDS; k++)
            assert_false(api_attrs_get(a, (api_attr_kind)k, NULL, NULL, NULL, NULL));
        assert_int_equal(api_attrs_draco_bits(a, API_ATTR_POSITION), -1);
        api_encode_opts_init(&o);
        o.format = API_FMT_PLY;
        o.attrs = a;
        api_buf_init(&b, 0);
        assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
        assert_non_null(strstr(b.data, want[i] ? "property float x\n"
                                               : "property double x\n"));
        api_buf_free(&b);
        api_attrs_free(a);
        mcf_mesh_free(m);
    }
}

/* Issue 20: a 36-quad OFF comes back as 36 quads (it came back as 72
 * triangles), a pentagon as a pentagon, at the smoothed positions. */
static void test_off_polygons(void **state)
{
    double X[147];
    int Q[144], i, k;
    char in[8192], *p = in;
    mcf_mesh *m = NULL, *d = NULL;
    api_attrs *a = NULL;
    api_encode_opts o;
    api_buf b;
    mcf_error err;
    const char *line;
    (void)state;
    tl_quad_grid(X, Q);
    p += sprintf(p, "OFF\n49 37 0\n");
    for (i = 0; i < 49; i++)
        p += sprintf(p, "%.17g %.17g %.17g\n", X[3 * i], X[3 * i + 1], X[3 * i + 2]);
    for (i = 0; i < 36; i++)
        p += sprintf(p, "4 %d %d %d %d\n", Q[4 * i], Q[4 * i + 1], Q[4 * i + 2], Q[4 * i + 3]);
    p += sprintf(p, "5 0 1 2 9 7\n"); /* a pentagon (over the grid: any) */
    assert_int_equal(api_mesh_decode_attrs(in, strlen(in), NULL, &m, &a, NULL, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 72 + 3);
    tl_smooth_a_little(m);
    api_encode_opts_init(&o);
    o.format = API_FMT_OFF;
    o.attrs = a;
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    assert_non_null(strstr(b.data, "OFF\n49 37 0\n"));
    line = strstr(b.data, "\n4 ") + 1;
    for (i = 0; i < 36; i++) {
        int v[4];
        assert_int_equal(sscanf(line, "4 %d %d %d %d", v, v + 1, v + 2, v + 3), 4);
        for (k = 0; k < 4; k++)
            assert_int_equal(v[k], Q[4 * i + k]);
        line = strchr(line, '\n') + 1;
    }
    assert_true(strncmp(line, "5 0 1 2 9 7\n", 12) == 0);
    assert_int_equal(api_off_decode(b.data, b.len, NULL, &d, &err), MCF_OK);
    tl_assert_same_mesh(m, d);
    api_buf_free(&b);
    mcf_mesh_free(m);
    mcf_mesh_free(d);
    api_attrs_free(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stl_roundtrip),
        cmocka_unit_test(test_stl_roundtrip_scans),
        cmocka_unit_test(test_stl_weld_car),
        cmocka_unit_test(test_stl_binary_cases),
        cmocka_unit_test(test_stl_ascii_variants),
        cmocka_unit_test(test_stl_ascii_errors),
        cmocka_unit_test(test_stl_writer),
        cmocka_unit_test(test_off_roundtrip),
        cmocka_unit_test(test_off_roundtrip_scans),
        cmocka_unit_test(test_off_variants),
        cmocka_unit_test(test_off_errors),
        cmocka_unit_test(test_garbage),
        cmocka_unit_test(test_attrs_stl_off),
        cmocka_unit_test(test_off_polygons),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
