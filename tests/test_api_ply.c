/* SPDX-License-Identifier: MIT */
/*
 * test_api_ply.c - the PLY reader and writer (api_ply.c).
 *
 * Reference model: a PLY writer in this file produces every variant the
 * reader must accept (three body formats, every scalar type for x y z,
 * extra scalar and list properties of every type around them, any list
 * count/item types, vertex_index, other elements before and after, face
 * element first) from real meshes; each must decode to the values the
 * model wrote. Round trips: the writer's ascii and binary output gives back
 * bit-identical positions and faces, with and without curvature
 * properties. Interop: draco_decoder's binary PLY of bunny.drc matches our
 * Draco decoding. Hostile input: every header error, truncation at every
 * offset, out-of-range indices, NaN, huge counts over tiny bodies,
 * garbage; each fails with the message checked here.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "testlib.h"
#include "../api/api.h"
#include "../api/api_internal.h"

static mcf_status dec_lim(const void *buf, size_t len, const api_limits *lim,
                          mcf_mesh **m, mcf_error *err)
{
    return tl_decode_copy(api_ply_decode, buf, len, lim, m, err);
}

static mcf_status dec(const void *buf, size_t len, mcf_mesh **m, mcf_error *err)
{
    api_limits lim;
    api_limits_default(&lim);
    return dec_lim(buf, len, &lim, m, err);
}

static void expect_fail_lim(const void *buf, size_t len, const api_limits *lim,
                            mcf_status code, const char *want)
{
    mcf_mesh *m = NULL;
    mcf_error err;
    mcf_status rc = dec_lim(buf, len, lim, &m, &err);
    if (rc != code || !strstr(err.msg, want))
        fail_msg("input \"%.50s\"...: got %s \"%s\", want %s containing \"%s\"",
                 (const char *)buf, mcf_status_name(rc), err.msg,
                 mcf_status_name(code), want);
    assert_null(m);
    assert_int_equal(err.status, code);
}

static void expect_fail(const char *text, mcf_status code, const char *want)
{
    api_limits lim;
    api_limits_default(&lim);
    expect_fail_lim(text, strlen(text), &lim, code, want);
}

static void expect_fail_bin(const api_buf *b, mcf_status code, const char *want)
{
    api_limits lim;
    api_limits_default(&lim);
    expect_fail_lim(b->data, b->len, &lim, code, want);
}

/* ------------------------------------------------------ reference writer */

typedef enum { A = 0, LE = 1, BE = 2 } fmt;

static const char *const types[] = {"char", "uchar", "short", "ushort", "int",
                                    "uint", "float", "double", "int8", "uint8",
                                    "int16", "uint16", "int32", "uint32",
                                    "float32", "float64"};
#define NTYPES ((int)(sizeof types / sizeof types[0]))

static size_t tsize(const char *t)
{
    if (!strcmp(t, "char") || !strcmp(t, "uchar") || !strcmp(t, "int8")
        || !strcmp(t, "uint8"))
        return 1;
    if (strstr(t, "short") || strstr(t, "16"))
        return 2;
    if (!strcmp(t, "double") || !strcmp(t, "float64"))
        return 8;
    return 4;
}

static int tfloat(const char *t)
{
    return !strncmp(t, "float", 5) || !strcmp(t, "double");
}

/* The value v as stored in type t (what a reader must give back). */
static double conv(const char *t, double v)
{
    if (!strcmp(t, "float") || !strcmp(t, "float32"))
        return (float)v;
    if (tfloat(t))
        return v;
    return (double)(long long)v; /* integer coordinates are integral here */
}

static void put(api_buf *b, fmt f, const char *t, double v)
{
    unsigned char raw[8], out[8];
    size_t n = tsize(t), i;
    if (f == A) {
        if (tfloat(t))
            api_buf_printf(b, " %.17g", conv(t, v));
        else
            api_buf_printf(b, " %lld", (long long)v);
        return;
    }
    if (!strcmp(t, "float") || !strcmp(t, "float32")) {
        float x = (float)v;
        memcpy(raw, &x, 4);
    } else if (tfloat(t)) {
        memcpy(raw, &v, 8);
    } else if (n == 1) {
        raw[0] = (unsigned char)(long long)v;
    } else if (n == 2) {
        int16_t x = (int16_t)(long long)v; /* same bits for ushort */
        memcpy(raw, &x, 2);
    } else {
        int32_t x = (int32_t)(long long)v;
        memcpy(raw, &x, 4);
    }
    for (i = 0; i < n; i++) /* the test host is little-endian (x86, arm) */
        out[i] = f == BE ? raw[n - 1 - i] : raw[i];
    api_buf_append(b, out, n);
}

static void endrow(api_buf *b, fmt f)
{
    if (f == A)
        api_buf_append(b, "\n", 1);
}

typedef struct {
    fmt f;
    const char *xyz;          /* type of x y z */
    const char *pre, *post;   /* extra scalar vertex props (NULL: none) */
    int vlist;                /* a list property inside vertex */
    const char *ct, *it;      /* face list count / item types */
    int index_name;           /* 1: "vertex_index" */
    int face_extra;           /* face props before and after the list */
    int other_first, other_last;  /* extra elements */
    int face_first;           /* face element before vertex */
    int quads;                /* pair triangles (0,1,2)(0,2,3) into quads */
} spec;

static void write_vertex_el(api_buf *b, const spec *s, const mcf_mesh *m)
{
    const double *X = mcf_mesh_positions(m);
    int i, k;
    for (i = 0; i < mcf_mesh_nvertices(m); i++) {
        if (s->pre)
            put(b, s->f, s->pre, 7);
        if (s->vlist) {
            put(b, s->f, "uchar", 2);
            put(b, s->f, "short", -5);
            put(b, s->f, "short", 9);
        }
        for (k = 0; k < 3; k++)
            put(b, s->f, s->xyz, X[3 * i + k]);
        if (s->post)
            put(b, s->f, s->post, 100);
        endrow(b, s->f);
    }
}

static void write_face_el(api_buf *b, const spec *s, const int32_t *F, int nf)
{
    int i, k;
    for (i = 0; i < nf; i++) {
        if (s->face_extra)
            put(b, s->f, "float", 0.5);
        if (s->quads && i + 1 < nf && F[3 * i] == F[3 * i + 3]
            && F[3 * i + 2] == F[3 * i + 4]) {
            const int32_t q[4] = {F[3 * i], F[3 * i + 1], F[3 * i + 2],
                                  F[3 * i + 5]};
            put(b, s->f, s->ct, 4);
            for (k = 0; k < 4; k++)
                put(b, s->f, s->it, q[k]);
            i++;
        } else {
            put(b, s->f, s->ct, 3);
            for (k = 0; k < 3; k++)
                put(b, s->f, s->it, F[3 * i + k]);
        }
        if (s->face_extra) {
            put(b, s->f, "uchar", 2);
            put(b, s->f, "int", 1);
            put(b, s->f, "int", 2);
        }
        endrow(b, s->f);
    }
}

static void write_other_el(api_buf *b, const spec *s)
{
    int i;
    for (i = 0; i < 3; i++) {
        put(b, s->f, "int", i);
        put(b, s->f, "uint", 2);
        put(b, s->f, "double", 1.5);
        put(b, s->f, "double", -2.5);
        put(b, s->f, "uchar", 255);
        endrow(b, s->f);
    }
}

