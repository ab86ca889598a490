/* SPDX-License-Identifier: MIT */
/*
 * test_api_obj.c - the OBJ reader and writer (api_obj.c).
 *
 * Real files: every OBJ of tests/data/meshes (and of $MCF_MESHES, the
 * large scans) decodes with the counts of
 * SOURCES.md, and write -> read returns bit-identical positions and the
 * same faces. Syntax: every face-reference form, negative indices,
 * polygons, comments, CRLF, skipped statements. Hostile input: every
 * malformed case fails with EDECODE or ELIMIT and names the line. Each
 * inline input is copied into an exact-size heap block with no NUL, so a
 * read past the end shows under AddressSanitizer.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

/* Decodes text from an exact-size, non-NUL-terminated copy. */
static mcf_status dec_lim(const char *text, const api_limits *lim,
                          mcf_mesh **m, mcf_error *err)
{
    return tl_decode_copy(api_obj_decode, text, strlen(text), lim, m, err);
}

static mcf_status dec(const char *text, mcf_mesh **m, mcf_error *err)
{
    api_limits lim;
    api_limits_default(&lim);
    return dec_lim(text, &lim, m, err);
}

/* Decoding must fail with code and a message containing want. */
static void expect_fail_lim(const char *text, const api_limits *lim,
                            mcf_status code, const char *want)
{
    mcf_mesh *m = NULL;
    mcf_error err;
    mcf_status rc = dec_lim(text, lim, &m, &err);
    if (rc != code || !strstr(err.msg, want))
        fail_msg("input %.40s...: got %s \"%s\", want %s containing \"%s\"",
                 text, mcf_status_name(rc), err.msg, mcf_status_name(code),
                 want);
    assert_null(m);
    assert_int_equal(err.status, code);
}

static void expect_fail(const char *text, mcf_status code, const char *want)
{
    api_limits lim;
    api_limits_default(&lim);
    expect_fail_lim(text, &lim, code, want);
}

static void expect_faces(const mcf_mesh *m, const int32_t *want, int nf)
{
    int i;
    assert_int_equal(mcf_mesh_nfaces(m), nf);
    for (i = 0; i < 3 * nf; i++)
        if (mcf_mesh_faces(m)[i] != want[i])
            fail_msg("face entry %d: %d, want %d", i, mcf_mesh_faces(m)[i],
                     want[i]);
}

static const struct {
    const char *file;
    int nv, nf;
} real[] = {
    {"sphere_cgal.obj", 812, 1620},
    {"bunny_npm_closed.obj", 1839, 3674},
    {"spot.obj", 2930, 5856},           /* f v/vt */
    {"knot1.obj", 3200, 6400},
    {"fertility.obj", 4494, 9000},
    {"stanford-bunny.obj", 35947, 69451},
    {"armadillo.obj", 43243, 86482},
    {"snowden.obj", 54559, 109259},
    {"dragon_vrip_res2.obj", 100250, 202520},
    {"test_nm.obj", 114, 170},          /* has vn */
};

/* The meshes of the repository (scans 0) or the large scans of
 * $MCF_MESHES (scans 1: the test is skipped when one is missing). */
static void real_counts(int scans)
{
    size_t i;
    for (i = 0; i < sizeof real / sizeof real[0]; i++) {
        mcf_mesh *m;
        if (tl_mesh_in_repo(real[i].file) == scans)
            continue;
        m = tl_load(real[i].file);
        if (mcf_mesh_nvertices(m) != real[i].nv
            || mcf_mesh_nfaces(m) != real[i].nf)
            fail_msg("%s: %d vertices, %d faces; SOURCES.md says %d, %d",
                     real[i].file, mcf_mesh_nvertices(m), mcf_mesh_nfaces(m),
                     real[i].nv, real[i].nf);
        mcf_mesh_free(m);
    }
}

static void test_real_counts(void **state)
{
    (void)state;
    real_counts(0);
}

static void test_real_counts_scans(void **state)
{
    (void)state;
    real_counts(1);
}

/* The first vertex and face of sphere_cgal.obj, as written in the file:
 * strtod is correctly rounded, so == on the parsed literal is exact. */