/* Counts the faces the writer emits (quads merge two triangles). */
static int emitted_faces(const spec *s, const int32_t *F, int nf)
{
    int i, n = 0;
    for (i = 0; i < nf; i++, n++)
        if (s->quads && i + 1 < nf && F[3 * i] == F[3 * i + 3]
            && F[3 * i + 2] == F[3 * i + 4])
            i++;
    return n;
}

static void header_vertex(api_buf *b, const spec *s, int nv)
{
    api_buf_printf(b, "element vertex %d\n", nv);
    if (s->pre)
        api_buf_printf(b, "property %s pre\n", s->pre);
    if (s->vlist)
        api_buf_printf(b, "property list uchar short vl\n");
    api_buf_printf(b, "property %s x\nproperty %s y\nproperty %s z\n", s->xyz,
                   s->xyz, s->xyz);
    if (s->post)
        api_buf_printf(b, "property %s post\n", s->post);
}

static void header_face(api_buf *b, const spec *s, int nf)
{
    api_buf_printf(b, "element face %d\n", nf);
    if (s->face_extra)
        api_buf_printf(b, "property float q\n");
    api_buf_printf(b, "property list %s %s %s\n", s->ct, s->it,
                   s->index_name ? "vertex_index" : "vertex_indices");
    if (s->face_extra)
        api_buf_printf(b, "property list uchar int flags\n");
}

static void header_other(api_buf *b)
{
    api_buf_printf(b, "element edge 3\nproperty int vertex1\nproperty uint vertex2\n"
                      "property double a\nproperty double b\nproperty uchar red\n");
}

static void write_ply(api_buf *b, const spec *s, const mcf_mesh *m)
{
    const int32_t *F = mcf_mesh_faces(m);
    int nf = mcf_mesh_nfaces(m), nv = mcf_mesh_nvertices(m);
    api_buf_printf(b, "ply\nformat %s 1.0\ncomment reference writer\nobj_info test\n",
                   s->f == A ? "ascii" : s->f == LE ? "binary_little_endian"
                                                   : "binary_big_endian");
    if (s->other_first)
        header_other(b);
    if (s->face_first) {
        header_face(b, s, emitted_faces(s, F, nf));
        header_vertex(b, s, nv);
    } else {
        header_vertex(b, s, nv);
        header_face(b, s, emitted_faces(s, F, nf));
    }
    if (s->other_last)
        header_other(b);
    api_buf_printf(b, "end_header\n");
    if (s->other_first)
        write_other_el(b, s);
    if (s->face_first) {
        write_face_el(b, s, F, nf);
        write_vertex_el(b, s, m);
    } else {
        write_vertex_el(b, s, m);
        write_face_el(b, s, F, nf);
    }
    if (s->other_last)
        write_other_el(b, s);
}

static void check_spec(const spec *s, const mcf_mesh *m)
{
    api_buf b;
    mcf_mesh *d = NULL;
    mcf_error err;
    int nv = mcf_mesh_nvertices(m), i;
    api_buf_init(&b, 0);
    write_ply(&b, s, m);
    if (dec(b.data, b.len, &d, &err) != MCF_OK)
        fail_msg("format %d xyz %s ct %s it %s: %s", s->f, s->xyz, s->ct, s->it,
                 err.msg);
    assert_int_equal(mcf_mesh_nvertices(d), nv);
    for (i = 0; i < 3 * nv; i++)
        if (mcf_mesh_positions(d)[i] != conv(s->xyz, mcf_mesh_positions(m)[i]))
            fail_msg("format %d xyz %s: coordinate %d: %.17g, want %.17g", s->f,
                     s->xyz, i, mcf_mesh_positions(d)[i],
                     conv(s->xyz, mcf_mesh_positions(m)[i]));
    /* quads are fanned (v0 v1 v2)(v0 v2 v3): the original triangles */
    assert_int_equal(mcf_mesh_nfaces(d), mcf_mesh_nfaces(m));
    assert_memory_equal(mcf_mesh_faces(d), mcf_mesh_faces(m),
                        sizeof(int32_t) * 3 * (size_t)mcf_mesh_nfaces(m));
    mcf_mesh_free(d);
    api_buf_free(&b);
}

/* Every scalar type for x y z in every body format, with integer
 * coordinates (so that each integer type holds them) for integer types. */
static void test_reference_types(void **state)
{
    mcf_mesh *m = tl_load("bunny_npm_closed.obj"), *mi;
    mcf_error err;
    int nv = mcf_mesh_nvertices(m), i, t, f;
    double *Xi = malloc(sizeof *Xi * 3 * (size_t)nv);
    (void)state;
    assert_non_null(Xi);
    /* 0..120 fits char, uchar and every wider type */
    for (i = 0; i < 3 * nv; i++)
        Xi[i] = floor(60.0 + 6.0 * mcf_mesh_positions(m)[i]);
    mi = mcf_mesh_new(nv, Xi, mcf_mesh_nfaces(m), mcf_mesh_faces(m), &err);
    assert_non_null(mi);
    for (f = A; f <= BE; f++)
        for (t = 0; t < NTYPES; t++) {
            spec s = {(fmt)f, types[t], NULL, NULL, 0, "uchar", "int", 0, 0, 0, 0, 0, 0};
            check_spec(&s, tfloat(types[t]) ? m : mi);
        }
    free(Xi);
    mcf_mesh_free(mi);
    mcf_mesh_free(m);
}

/* Extra properties of every type around x y z, list properties in vertex
 * and face, every list count/item type, vertex_index, other elements,
 * face element first, quads. */
static void test_reference_layouts(void **state)
{
    static const char *const counts[] = {"uchar", "char", "ushort", "short",
                                         "int", "uint", "uint8", "int32"};
    static const char *const items[] = {"int", "uint", "int32", "uint32"};
    mcf_mesh *m = tl_load("sphere_cgal.obj");
    int f, t, c, it;
    (void)state;
    for (f = A; f <= BE; f++) {
        for (t = 0; t < NTYPES; t++) {
            spec s = {(fmt)f, "double", types[t], types[(t + 5) % NTYPES], t & 1,
                      "uchar", "int", t & 1, t % 3 == 0, t % 4 == 1, t % 4 == 2,
                      t % 5 == 3, t % 2 == 0};
            check_spec(&s, m);
        }
        for (c = 0; c < (int)(sizeof counts / sizeof counts[0]); c++)
            for (it = 0; it < (int)(sizeof items / sizeof items[0]); it++) {
                spec s = {(fmt)f, "float", NULL, NULL, 0, counts[c], items[it],
                          (c + it) & 1, 0, 0, 0, 0, 1};
                check_spec(&s, m);
            }
    }
    /* indices in short/ushort items: a mesh under 32768 vertices */
    {
        spec s = {LE, "float", NULL, NULL, 0, "uchar", "ushort", 0, 0, 0, 0, 0, 0};
        check_spec(&s, m);
        s.it = "short";
        s.f = BE;
        check_spec(&s, m);
        s.f = A;
        check_spec(&s, m);
    }
    mcf_mesh_free(m);
}

/* Polygons of 4..6 vertices are fanned from their first vertex. */
static void test_polygons(void **state)
{
    static const char text[] =
        "ply\r\nformat ascii 1.0\r\nelement vertex 6\r\nproperty float x\r\n"
        "property float y\r\nproperty float z\r\nelement face 3\r\n"
        "property list uchar int vertex_indices\r\nend_header\r\n"
        "0 0 0\r\n1 0 0\r\n1 1 0\r\n0 1 0\r\n0 2 0\r\n1 2 0\r\n"
        "4 0 1 2 3\r\n\r\n5 3 2 5 4 0\r\n6 0 1 2 3 4 5\r\n";
    static const int32_t want[] = {0, 1, 2, 0, 2, 3, 3, 2, 5, 3, 5, 4, 3, 4, 0,
                                   0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 5};
    mcf_mesh *m;
    mcf_error err;
    (void)state;
    assert_int_equal(dec(text, strlen(text), &m, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 9);
    assert_memory_equal(mcf_mesh_faces(m), want, sizeof want);
    mcf_mesh_free(m);
}

/* A polygon fanning into more triangles than its mesh's declared counts
 * pay for is refused before it is built (issue 28): a 10 MB binary PLY,
 * 3 vertices and one face of 10,000,002 uchar corners, fanned into
 * 10,000,000 triangles (within max_faces) and peaked at 474 MiB in the
 * daemon before its 422; the budget is 2 x the vertices (or the faces
 * declared) + an eighth + 1024, here 1030. A convex polygon of 250
 * corners on 250 vertices (248 triangles) still decodes. */
static void test_polygon_fan_budget(void **state)
{
    const unsigned nvs[] = {3, 250};
    const uint32_t corners[] = {10000002u, 250u};
    mcf_mesh *m = NULL;
    mcf_error err;
    int t;
    (void)state;
    for (t = 0; t < 2; t++) {
        char head[300];
        size_t hl, n, i;
        unsigned char *buf;
        mcf_status st;
        hl = (size_t)snprintf(head, sizeof head,
                              "ply\nformat binary_little_endian 1.0\nelement vertex %u\n"
                              "property float x\nproperty float y\nproperty float z\n"
                              "element face 1\nproperty list uint uchar vertex_indices\n"
                              "end_header\n", nvs[t]);
        n = hl + 12 * nvs[t] + 4 + corners[t];
        assert_non_null(buf = malloc(n));
        memcpy(buf, head, hl);
        for (i = 0; i < nvs[t]; i++) {      /* a circle: a convex polygon */
            float v[3] = {(float)cos(6.283185307179586 * (double)i / nvs[t]),
                          (float)sin(6.283185307179586 * (double)i / nvs[t]), 0};
            memcpy(buf + hl + 12 * i, v, 12);
        }
        memcpy(buf + hl + 12 * nvs[t], &corners[t], 4);
        for (i = 0; i < corners[t]; i++)
            buf[hl + 12 * nvs[t] + 4 + i] = (unsigned char)(i % nvs[t]);
        st = dec(buf, n, &m, &err);
        free(buf);
        if (t == 0) {
            assert_int_equal(st, MCF_ELIMIT);
            assert_non_null(strstr(err.msg, "10000002 corners"));
            assert_non_null(strstr(err.msg, "more than 1030 triangles"));
        } else {
            if (st != MCF_OK)
                fail_msg("a 250-corner polygon: %s", err.msg);
            assert_int_equal(mcf_mesh_nfaces(m), 248);
            mcf_mesh_free(m);
        }
    }
}

/* ----------------------------------------------------------- round trips */

static void roundtrip(const char *file, int binary)
{
    mcf_mesh *m = tl_load(file), *d = NULL;
    api_encode_opts o;
    api_buf b;
    mcf_error err;
    api_format f;
    api_encode_opts_init(&o);
    o.format = API_FMT_PLY;
    o.ply_binary = binary;
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    if (api_mesh_decode(b.data, b.len, NULL, &d, &f, &err) != MCF_OK)
        fail_msg("%s: %s", file, err.msg);
    assert_int_equal(f, API_FMT_PLY);
    tl_assert_same_mesh(m, d);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
    api_buf_free(&b);
}

static void test_roundtrip(void **state)
{
    (void)state;
    roundtrip("bunny_npm_closed.obj", 0);
    roundtrip("bunny_npm_closed.obj", 1);
    roundtrip("test_nm.obj", 0);          /* unreferenced vertices */
    roundtrip("test_nm.obj", 1);
    roundtrip("car.drc", 1);
}

/* The same on the large scans of $MCF_MESHES. */
static void test_roundtrip_scans(void **state)
{
    (void)state;
    roundtrip("spot.obj", 0);
    roundtrip("spot.obj", 1);
    roundtrip("stanford-bunny.obj", 0);   /* unreferenced vertices */
    roundtrip("stanford-bunny.obj", 1);
    roundtrip("dragon_vrip_res2.obj", 1); /* duplicate, non-manifold faces */
}

/* Big-endian: the model writes BE from the writer's LE output values. */
static void test_roundtrip_be(void **state)
{
    mcf_mesh *m = tl_load("knot1.obj");
    spec s = {BE, "double", NULL, NULL, 0, "uchar", "int", 0, 0, 0, 0, 0, 0};
    (void)state;
    check_spec(&s, m);
    s.f = LE;
    check_spec(&s, m);
    mcf_mesh_free(m);
}

/* Curvature properties: declared in the header, values stored as float
 * (binary: at the right offsets; ascii: the float's digits), skipped by
 * the reader. */
static void test_curvature_properties(void **state)
{
    static const double X[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const int32_t F[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
    static const double H[] = {0.1, -2.5, 1e-3, 3};
    static const double K[] = {7, 8, 9, 1.0 / 3};
    mcf_error err;
    mcf_mesh *m = mcf_mesh_new(4, X, 4, F, &err), *d;
    api_encode_opts o;
    api_buf b;
    const char *body;
    int i, binary;
    (void)state;
    assert_non_null(m);
    for (binary = 0; binary <= 1; binary++) {
        api_encode_opts_init(&o);
        o.ply_binary = binary;
        o.ply_mean_curvature = H;
        o.ply_gaussian_curvature = K;
        api_buf_init(&b, 0);
        assert_int_equal(api_ply_encode(m, &o, &b, &err), MCF_OK);
        assert_non_null(strstr(b.data, "property double z\nproperty float "
                                       "mean_curvature\nproperty float "
                                       "gaussian_curvature\nelement face 4\n"));
        body = strstr(b.data, "end_header\n") + 11;
        for (i = 0; i < 4; i++) {
            float h, k;
            if (binary) {
                memcpy(&h, body + 32 * i + 24, 4);
                memcpy(&k, body + 32 * i + 28, 4);
            } else {
                double x, y, z;
                int used = 0;
                assert_int_equal(sscanf(body, "%lf %lf %lf %f %f%n", &x, &y, &z, &h,
                                        &k, &used),
                                 5);
                body += used + 1;
            }
            assert_true(h == (float)H[i] && k == (float)K[i]);
        }
        assert_int_equal(dec(b.data, b.len, &d, &err), MCF_OK);
        assert_memory_equal(mcf_mesh_positions(d), X, sizeof X);
        assert_memory_equal(mcf_mesh_faces(d), F, sizeof F);
        mcf_mesh_free(d);
        api_buf_free(&b);
    }
    /* only one of them */
    api_encode_opts_init(&o);
    o.ply_gaussian_curvature = K;
    api_buf_init(&b, 0);
    assert_int_equal(api_ply_encode(m, &o, &b, &err), MCF_OK);
    assert_null(strstr(b.data, "mean_curvature"));
    assert_non_null(strstr(b.data, "property float gaussian_curvature\n"));
    assert_int_equal(dec(b.data, b.len, &d, &err), MCF_OK);
    mcf_mesh_free(d);
    /* output maximum: ELIMIT and the buffer as it was */
    api_buf_free(&b);
    api_buf_init(&b, 100);
    assert_int_equal(api_buf_append(&b, "abc", 3), MCF_OK);
    assert_int_equal(api_ply_encode(m, &o, &b, &err), MCF_ELIMIT);
    assert_int_equal(b.len, 3);
    assert_string_equal(b.data, "abc");
    api_buf_free(&b);
    mcf_mesh_free(m);
}

/* draco_decoder writes binary PLY with float positions: it must match our
 * own Draco decoding of the same file exactly. */
static void test_draco_decoder_ply(void **state)
{
    char tmpl[] = "/tmp/mcf_ply_XXXXXX", *dir, cmd[1024], out[512], *buf;
    size_t len;
    mcf_mesh *ref, *d;
    mcf_error err;
    int f;
    (void)state;
    if (system("command -v draco_decoder >/dev/null 2>&1") != 0)
        skip();
    dir = mkdtemp(tmpl);
    assert_non_null(dir);
    snprintf(out, sizeof out, "%s/bunny.ply", dir);
    snprintf(cmd, sizeof cmd, "draco_decoder -i %s -o %s >/dev/null 2>&1",
             tl_need_mesh("bunny.drc"), out);
    assert_int_equal(system(cmd), 0);
    assert_int_equal(tl_read_file(out, &buf, &len), 0);
    remove(out);
    rmdir(dir);
    assert_int_equal(dec(buf, len, &d, &err), MCF_OK);
    ref = tl_load("bunny.drc");
    assert_int_equal(mcf_mesh_nvertices(d), 34834);
    assert_int_equal(mcf_mesh_nfaces(d), 69451);
    /* Same faces in the same order; draco_decoder numbers vertices by
     * point, we by position value: compare corner by corner. */
    for (f = 0; f < 3 * 69451; f++) {
        const double *p = mcf_mesh_positions(d) + 3 * mcf_mesh_faces(d)[f];
        const double *q = mcf_mesh_positions(ref) + 3 * mcf_mesh_faces(ref)[f];
        if (memcmp(p, q, 3 * sizeof *p) != 0)
            fail_msg("corner %d: %.9g %.9g %.9g vs %.9g %.9g %.9g", f, p[0], p[1],
                     p[2], q[0], q[1], q[2]);
    }
    mcf_mesh_free(d);
    mcf_mesh_free(ref);
    free(buf);
}

/* --------------------------------------------------------- hostile input */

#define HDR_V "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n" \
              "property float y\nproperty float z\n"
#define HDR_F "element face 1\nproperty list uchar int vertex_indices\n"
#define TRI "0 0 0\n1 0 0\n0 1 0\n"

static void test_header_errors(void **state)
{
    (void)state;
    expect_fail("", MCF_EDECODE, "ply: empty input");
    expect_fail("plx\n", MCF_EDECODE, "ply: line 1 must be 'ply' alone");
    expect_fail("ply", MCF_EDECODE, "ply: line 1 must be 'ply' alone");
    expect_fail("ply foo\n", MCF_EDECODE, "ply: line 1 must be 'ply' alone");
    expect_fail("ply\nformat ascii 2.0\n", MCF_EDECODE,
                "ply: line 2: format version must be 1.0");
    expect_fail("ply\nformat xml 1.0\n", MCF_EDECODE,
                "ply: line 2: unknown format 'xml' (ascii, binary_little_endian, "
                "binary_big_endian)");
    expect_fail("ply\nformat ascii 1.0\nformat ascii 1.0\n", MCF_EDECODE,
                "ply: line 3: second format line");
    expect_fail("ply\nformat ascii 1.0\n", MCF_EDECODE, "ply: no end_header line");
    expect_fail("ply\nend_header\n", MCF_EDECODE,
                "ply: line 2: end_header before any format line");
    expect_fail("ply\nformat ascii 1.0\nend_header junk\n", MCF_EDECODE,
                "ply: line 3: text after end_header");
    expect_fail("ply\nformat ascii 1.0\n\nend_header\n", MCF_EDECODE,
                "ply: line 3: empty header line");
    expect_fail("ply\nformat ascii 1.0\nproperty float x\n", MCF_EDECODE,
                "ply: line 3: property before any element");
    expect_fail("ply\nelement vertex 1\nformat ascii 1.0\n", MCF_EDECODE,
                "ply: line 3: format line after an element");
    expect_fail("ply\nformat ascii 1.0\nelement vertex -3\n", MCF_EDECODE,
                "ply: line 3: bad element count '-3'");
    expect_fail("ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n",
                MCF_EDECODE, "ply: line 3: bad element count '9999");
    expect_fail("ply\nformat ascii 1.0\nelement vertex\n", MCF_EDECODE,
                "ply: line 3: 'element <name> <count>' expected");
    expect_fail("ply\nformat ascii 1.0\nelement vertex 1\nelement vertex 1\n",
                MCF_EDECODE, "ply: line 4: element 'vertex' declared twice");
    expect_fail("ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\n",
                MCF_EDECODE, "ply: line 4: unknown property type 'flot'");
    expect_fail("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float x\n",
                MCF_EDECODE, "ply: line 5: property 'x' declared twice");
    expect_fail("ply\nformat ascii 1.0\nelement vertex 1\nproperty float\n",
                MCF_EDECODE, "ply: line 4: 'property [list <count> <item>] <type> "
                             "<name>' expected");
    expect_fail("ply\nformat ascii 1.0\nelement face 1\n"
                "property list float int vertex_indices\n",
                MCF_EDECODE, "ply: line 4: list count type 'float' is not an integer type");
    expect_fail("ply\nformat ascii 1.0\nelement face 1\n"
                "property list uchar foo vertex_indices\n",
                MCF_EDECODE, "ply: line 4: unknown property type 'foo'");
    expect_fail("ply\nformat ascii 1.0\nelement face 1\n"
                "property list huge int vertex_indices\n",
                MCF_EDECODE, "ply: line 4: unknown list count type 'huge'");
    expect_fail("ply\nformat ascii 1.0\nelement face 1\n"
                "property list uchar float vertex_indices\n",
                MCF_EDECODE, "ply: line 4: face indices must have an integer type");
    expect_fail("ply\nformat ascii 1.0\nelement face 1\nproperty int vertex_indices\n",
                MCF_EDECODE, "ply: line 4: face property 'vertex_indices' must be a list");
    expect_fail("ply\nformat ascii 1.0\nelement face 1\n"
                "property list uchar int vertex_indices\n"
                "property list uchar int vertex_index\n",
                MCF_EDECODE, "ply: line 5: both vertex_indices and vertex_index");
    expect_fail("ply\nformat ascii 1.0\nfoo bar\n", MCF_EDECODE,
                "ply: line 3: unknown header keyword 'foo'");
    expect_fail("ply\nformat ascii 1.0\n" HDR_F "end_header\n3 0 1 2\n", MCF_EDECODE,
                "ply: no 'vertex' element");
    expect_fail("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                "property float y\n" HDR_F "end_header\n" TRI "3 0 1 2\n",
                MCF_EDECODE, "ply: element 'vertex' lacks property 'z'");
    expect_fail(HDR_V "end_header\n" TRI, MCF_EDECODE,
                "ply: no 'face' element (a point cloud is not a mesh)");
    expect_fail(HDR_V "element face 1\nproperty list uchar int other\nend_header\n"
                TRI "3 0 1 2\n",
                MCF_EDECODE, "ply: element 'face' has no 'vertex_indices' list");
}

static void test_body_errors(void **state)
{
    api_limits lim;
    (void)state;
    expect_fail(HDR_V HDR_F "end_header\n" TRI "3 0 1 7\n", MCF_EDECODE,
                "ply: line 13: face 0: index 7 out of range (0..2)");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "3 0 1 -1\n", MCF_EDECODE,
                "ply: line 13: face 0: index -1 out of range (0..2)");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "3 0 1 x\n", MCF_EDECODE,
                "ply: line 13: bad index 'x'");
    /* (padded: shorter than "3 a b c" the body-size check would refuse it) */
    expect_fail(HDR_V HDR_F "end_header\n" TRI "2 0 1    \n", MCF_EDECODE,
                "ply: line 13: face 0 has 2 vertices, at least 3 needed");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "4 0 1 2\n", MCF_EDECODE,
                "ply: line 13: face 0: list 'vertex_indices' has 3 of 4 values");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "-4 0 1 2\n", MCF_EDECODE,
                "ply: line 13: bad list length '-4'");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "3 0 1 2 5\n", MCF_EDECODE,
                "ply: line 13: face 0 has more values than its 1 properties");
    expect_fail(HDR_V HDR_F "end_header\n0 0 0\n1 0  \n0 1 0\n3 0 1 2\n", MCF_EDECODE,
                "ply: line 11: vertex 1: value for 'z' missing");
    expect_fail(HDR_V HDR_F "end_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n",
                MCF_EDECODE, "ply: line 11: coordinate 'nan' is not finite");
    expect_fail(HDR_V HDR_F "end_header\n0 0 0\n1 0 1e999\n0 1 0\n3 0 1 2\n",
                MCF_EDECODE, "ply: line 11: coordinate '1e999' is not finite");
    expect_fail(HDR_V HDR_F "end_header\n0 0 0\n1 0 zz\n0 1 0\n3 0 1 2\n",
                MCF_EDECODE, "ply: line 11: bad number 'zz'");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "\n\n\n\n\n\n\n\n", MCF_EDECODE,
                "ply: line 20: input ends before face 0 of 1");
    expect_fail(HDR_V HDR_F "end_header\n" TRI, MCF_EDECODE,
                "ply: header declares 1 'face' elements, more than the 18-byte "
                "body can hold");
    expect_fail(HDR_V HDR_F "end_header\n" TRI "3 0 1 2\n7 7 7\n", MCF_EDECODE,
                "ply: line 14: data after the last element");
    /* huge counts over a tiny body: refused before any allocation */
    expect_fail("ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\n"
                "property float y\nproperty float z\n" HDR_F "end_header\n" TRI
                "3 0 1 2\n",
                MCF_EDECODE, "ply: header declares 4000000000 'vertex' elements, "
                             "more than the 26-byte body can hold");
    expect_fail(HDR_V "element face 18446744073709551615\n"
                "property list uchar int vertex_indices\nend_header\n" TRI "3 0 1 2\n",
                MCF_EDECODE, "ply: header declares 18446744073709551615 'face' "
                             "elements");
    expect_fail(HDR_V HDR_F "element junk 1000000\nproperty char a\nend_header\n"
                TRI "3 0 1 2\n",
                MCF_EDECODE, "ply: header declares 1000000 'junk' elements");
    /* zero counts */
    expect_fail("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                "property float y\nproperty float z\n" HDR_F "end_header\n3 0 1 2\n",
                MCF_EDECODE, "ply: no vertices");
    expect_fail(HDR_V "element face 0\nproperty list uchar int vertex_indices\n"
                "end_header\n" TRI,
                MCF_EDECODE, "ply: no faces: 3 vertices only");
    /* limits, with bodies that do hold the counts */
    api_limits_default(&lim);
    lim.max_vertices = 2;
    expect_fail_lim(HDR_V HDR_F "end_header\n" TRI "3 0 1 2\n",
                    strlen(HDR_V HDR_F "end_header\n" TRI "3 0 1 2\n"), &lim,
                    MCF_ELIMIT, "ply: 3 vertices exceed max_vertices (2)");
    api_limits_default(&lim);
    lim.max_faces = 2;
    expect_fail_lim(HDR_V HDR_F "end_header\n" TRI "5 0 1 2 0 1\n",
                    strlen(HDR_V HDR_F "end_header\n" TRI "5 0 1 2 0 1\n"), &lim,
                    MCF_ELIMIT, "ply: face 0: more than max_faces (2) triangles");
    api_limits_default(&lim);
    lim.max_input_bytes = 10;
    expect_fail_lim(HDR_V, strlen(HDR_V), &lim, MCF_ELIMIT,
                    "ply: input of 89 bytes exceeds max_input_bytes (10)");
}