static void test_real_values(void **state)
{
    mcf_mesh *m = tl_load("sphere_cgal.obj");
    const double *X = mcf_mesh_positions(m);
    (void)state;
    assert_true(X[0] == -0.52573111211913348);
    assert_true(X[1] == 0.85065080835203999);
    assert_true(X[2] == -2.5720446970240305e-18);
    assert_true(X[3] == 0.52573111211913359);
    mcf_mesh_free(m);
}

static void roundtrip(const char *file)
{
    mcf_mesh *a = tl_load(file), *b = NULL;
    api_buf out;
    mcf_error err;
    api_limits lim;

    api_buf_init(&out, 0);
    api_limits_default(&lim);
    if (api_obj_encode(a, &out, &err) != MCF_OK)
        fail_msg("%s: encode: %s", file, err.msg);
    if (api_obj_decode(out.data, out.len, &lim, &b, &err) != MCF_OK)
        fail_msg("%s: decode of own output: %s", file, err.msg);
    /* %.17g round-trips doubles exactly: bit-identical, no tolerance. */
    tl_assert_same_mesh(a, b);
    api_buf_free(&out);
    mcf_mesh_free(a);
    mcf_mesh_free(b);
}

static void test_roundtrip(void **state)
{
    (void)state;
    roundtrip("sphere_cgal.obj");
    roundtrip("knot1.obj");
}

static void test_roundtrip_scans(void **state)
{
    (void)state;
    roundtrip("fertility.obj");
    roundtrip("spot.obj");
}

/* Values no short decimal represents: subnormal, huge, negative zero. */
static void test_roundtrip_extremes(void **state)
{
    const double X[] = {4.9406564584124654e-324, -1.7976931348623157e308, -0.0,
                        0.1, 1.0 / 3.0, -2.2250738585072014e-308,
                        1e-300, 123456789.123456789, 6.02214076e23};
    const int32_t F[] = {0, 1, 2};
    mcf_error err;
    mcf_mesh *a = mcf_mesh_new(3, X, 1, F, &err), *b = NULL;
    api_buf out;
    (void)state;
    assert_non_null(a);
    api_buf_init(&out, 0);
    assert_int_equal(api_obj_encode(a, &out, &err), MCF_OK);
    assert_int_equal(api_obj_decode(out.data, out.len, NULL, &b, &err), MCF_OK);
    assert_memory_equal(mcf_mesh_positions(a), mcf_mesh_positions(b), sizeof X);
    api_buf_free(&out);
    mcf_mesh_free(a);
    mcf_mesh_free(b);
}

static void test_encode_limit(void **state)
{
    mcf_mesh *m = tl_load("sphere_cgal.obj");
    api_buf out;
    mcf_error err;
    (void)state;
    api_buf_init(&out, 1000);
    assert_int_equal(api_buf_append(&out, "abc", 3), MCF_OK);
    assert_int_equal(api_obj_encode(m, &out, &err), MCF_ELIMIT);
    /* A failed encode leaves what the buffer held before. */
    assert_int_equal(out.len, 3);
    assert_string_equal(out.data, "abc");
    api_buf_free(&out);
    mcf_mesh_free(m);
}

static void test_polygons(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    const int32_t want[] = {0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 2, 3, 0, 3, 4};
    (void)state;
    assert_int_equal(dec("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0 0\n"
                         "f 1 2 3 4\nf 1 2 3 4 5\n", &m, &err), MCF_OK);
    expect_faces(m, want, 5);
    mcf_mesh_free(m);
}

/* Polygons fanning into more triangles than their vertices and faces
 * make (api__fan_max: 2 x 3 + 1024 = 1030 here) are refused before the
 * triangles are built (issue 28); 2,000 corners on 3 vertices: 1,998. */