/* A binary header + body built by hand. */
static void bin_tri(api_buf *b, const char *fmtname, const float *xyz, int n,
                    const unsigned char *face, size_t facelen, const char *extra)
{
    api_buf_init(b, 0);
    api_buf_printf(b, "ply\nformat %s 1.0\nelement vertex %d\nproperty float x\n"
                      "property float y\nproperty float z\nelement face 1\n"
                      "property list char int vertex_indices\n%send_header\n",
                   fmtname, n, extra);
    api_buf_append(b, xyz, sizeof(float) * 3 * (size_t)n);
    api_buf_append(b, face, facelen);
}

static void test_binary_errors(void **state)
{
    static const float xyz[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    static const unsigned char ok[] = {3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0};
    static const unsigned char big[] = {3, 0, 0, 0, 0, 1, 0, 0, 0, 9, 0, 0, 0};
    static const unsigned char neg[] = {0xff, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0};
    static const unsigned char two[] = {2, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0};
    static const unsigned char more[] = {5, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0};
    float nanxyz[9];
    api_buf b;
    mcf_mesh *m;
    mcf_error err;
    size_t cut, body;
    (void)state;

    bin_tri(&b, "binary_little_endian", xyz, 3, ok, sizeof ok, "");
    assert_int_equal(dec(b.data, b.len, &m, &err), MCF_OK);
    mcf_mesh_free(m);
    /* fixed-size rows: every truncation of the body is caught by the
     * body-size check before reading, naming the element and the size */
    body = b.len - sizeof xyz - sizeof ok;
    for (cut = body; cut < b.len; cut++) {
        char want[128];
        mcf_status rc = dec(b.data, cut, &m, &err);
        snprintf(want, sizeof want, "ply: header declares %s, more than the "
                                    "%zu-byte body can hold",
                 cut < body + sizeof xyz ? "3 'vertex' elements" : "1 'face' elements",
                 cut - body);
        if (rc != MCF_EDECODE || !strstr(err.msg, want))
            fail_msg("cut at %zu: %s \"%s\", want \"%s\"", cut, mcf_status_name(rc),
                     err.msg, want);
    }
    /* truncated inside the header */
    for (cut = 1; cut < body; cut++) {
        mcf_status rc = dec(b.data, cut, &m, &err);
        if (rc != MCF_EDECODE || strncmp(err.msg, "ply: ", 5) != 0)
            fail_msg("header cut at %zu: %s \"%s\"", cut, mcf_status_name(rc), err.msg);
    }
    api_buf_append(&b, "x", 1);
    expect_fail_bin(&b, MCF_EDECODE, "ply: 1 bytes after the last element (byte 49)");
    api_buf_free(&b);

    bin_tri(&b, "binary_little_endian", xyz, 3, big, sizeof big, "");
    expect_fail_bin(&b, MCF_EDECODE, "ply: face 0: index 9 out of range (0..2)");
    api_buf_free(&b);
    bin_tri(&b, "binary_little_endian", xyz, 3, neg, sizeof neg, "");
    expect_fail_bin(&b, MCF_EDECODE, "ply: face 0: negative list length -1");
    api_buf_free(&b);
    bin_tri(&b, "binary_little_endian", xyz, 3, two, sizeof two, "");
    expect_fail_bin(&b, MCF_EDECODE, "ply: face 0 has 2 vertices, at least 3 needed");
    api_buf_free(&b);
    bin_tri(&b, "binary_little_endian", xyz, 3, more, sizeof more, "");
    expect_fail_bin(&b, MCF_EDECODE, "ply: body ends inside face 0 of 1");
    api_buf_free(&b);
    memcpy(nanxyz, xyz, sizeof nanxyz);
    nanxyz[4] = NAN;
    bin_tri(&b, "binary_little_endian", nanxyz, 3, ok, sizeof ok, "");
    expect_fail_bin(&b, MCF_EDECODE, "ply: vertex 1: coordinate y is not finite");
    api_buf_free(&b);
    /* big-endian reading of little-endian bytes: index 0x03000000 */
    bin_tri(&b, "binary_big_endian", xyz, 3, ok, sizeof ok, "");
    expect_fail_bin(&b, MCF_EDECODE, "ply: face 0: index 16777216 out of range");
    api_buf_free(&b);
    /* huge counts over a tiny binary body */
    bin_tri(&b, "binary_little_endian", xyz, 3, ok, sizeof ok,
            "element extra 2000000000\nproperty double a\n");
    expect_fail_bin(&b, MCF_EDECODE,
                    "ply: header declares 2000000000 'extra' elements, more than the "
                    "49-byte body can hold");
    api_buf_free(&b);
    /* an element without properties takes no bytes, whatever its count */
    bin_tri(&b, "binary_little_endian", xyz, 3, ok, sizeof ok,
            "element nothing 18446744073709551615\n");
    assert_int_equal(dec(b.data, b.len, &m, &err), MCF_OK);
    mcf_mesh_free(m);
    api_buf_free(&b);
}

/* Every prefix of an ASCII file fails with a "ply: " message or, where
 * only trailing white space was cut, decodes. */
static void test_ascii_truncations(void **state)
{
    static const char text[] = HDR_V HDR_F "end_header\n" TRI "3 0 1 2\n";
    size_t cut, n = strlen(text);
    (void)state;
    for (cut = 0; cut < n; cut++) {
        mcf_mesh *m;
        mcf_error err;
        mcf_status rc = dec(text, cut, &m, &err);
        if (cut == n - 1) {
            assert_int_equal(rc, MCF_OK); /* only the final newline is missing */
            mcf_mesh_free(m);
            continue;
        }
        if (rc != MCF_EDECODE || strncmp(err.msg, "ply: ", 5) != 0)
            fail_msg("cut at %zu: %s \"%s\"", cut, mcf_status_name(rc), err.msg);
    }
}

/* Deterministic garbage: random bytes after "ply\n", and random bytes in
 * the body of a valid binary file: never a crash, always a message. */
static void test_garbage(void **state)
{
    uint64_t s = 0x2545f4914f6cdd1dull;
    int trial;
    mcf_mesh *m = tl_load("sphere_cgal.obj");
    api_encode_opts o;
    api_buf good;
    mcf_error err;
    (void)state;
    api_encode_opts_init(&o);
    api_buf_init(&good, 0);
    assert_int_equal(api_ply_encode(m, &o, &good, &err), MCF_OK);
    for (trial = 0; trial < 300; trial++) {
        unsigned char buf[600];
        size_t len = 4 + (size_t)(trial * 7 % 590), i;
        mcf_mesh *d;
        mcf_status rc;
        memcpy(buf, "ply\n", 4);
        for (i = 4; i < len; i++) {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            buf[i] = (unsigned char)s;
        }
        rc = dec(buf, len, &d, &err);
        assert_int_equal(rc, MCF_EDECODE);
        assert_true(strncmp(err.msg, "ply: ", 5) == 0);
        /* corrupt 8 bytes of the binary body */
        {
            char *c = malloc(good.len);
            size_t body = (size_t)(strstr(good.data, "end_header\n") + 11 - good.data);
            assert_non_null(c);
            memcpy(c, good.data, good.len);
            for (i = 0; i < 8; i++) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                c[body + s % (good.len - body)] = (char)(s >> 32);
            }
            rc = dec(c, good.len, &d, &err);
            if (rc == MCF_OK)
                mcf_mesh_free(d);
            else if (strncmp(err.msg, "ply: ", 5) != 0)
                fail_msg("corrupt body: %s \"%s\"", mcf_status_name(rc), err.msg);
            free(c);
        }
    }
    api_buf_free(&good);
    mcf_mesh_free(m);
}