static void test_polygon_fan_budget(void **state)
{
    api_buf b;
    mcf_mesh *m = NULL;
    mcf_error err;
    int i;
    (void)state;
    api_buf_init(&b, 0);
    assert_int_equal(api_buf_printf(&b, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf"), MCF_OK);
    for (i = 0; i < 2000; i++)
        assert_int_equal(api_buf_printf(&b, " %d", 1 + i % 3), MCF_OK);
    assert_int_equal(api_buf_printf(&b, "\n"), MCF_OK);
    assert_int_equal(dec(b.data, &m, &err), MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "1998 triangles"));
    api_buf_free(&b);
}

static void test_reference_forms(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    const int32_t want[] = {0, 1, 2, 1, 2, 3, 0, 2, 3, 3, 1, 0};
    (void)state;
    assert_int_equal(dec("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                         "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
                         "f 1/1 2/2 3/3\n"
                         "f 2//1 3//1 4//1\n"
                         "f 1/1/1 3/3/1 4/2/1\n"
                         "f 4/-1 2//-1 1/-2/-1\n", &m, &err), MCF_OK);
    expect_faces(m, want, 4);
    mcf_mesh_free(m);
}

static void test_negative_indices(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    /* -1 is the latest vertex read so far, not the last of the file. */
    const int32_t want[] = {0, 1, 2, 1, 2, 3, 0, 3, 4};
    (void)state;
    assert_int_equal(dec("v 0 0 0\nv 1 0 0\nv 1 1 0\nf -3 -2 -1\n"
                         "v 0 1 0\nf -3 -2 -1\nv 2 2 2\nf 1 -2 -1\n", &m, &err),
                     MCF_OK);
    expect_faces(m, want, 3);
    mcf_mesh_free(m);
}

/* A positive index may name a vertex defined further down. */
static void test_forward_reference(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    const int32_t want[] = {0, 1, 2};
    (void)state;
    assert_int_equal(dec("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 1 1 0\n", &m, &err),
                     MCF_OK);
    expect_faces(m, want, 1);
    mcf_mesh_free(m);
}

static void test_syntax_tolerated(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    const int32_t want[] = {0, 1, 2};
    (void)state;
    assert_int_equal(dec("# header\r\n\r\n   \r\nmtllib a.mtl\r\no thing\r\n"
                         "g group one\r\ns off\r\nusemtl red\r\n"
                         "v 1 2 3 1.0\r\n"                  /* w */
                         "v\t4e0  5.5 -6 0.1 0.2 0.3\r\n"   /* colour */
                         "v +7 .5 -0.0 # trailing comment\r\n"
                         "vt 0.5 0.5\r\nvn 0 0 1\r\nvp 0.1\r\n"
                         "l 1 2\r\n"
                         "f 1 2 3 # comment\r\n"
                         "# no newline at the end", &m, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nvertices(m), 3);
    expect_faces(m, want, 1);
    assert_true(mcf_mesh_positions(m)[3] == 4.0);
    assert_true(mcf_mesh_positions(m)[4] == 5.5);
    assert_true(mcf_mesh_positions(m)[6] == 7.0);
    assert_true(mcf_mesh_positions(m)[7] == 0.5);
    assert_true(signbit(mcf_mesh_positions(m)[8]));
    mcf_mesh_free(m);
}

/* A UTF-8 byte-order mark before the first statement is skipped. */
static void test_bom(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    const char t[] = "\xEF\xBB\xBFv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    (void)state;
    assert_int_equal(api_format_detect(t, sizeof t - 1), API_FMT_OBJ);
    assert_int_equal(dec(t, &m, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 1);
    mcf_mesh_free(m);
    /* Only at the very start: elsewhere it is an unknown statement. */
    expect_fail("v 0 0 0\n\xEF\xBB\xBFv 1 0 0\n", MCF_EDECODE, "line 2: unknown statement");
}

/* The last number touches the end of the buffer (no newline, no NUL). */
static void test_number_at_end(void **state)
{
    mcf_mesh *m;
    mcf_error err;
    (void)state;
    assert_int_equal(dec("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 1 1 0.125", &m, &err),
                     MCF_OK);
    assert_true(mcf_mesh_positions(m)[8] == 0.125);
    mcf_mesh_free(m);
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4", MCF_EDECODE,
                "line 4: face index 4 out of range (1..3)");
}

static void test_malformed(void **state)
{
    char big[300];
    (void)state;
    expect_fail("", MCF_EDECODE, "empty");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1\nf 1 2 3\n", MCF_EDECODE,
                "line 3: vertex has 2 coordinates");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1", MCF_EDECODE, "line 3:");
    expect_fail("v 0 0 0\nv 1 zero 0\nv 1 1 0\nf 1 2 3\n", MCF_EDECODE,
                "line 2: bad number 'zero'");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0x\nf 1 2 3\n", MCF_EDECODE,
                "line 3: bad number '0x'");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 1,5\nf 1 2 3\n", MCF_EDECODE,
                "line 3: bad number");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n", MCF_EDECODE,
                "line 4: face index 0");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 -4\n", MCF_EDECODE,
                "line 4: face index -4 out of range (-3..-1)");
    expect_fail("v 0 0 0\nv 1 0 0\nf 1 2 -3\nv 1 1 0\n", MCF_EDECODE,
                "line 3: face index -3 out of range (-2..-1)");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 99999999999999999999\n",
                MCF_EDECODE, "line 4: face index 99999999999999999999 out of range");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 x\n", MCF_EDECODE,
                "line 4: bad face vertex index 'x'");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3/1/1/1\n", MCF_EDECODE,
                "line 4: bad face vertex '3/1/1/1'");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 /3\n", MCF_EDECODE,
                "line 4: bad face vertex index");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2\n", MCF_EDECODE,
                "line 4: face has 2 vertices");
    expect_fail("v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n", MCF_EDECODE,
                "line 2: coordinate 'nan' is not finite");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 -inf 0\nf 1 2 3\n", MCF_EDECODE,
                "line 3: coordinate '-inf' is not finite");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1e999 0\nf 1 2 3\n", MCF_EDECODE,
                "line 3: coordinate '1e999' is not finite");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\nfoo 1 2 3\n", MCF_EDECODE,
                "line 4: unknown statement 'foo'");
    expect_fail("v 0 0 0\nv 1 0 0\nv 1 1 0\n", MCF_EDECODE, "no faces");
    expect_fail("# nothing\n", MCF_EDECODE, "no vertices");
    /* A number too long for the local buffer is refused, not truncated. */
    memset(big, '1', sizeof big);
    memcpy(big, "v 1 1 ", 6);
    big[sizeof big - 1] = '\0';
    expect_fail(big, MCF_EDECODE, "line 1: bad number");
}

static void test_binary_garbage(void **state)
{
    unsigned char junk[512];
    mcf_mesh *m = NULL;
    mcf_error err;
    unsigned x = 12345;
    size_t i;
    (void)state;
    for (i = 0; i < sizeof junk; i++) {
        x = x * 1103515245u + 12345u;
        junk[i] = (unsigned char)(x >> 16);
    }
    junk[0] = 'v'; /* looks like OBJ for one byte */
    junk[1] = ' ';
    junk[2] = 0x01;
    assert_int_equal(api_obj_decode(junk, sizeof junk, NULL, &m, &err),
                     MCF_EDECODE);
    assert_non_null(strstr(err.msg, "line 1: binary data"));
    assert_null(m);
    /* An embedded NUL on a later line. */
    {
        const char t[] = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\0\n";
        assert_int_equal(api_obj_decode(t, sizeof t - 1, NULL, &m, &err),
                         MCF_EDECODE);
        assert_non_null(strstr(err.msg, "line 4: binary data (byte 0x00)"));
    }
}

static void test_limits(void **state)
{
    api_limits lim;
    (void)state;
    api_limits_default(&lim);
    lim.max_vertices = 3;
    expect_fail_lim("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 2 2 2\nf 1 2 3\n", &lim,
                    MCF_ELIMIT, "line 4: more than max_vertices (3)");
    api_limits_default(&lim);
    lim.max_faces = 2;
    /* A pentagon is 3 triangles: over the limit on its own line. */
    expect_fail_lim("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 5 5 5\n"
                    "# c\nf 1 2 3 4 5\n", &lim, MCF_ELIMIT,
                    "line 7: more than max_faces (2)");
    api_limits_default(&lim);
    lim.max_input_bytes = 10;
    expect_fail_lim("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n", &lim, MCF_ELIMIT,
                    "max_input_bytes (10)");
    /* Limits win over syntax further down: nothing is allocated first. */
    api_limits_default(&lim);
    lim.max_vertices = 2;
    expect_fail_lim("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 junk\n", &lim,
                    MCF_ELIMIT, "line 3:");
}