/* ------------------------------------------------------------ attributes */

/* A 3x2 strip of quads in OBJ text with a UV seam between the second and
 * third column (the right column's corners use their own vt values),
 * per-vertex colours and normals on every corner. */
static const char strip_obj[] =
    "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 2 0 0.25 0 0 1\nv 3 0 0 0.5 0.5 0\n"
    "v 0 1 0 1 1 1\nv 1 1 0.5 0 0 0\nv 2 1 0 0.2 0.4 0.6\nv 3 1 0 1 0 1\n"
    "vt 0 0\nvt 0.25 0\nvt 0.5 0\nvt 0 1\nvt 0.25 1\nvt 0.5 1\n"
    "vt 0.75 0\nvt 1 0\nvt 0.75 1\nvt 1 1\n"
    "vn 0 0 1\n"
    "f 1/1/1 2/2/1 6/5/1 5/4/1\nf 2/2/1 3/3/1 7/6/1 6/5/1\n"
    "f 3/7/1 4/8/1 8/10/1 7/9/1\n";

/* The decoded strip and its attributes. */
static mcf_mesh *strip(api_attrs **a)
{
    mcf_mesh *m = NULL;
    mcf_error err;
    if (api_obj_decode_attrs(strip_obj, sizeof strip_obj - 1, NULL, &m, a, &err)
        != MCF_OK)
        fail_msg("strip: %s", err.msg);
    return m;
}