/* A face line announcing millions of triangles in a short input. */
static void test_huge_counts(void **state)
{
    size_t n = 3 * 20 + 2 + 2 * 200000, i;
    char *t = malloc(n + 1), *p = t;
    mcf_mesh *m = NULL;
    mcf_error err;
    api_limits lim;
    (void)state;
    assert_non_null(t);
    memcpy(p, "v 0 0 0\nv 1 0 0\nv 1 1 0\n", 24);
    p += 24;
    *p++ = 'f';
    for (i = 0; i < 200000; i++) {
        *p++ = ' ';
        *p++ = '1';
    }
    api_limits_default(&lim);
    lim.max_faces = 1000;
    assert_int_equal(api_obj_decode(t, (size_t)(p - t), &lim, &m, &err),
                     MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "line 4: more than max_faces (1000)"));
    assert_null(m);
    free(t);
}

/* ------------------------------------------------------------ attributes */

/* spot.obj (f v/vt, 3,225 vt, 6 significant digits): its texcoords come
 * back bit for bit through OBJ, corner by corner, after smoothing too;
 * the positions count as single precision. */
static void test_obj_attrs_spot(void **state)
{
    char path[4096], *buf;
    size_t len;
    mcf_mesh *m = NULL, *d = NULL;
    api_attrs *a = NULL, *da = NULL;
    mcf_error err;
    api_encode_opts o;
    api_buf b;
    mcf_flow_params p;
    const double *v0, *v1;
    const int32_t *c0, *c1;
    int n0, n1, c;
    (void)state;
    snprintf(path, sizeof path, "%s", tl_need_mesh("spot.obj"));
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("cannot read %s", path);
    assert_int_equal(api_obj_decode_attrs(buf, len, NULL, &m, &a, &err), MCF_OK);
    free(buf);
    assert_int_equal(api_attrs_float32(a), 1);
    assert_int_equal(api_attrs_draco_bits(a, API_ATTR_POSITION), -1);
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, &n0, &v0, &c0));
    assert_int_equal(n0, 3225);
    assert_false(api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
    assert_false(api_attrs_get(a, API_ATTR_COLOR, NULL, NULL, NULL, NULL));
    mcf_flow_params_init(&p);
    p.dt = 1e-5;
    p.iterations = 2;
    assert_int_equal(mcf_flow_run(m, &p, NULL, &err), MCF_OK);
    api_encode_opts_init(&o);
    o.format = API_FMT_OBJ;
    o.attrs = a;
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    assert_non_null(strstr(b.data, "\nf 739/1 735/2 736/3\n"));
    assert_int_equal(api_obj_decode_attrs(b.data, b.len, NULL, &d, &da, &err), MCF_OK);
    tl_assert_same_mesh(m, d);
    assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, &n1, &v1, &c1));
    assert_int_equal(n1, n0);
    for (c = 0; c < 3 * mcf_mesh_nfaces(m); c++)
        if (v0[2 * c0[c]] != v1[2 * c1[c]] || v0[2 * c0[c] + 1] != v1[2 * c1[c] + 1])
            fail_msg("corner %d: texcoord changed", c);
    api_buf_free(&b);
    api_attrs_free(a);
    api_attrs_free(da);
    mcf_mesh_free(m);
    mcf_mesh_free(d);
}

/* vt, vn and vertex colours with every reference form: a quad with
 * v/vt/vn, a triangle with negative references, one with v//vn. The
 * encoder writes v x y z r g b, the vt values as they were and vn
 * recomputed (unit, facing like the faces), f v/vt/vn. */