/* Attribute k of a and b agree corner by corner (same face order), within
 * tol. */
static void assert_same_attr(const api_attrs *a, const api_attrs *b, int nf,
                             api_attr_kind k, double tol, const char *what)
{
    int na, nb, c, i;
    const double *va, *vb;
    const int32_t *ca, *cb;
    assert_true(api_attrs_get(a, k, &na, NULL, &va, &ca));
    if (!api_attrs_get(b, k, &nb, NULL, &vb, &cb))
        fail_msg("%s: attribute %d lost", what, (int)k);
    assert_int_equal(na, nb);
    for (c = 0; c < 3 * nf; c++)
        for (i = 0; i < na; i++)
            if (!(fabs(va[na * ca[c] + i] - vb[nb * cb[c] + i]) <= tol))
                fail_msg("%s: attribute %d corner %d: %.17g vs %.17g", what, (int)k,
                         c, va[na * ca[c] + i], vb[nb * cb[c] + i]);
}

/* The strip to PLY (binary and ASCII) and back: texcoords (with their
 * seam, through the face `texcoord` list) and colours exactly, normals
 * recomputed per vertex (the strip bends, so they differ from the input's
 * single +z), positions float (OBJ text of few digits is single
 * precision). */
static void test_ply_attrs(void **state)
{
    api_attrs *a = NULL;
    mcf_mesh *m = strip(&a);
    int bin;
    (void)state;
    assert_int_equal(api_attrs_float32(a), 1);
    for (bin = 0; bin < 2; bin++) {
        api_encode_opts o;
        api_buf b;
        mcf_error err;
        mcf_mesh *d = NULL;
        api_attrs *da = NULL;
        const double *N;
        int nn, c;
        api_encode_opts_init(&o);
        o.format = API_FMT_PLY;
        o.ply_binary = bin;
        o.attrs = a;
        api_buf_init(&b, 0);
        assert_int_equal(api_ply_encode(m, &o, &b, &err), MCF_OK);
        assert_non_null(strstr(b.data, "property float x\n"));
        assert_non_null(strstr(b.data, "property float nx\n"));
        assert_non_null(strstr(b.data, "property uchar red\n"));
        assert_non_null(strstr(b.data, "property list uchar float texcoord\n"));
        assert_null(strstr(b.data, "curvature"));
        assert_int_equal(api_ply_decode_attrs(b.data, b.len, NULL, &d, &da, &err),
                         MCF_OK);
        assert_int_equal(api_attrs_float32(da), 1);
        tl_assert_same_mesh(m, d);
        assert_same_attr(a, da, 6, API_ATTR_TEXCOORD, 0.0, "texcoord");
        /* OBJ's float colours go out as bytes: within half a step */
        assert_same_attr(a, da, 6, API_ATTR_COLOR, 0.5 / 255 + 1e-12, "colour");
        assert_true(api_attrs_get(da, API_ATTR_NORMAL, &nn, NULL, &N, NULL));
        for (c = 0; c < 8; c++)
            tl_assert_near(N[3 * c] * N[3 * c] + N[3 * c + 1] * N[3 * c + 1]
                               + N[3 * c + 2] * N[3 * c + 2],
                           1.0, 1e-6, "|n|^2");
        /* the bumps (vertices 3 and 6) tilt some normals off the input's
         * +z, none past the horizontal */
        {
            double tilt = 0;
            for (c = 0; c < 8; c++) {
                assert_true(N[3 * c + 2] > 0.3);
                tilt = fmax(tilt, fabs(N[3 * c]) + fabs(N[3 * c + 1]));
            }
            assert_true(tilt > 0.1);
        }
        api_attrs_free(da);
        mcf_mesh_free(d);
        api_buf_free(&b);
    }
    api_attrs_free(a);
    mcf_mesh_free(m);
}

/* Vertex properties the attributes do not model (a scanner's quality and
 * confidence, a signed short, an int) pass through a smoothing's decode
 * and encode as they came: the same names, types and values, in ASCII
 * and binary, and again after a second round; what cannot pass (a vertex
 * list, a face scalar, another element) is named by api_attrs_not_kept,
 * which names the scalars too for a format without them. */
static void test_ply_passthrough(void **state)
{
    static const char src[] =
        "ply\nformat ascii 1.0\nelement vertex 4\n"
        "property double x\nproperty double y\nproperty double z\n"
        "property float quality\nproperty uchar confidence\nproperty short s16\n"
        "property int i32\nproperty list uchar int ring\n"
        "element face 4\nproperty list uchar int vertex_indices\nproperty int tag\n"
        "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
        "0 0 0 0.25 0 -32768 -7 0\n1 0 0 1.5 17 -1 2147483647 1 3\n"
        "0 1 0 2.75 200 12 0 0\n0 0 1 3.125 255 32767 -2147483648 0\n"
        "3 0 2 1 7\n3 0 1 3 7\n3 0 3 2 7\n3 1 2 3 7\n0 1\n";
    static const char *const decl[] = {"property float quality\n", "property uchar confidence\n",
                                       "property short s16\n", "property int i32\n"};
    /* the values as written above, per property, per vertex */
    static const double want[4][4] = {{0.25, 1.5, 2.75, 3.125}, {0, 17, 200, 255},
                                      {-32768, -1, 12, 32767},
                                      {-7, 2147483647.0, 0, -2147483648.0}};
    char names[256];
    mcf_error err;
    mcf_mesh *m = NULL;
    api_attrs *a = NULL;
    int bin, round, k, v;
    (void)state;
    assert_int_equal(api_ply_decode_attrs(src, sizeof src - 1, NULL, &m, &a, &err), MCF_OK);
    assert_int_equal(api_attrs_not_kept(a, API_FMT_PLY, names, sizeof names), 3);
    assert_string_equal(names, "vertex ring (a list), face tag, element edge");
    assert_int_equal(api_attrs_not_kept(a, API_FMT_OBJ, names, sizeof names), 7);
    assert_string_equal(names, "vertex quality, vertex confidence, vertex s16, vertex i32, "
                               "vertex ring (a list), face tag, element edge");
    assert_int_equal(api_attrs_not_kept(a, API_FMT_OBJ, names, 20), 7);
    assert_string_equal(names, "vertex quality, ...");
    assert_int_equal(api_attrs_not_kept(NULL, API_FMT_OBJ, names, sizeof names), 0);
    assert_string_equal(names, "");
    for (bin = 0; bin < 2; bin++) {
        api_attrs *cur = a;
        mcf_mesh *cm = m;
        for (round = 0; round < 2; round++) {
            api_encode_opts o;
            api_buf b;
            mcf_mesh *d = NULL;
            api_attrs *da = NULL;
            api_encode_opts_init(&o);
            o.format = API_FMT_PLY;
            o.ply_binary = bin;
            o.attrs = cur;
            api_buf_init(&b, 0);
            assert_int_equal(api_ply_encode(cm, &o, &b, &err), MCF_OK);
            for (k = 0; k < 4; k++)
                assert_non_null(strstr(b.data, decl[k]));
            assert_int_equal(api_ply_decode_attrs(b.data, b.len, NULL, &d, &da, &err), MCF_OK);
            tl_assert_same_mesh(m, d);
            assert_int_equal(da->nscal, 4);
            for (k = 0; k < 4; k++)
                for (v = 0; v < 4; v++)
                    assert_true(da->scal[k].values[v] == want[k][v]);
            /* what mcfd wrote is all a PLY keeps: nothing more to name */
            assert_int_equal(api_attrs_not_kept(da, API_FMT_PLY, names, sizeof names), 0);
            api_buf_free(&b);
            if (cur != a) {
                api_attrs_free(cur);
                mcf_mesh_free(cm);
            }
            cur = da;
            cm = d;
        }
        api_attrs_free(cur);
        mcf_mesh_free(cm);
    }
    api_attrs_free(a);
    mcf_mesh_free(m);
}

/* Vertex texcoords under their three usual names, uchar and float
 * colours, normals, double positions; curvature only when asked. */