static void test_obj_attrs_forms(void **state)
{
    static const char text[] =
        "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 0.5 0.5 0.5\n"
        "v 0.5 0.5 1 0.25 0.25 0.25\n"
        "vt 0.1 0.2\nvt 0.3 0.4\nvt 0.5 0.6\nvt 0.7 0.8\nvt 0.9\n"
        "vn 0 0 -1\nvn 0 0 1\n"
        "f 4/4/1 3/3/1 2/2/1 1/1/1\n"
        "f 1/1/2 2/2/2 -1/-1/-1\n"
        "f 2/2/2 3/3/2 5/5/2\nf 3/3/2 4/4/2 5/5/2\nf 4/4/2 1/1/2 5/5/2\n";
    mcf_mesh *m = NULL, *d = NULL;
    api_attrs *a = NULL, *da = NULL;
    mcf_error err;
    api_encode_opts o;
    api_buf b;
    const double *tv, *cv, *nv;
    const int32_t *tc, *nc;
    int n, c;
    (void)state;
    assert_int_equal(api_obj_decode_attrs(text, sizeof text - 1, NULL, &m, &a, &err),
                     MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 6);
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, &n, &tv, &tc));
    assert_int_equal(n, 5);
    /* the fan of the quad: (4, 3, 2), (4, 2, 1); "vt 0.9" has v = 0 */
    assert_int_equal(tc[0], 3);
    assert_int_equal(tc[5], 0);
    assert_int_equal(tc[8], 4);
    assert_true(tv[8] == 0.9 && tv[9] == 0.0);
    assert_true(api_attrs_get(a, API_ATTR_NORMAL, NULL, &n, NULL, &nc));
    assert_int_equal(n, 2);
    assert_int_equal(nc[0], 0);
    assert_int_equal(nc[8], 1);
    assert_true(api_attrs_get(a, API_ATTR_COLOR, &n, NULL, &cv, NULL));
    assert_int_equal(n, 3);
    assert_true(cv[9] == 0.5);

    api_encode_opts_init(&o);
    o.format = API_FMT_OBJ;
    o.attrs = a;
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    assert_non_null(strstr(b.data, "\nv 0 1 0 0.5 0.5 0.5\n"));
    assert_non_null(strstr(b.data, "\nvt 0.90000000000000002 0\n"));
    assert_non_null(strstr(b.data, "\nf 4/4/1 3/3/1 2/2/1 1/1/1\n")); /* the quad as it came */
    assert_int_equal(api_obj_decode_attrs(b.data, b.len, NULL, &d, &da, &err), MCF_OK);
    tl_assert_same_mesh(m, d);
    assert_true(api_attrs_get(da, API_ATTR_NORMAL, NULL, &n, &nv, &nc));
    assert_int_equal(n, 2);
    /* normal 1: the bottom (faces 0 and 1, facing -z); normal 2: the
     * pyramid's sides, summed: +z */
    tl_assert_near(nv[2], -1.0, 1e-9, "bottom normal");
    tl_assert_near(nv[5], 1.0, 1e-9, "side normal");
    for (c = 0; c < 3 * 6; c++)
        assert_true(nc[c] == (c < 6 ? 0 : 1));
    api_buf_free(&b);
    api_attrs_free(a);
    api_attrs_free(da);
    mcf_mesh_free(m);
    mcf_mesh_free(d);
}

/* A corner without vt (or with one out of range) drops the texcoords, a
 * `v` without colour the colours; nothing else changes and plain
 * decoding never looked at them. */
static void test_obj_attrs_dropped(void **state)
{
    static const char text[] =
        "v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0 1 1 1\nv 1 1 0 1 1 1\n"
        "vt 0 0\nvt 1 0\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/9/1\nf 2//1 4//1 3//1\n";
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    mcf_error err;
    (void)state;
    assert_int_equal(api_obj_decode_attrs(text, sizeof text - 1, NULL, &m, &a, &err),
                     MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 2);
    assert_false(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, NULL, NULL));
    assert_false(api_attrs_get(a, API_ATTR_COLOR, NULL, NULL, NULL, NULL));
    assert_true(api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
    assert_int_equal(api_attrs_float32(a), 1);
    api_attrs_free(a);
    mcf_mesh_free(m);
}

/* Issue 20: an OBJ's polygons and its g, o, s, usemtl and mtllib lines
 * come back as they came, in order, with the smoothed positions; the
 * same polygons go on to PLY and OFF. */
static void test_obj_groups_and_polygons(void **state)
{
    double X[147];
    int Q[144], i;
    char in[16384], *p = in, want[16384], *w = want, *got, *g;
    mcf_mesh *m = NULL, *d = NULL;
    api_attrs *a = NULL;
    api_encode_opts o;
    api_buf b;
    mcf_error err;
    (void)state;
    tl_quad_grid(X, Q);
    p += sprintf(p, "# a grid\nmtllib grid.mtl\no grid\n");
    w += sprintf(w, "mtllib grid.mtl\no grid\n");
    for (i = 0; i < 49; i++)
        p += sprintf(p, "v %.17g %.17g %.17g\n", X[3 * i], X[3 * i + 1], X[3 * i + 2]);
    for (i = 0; i < 36; i++) {
        const char *st = i == 0 ? "g left\nusemtl red\ns 1\n"
                         : i == 18 ? "g right\nusemtl blue   \ns off\n" : "";
        p += sprintf(p, "%sf %d %d %d %d\n", st, Q[4 * i] + 1, Q[4 * i + 1] + 1,
                     Q[4 * i + 2] + 1, Q[4 * i + 3] + 1);
        w += sprintf(w, "%sf %d %d %d %d\n", i == 18 ? "g right\nusemtl blue\ns off\n" : st,
                     Q[4 * i] + 1, Q[4 * i + 1] + 1, Q[4 * i + 2] + 1, Q[4 * i + 3] + 1);
    }
    p += sprintf(p, "g cap\nf 1 2 3 10 9\nf 1 9 8\n");
    w += sprintf(w, "g cap\nf 1 2 3 10 9\nf 1 9 8\n");
    assert_int_equal(api_obj_decode_attrs(in, strlen(in), NULL, &m, &a, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 72 + 3 + 1);
    tl_smooth_a_little(m);
    api_encode_opts_init(&o);
    o.format = API_FMT_OBJ;
    o.attrs = a;
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    /* everything but the comment and the v lines, in order */
    got = calloc(b.len + 1, 1);
    assert_non_null(got);
    for (g = got, p = b.data; *p; p = strchr(p, '\n') + 1)
        if (*p != '#' && strncmp(p, "v ", 2) != 0) {
            size_t n = (size_t)(strchr(p, '\n') + 1 - p);
            memcpy(g, p, n);
            g += n;
        }
    assert_string_equal(got, want);
    assert_int_equal(api_obj_decode(b.data, b.len, NULL, &d, &err), MCF_OK);
    tl_assert_same_mesh(m, d);
    mcf_mesh_free(d);
    /* to OFF: the same polygons */
    b.len = 0;
    o.format = API_FMT_OFF;
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    assert_non_null(strstr(b.data, "\n49 38 0\n"));
    assert_non_null(strstr(b.data, "\n5 0 1 2 9 8\n3 0 8 7\n"));
    free(got);
    api_buf_free(&b);
    mcf_mesh_free(m);
    api_attrs_free(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_real_counts),
        cmocka_unit_test(test_real_counts_scans),
        cmocka_unit_test(test_real_values),
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_roundtrip_scans),
        cmocka_unit_test(test_roundtrip_extremes),
        cmocka_unit_test(test_encode_limit),
        cmocka_unit_test(test_polygons),
        cmocka_unit_test(test_polygon_fan_budget),
        cmocka_unit_test(test_reference_forms),
        cmocka_unit_test(test_negative_indices),
        cmocka_unit_test(test_forward_reference),
        cmocka_unit_test(test_syntax_tolerated),
        cmocka_unit_test(test_bom),
        cmocka_unit_test(test_number_at_end),
        cmocka_unit_test(test_malformed),
        cmocka_unit_test(test_binary_garbage),
        cmocka_unit_test(test_limits),
        cmocka_unit_test(test_huge_counts),
        cmocka_unit_test(test_obj_attrs_spot),
        cmocka_unit_test(test_obj_attrs_forms),
        cmocka_unit_test(test_obj_groups_and_polygons),
        cmocka_unit_test(test_obj_attrs_dropped),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