static void test_ply_attr_names(void **state)
{
    static const char *const names[][2] = {{"s", "t"}, {"u", "v"},
                                           {"texture_u", "texture_v"}};
    size_t i;
    (void)state;
    for (i = 0; i < 3; i++) {
        char text[1024];
        mcf_mesh *m = NULL, *d = NULL;
        api_attrs *a = NULL, *da = NULL;
        mcf_error err;
        const double *v;
        int n;
        api_encode_opts o;
        api_buf b;
        snprintf(text, sizeof text,
                 "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\n"
                 "property double y\nproperty double z\nproperty float nx\n"
                 "property float ny\nproperty float nz\nproperty float %s\n"
                 "property float %s\nproperty uchar red\nproperty uchar green\n"
                 "property uchar blue\nelement face 1\n"
                 "property list uchar int vertex_indices\nend_header\n"
                 "0 0 0 0 0 1 0.125 0.25 255 0 7\n1 0 0 0 0 1 0.5 0.75 1 2 3\n"
                 "0 1 0 0 0 1 1 0 10 20 30\n3 0 1 2\n",
                 names[i][0], names[i][1]);
        assert_int_equal(tl_decode_copy(api_ply_decode, text, strlen(text), NULL, &m,
                                        &err), MCF_OK);
        mcf_mesh_free(m);
        m = NULL;
        assert_int_equal(api_ply_decode_attrs(text, strlen(text), NULL, &m, &a, &err),
                         MCF_OK);
        assert_int_equal(api_attrs_float32(a), 0);
        assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, &n, NULL, &v, NULL));
        assert_true(v[2] == 0.5 && v[3] == 0.75);
        assert_true(api_attrs_get(a, API_ATTR_COLOR, &n, NULL, &v, NULL));
        assert_int_equal(n, 3);
        assert_true(v[0] == 1.0 && v[2] == 7 / 255.0);
        assert_true(api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
        api_encode_opts_init(&o);
        o.format = API_FMT_PLY;
        o.attrs = a;
        o.ply_curvature = (int)(i == 2);
        api_buf_init(&b, 0);
        assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
        assert_non_null(strstr(b.data, "property double x\n"));
        assert_non_null(strstr(b.data, "property double s\n"));
        assert_true((strstr(b.data, "property float mean_curvature") != NULL) == (i == 2));
        assert_int_equal(api_ply_decode_attrs(b.data, b.len, NULL, &d, &da, &err),
                         MCF_OK);
        assert_same_attr(a, da, 1, API_ATTR_TEXCOORD, 0.0, "texcoord");
        assert_same_attr(a, da, 1, API_ATTR_COLOR, 0.0, "colour");
        api_buf_free(&b);
        api_attrs_free(a);
        api_attrs_free(da);
        mcf_mesh_free(m);
        mcf_mesh_free(d);
    }
}

/* An attribute some vertex lacks a component of, or with a NaN, is
 * dropped; the mesh still decodes. A handle from another mesh is
 * refused by the encoder. */
static void test_ply_attr_partial(void **state)
{
    static const char text[] =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nproperty float s\nproperty float nx\n"
        "property float ny\nproperty float nz\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n"
        "0 0 0 0.5 nan 0 1\n1 0 0 0.5 0 0 1\n0 1 0 0.5 0 0 1\n3 0 1 2\n";
    mcf_mesh *m = NULL, *other;
    api_attrs *a = NULL;
    mcf_error err;
    api_encode_opts o;
    api_buf b;
    (void)state;
    assert_int_equal(api_ply_decode_attrs(text, sizeof text - 1, NULL, &m, &a, &err),
                     MCF_OK);
    assert_false(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, NULL, NULL));
    assert_false(api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
    other = strip(NULL);
    api_encode_opts_init(&o);
    o.format = API_FMT_PLY;
    o.attrs = a;
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(other, &o, &b, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "attributes belong to a mesh of 3 vertices"));
    api_buf_free(&b);
    api_attrs_free(a);
    mcf_mesh_free(m);
    mcf_mesh_free(other);
}

/* Issue 20: a PLY's quads and polygons (with a face texcoord list) come
 * back as they came, ascii and binary. */
static void test_ply_polygons(void **state)
{
    double X[147];
    int Q[144], i, bin;
    char in[16384], *p = in;
    mcf_mesh *m = NULL, *d = NULL;
    api_attrs *a = NULL, *da = NULL;
    api_encode_opts o;
    api_buf b;
    mcf_error err;
    (void)state;
    tl_quad_grid(X, Q);
    p += sprintf(p, "ply\nformat ascii 1.0\nelement vertex 49\nproperty double x\n"
                    "property double y\nproperty double z\nelement face 37\n"
                    "property list uchar int vertex_indices\n"
                    "property list uchar float texcoord\nend_header\n");
    for (i = 0; i < 49; i++)
        p += sprintf(p, "%.17g %.17g %.17g\n", X[3 * i], X[3 * i + 1], X[3 * i + 2]);
    for (i = 0; i < 36; i++)
        p += sprintf(p, "4 %d %d %d %d 8 0 0 1 0 1 1 0 %d\n", Q[4 * i], Q[4 * i + 1],
                     Q[4 * i + 2], Q[4 * i + 3], i % 2);
    p += sprintf(p, "5 0 1 2 9 8 10 0 0 0.5 0 1 0 1 1 0.5 1\n");
    assert_int_equal(api_ply_decode_attrs(in, strlen(in), NULL, &m, &a, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(m), 75);
    tl_smooth_a_little(m);
    for (bin = 0; bin < 2; bin++) {
        int n, j;
        const double *tv, *dv;
        const int32_t *tc, *dc;
        api_encode_opts_init(&o);
        o.format = API_FMT_PLY;
        o.ply_binary = bin;
        o.attrs = a;
        api_buf_init(&b, 0);
        assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
        assert_non_null(strstr(b.data, "element face 37\n"));
        assert_int_equal(api_ply_decode_attrs(b.data, b.len, NULL, &d, &da, &err), MCF_OK);
        tl_assert_same_mesh(m, d);
        assert_non_null(da->poly);
        assert_int_equal(da->npoly, 37);
        assert_int_equal(da->poly[36], 5);
        /* every corner's texcoord as it came (the list may be float32) */
        assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, &n, &tv, &tc));
        assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, &n, &dv, &dc));
        for (j = 0; j < 3 * 75; j++) {
            tl_assert_near(dv[2 * dc[j]], tv[2 * tc[j]], 0, "u");
            tl_assert_near(dv[2 * dc[j] + 1], tv[2 * tc[j] + 1], 0, "v");
        }
        mcf_mesh_free(d);
        api_attrs_free(da);
        api_buf_free(&b);
    }
    mcf_mesh_free(m);
    api_attrs_free(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_reference_types),
        cmocka_unit_test(test_reference_layouts),
        cmocka_unit_test(test_polygons),
        cmocka_unit_test(test_polygon_fan_budget),
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_roundtrip_scans),
        cmocka_unit_test(test_roundtrip_be),
        cmocka_unit_test(test_curvature_properties),
        cmocka_unit_test(test_draco_decoder_ply),
        cmocka_unit_test(test_ply_attrs),
        cmocka_unit_test(test_ply_attr_names),
        cmocka_unit_test(test_ply_attr_partial),
        cmocka_unit_test(test_ply_passthrough),
        cmocka_unit_test(test_header_errors),
        cmocka_unit_test(test_body_errors),
        cmocka_unit_test(test_binary_errors),
        cmocka_unit_test(test_ascii_truncations),
        cmocka_unit_test(test_garbage),
        cmocka_unit_test(test_ply_polygons),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
