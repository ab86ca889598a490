/* SPDX-License-Identifier: MIT */
/*
 * test_api_draco.c - the Draco bridge (api_draco.cc).
 *
 * Real files: every .drc of tests/data/meshes (and of $MCF_MESHES, the
 * large dragon_vrip.drc) decodes with the counts of
 * SOURCES.md (the old v1.1 bunny.drc included), and their topology where
 * SOURCES.md states it. Round trips: lossless encoding gives back
 * bit-identical positions, compared through face corners since edgebreaker
 * renumbers vertices and reorders faces; quantized encoding stays within
 * the quantization step and reports exactly the error measured here.
 * Interop: files written by Debian's draco_encoder CLI decode to the same
 * positions. Hostile input: truncations at every offset, corrupted bytes,
 * point clouds, limits, empty input; each fails with a precise message.
 * Attributes (issue 12): car.drc's texture coordinates come back bit for
 * bit through smoothing and Draco (both methods) and its normals are the
 * smoothed surface's; the default output is float32 at the input's
 * quantization and not larger than the input; Debian's draco_decoder
 * turns every kind of output into a PLY with typed properties that reads
 * back, and draco_encoder reads mcfd's PLY.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "testlib.h"
#include "../api/api.h"
#include "../api/api_internal.h"

static mcf_status dec(const void *buf, size_t len, mcf_mesh **m, mcf_error *err)
{
    api_limits lim;
    api_limits_default(&lim);
    *m = NULL;
    err->status = MCF_OK;
    err->msg[0] = '\0';
    return api_draco_decode(buf, len, &lim, m, err);
}

/* A regression input of tests/data ($MCF_TESTDATA overrides the folder;
 * `make test` runs from the top of the tree). */
static char *read_data_file(const char *name, size_t *len)
{
    const char *d = getenv("MCF_TESTDATA");
    char path[4096], *buf = NULL;
    snprintf(path, sizeof path, "%s/%s", d && *d ? d : "tests/data", name);
    if (tl_read_file(path, &buf, len) != 0)
        fail_msg("cannot read %s", path);
    return buf;
}

static char *read_mesh_file(const char *name, size_t *len)
{
    char path[4096], *buf = NULL;
    snprintf(path, sizeof path, "%s", tl_need_mesh(name));
    if (tl_read_file(path, &buf, len) != 0)
        fail_msg("cannot read %s", path);
    return buf;
}

/* Encodes m; returns the bytes (free them) and the measured error. */
static char *enc(const mcf_mesh *m, int q, int level, int preserve, size_t *len,
                 double *qerr)
{
    api_encode_opts o;
    api_buf b;
    mcf_error err = {MCF_OK, ""};
    mcf_status rc;
    api_encode_opts_init(&o);
    o.format = API_FMT_DRACO;
    o.quantization_bits = q;
    o.compression_level = level;
    o.preserve_order = preserve;
    api_buf_init(&b, 0);
    rc = api_draco_encode(m, &o, &b, qerr, &err);
    if (rc != MCF_OK)
        fail_msg("encode q=%d cl=%d: %s: %s", q, level, mcf_status_name(rc), err.msg);
    return api_buf_detach(&b, len);
}

/* ------------------------------------------------ face-corner comparison */

typedef struct {
    double p[9];
} tri9;

static int cmp_pt(const double *a, const double *b)
{
    int k;
    for (k = 0; k < 3; k++)
        if (a[k] != b[k])
            return a[k] < b[k] ? -1 : 1;
    return 0;
}

static int cmp_tri(const void *a, const void *b)
{
    const tri9 *s = a, *t = b;
    int k, c;
    for (k = 0; k < 3; k++)
        if ((c = cmp_pt(s->p + 3 * k, t->p + 3 * k)) != 0)
            return c;
    return 0;
}

/* Each face as its three corner positions, rotated to start at the
 * smallest corner (orientation kept), then sorted: two meshes with the
 * same faces in any vertex or face order give equal arrays. Faces with a
 * repeated index are left out when skip_repeated (edgebreaker drops
 * them). X overrides the mesh's positions when non-NULL. */
static tri9 *canon(const mcf_mesh *m, const double *X, int skip_repeated, int *n)
{
    int nf = mcf_mesh_nfaces(m), f, k, r, cnt = 0;
    const int32_t *F = mcf_mesh_faces(m);
    tri9 *t = malloc(sizeof *t * (size_t)(nf ? nf : 1));
    assert_non_null(t);
    if (!X)
        X = mcf_mesh_positions(m);
    for (f = 0; f < nf; f++) {
        const int32_t *v = F + 3 * f;
        if (skip_repeated && (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]))
            continue;
        r = 0;
        for (k = 1; k < 3; k++)
            if (cmp_pt(&X[3 * v[k]], &X[3 * v[r]]) < 0)
                r = k;
        for (k = 0; k < 3; k++)
            memcpy(t[cnt].p + 3 * k, &X[3 * v[(k + r) % 3]], 3 * sizeof(double));
        cnt++;
    }
    qsort(t, (size_t)cnt, sizeof *t, cmp_tri);
    *n = cnt;
    return t;
}

/* Fails unless a and b have bit-identical faces (through face corners). */
static void assert_same_faces(const mcf_mesh *a, const double *Xa,
                              const mcf_mesh *b, const char *what)
{
    int na, nb, i;
    tri9 *ta = canon(a, Xa, 1, &na), *tb = canon(b, NULL, 1, &nb);
    if (na != nb)
        fail_msg("%s: %d vs %d faces", what, na, nb);
    for (i = 0; i < na; i++)
        if (memcmp(&ta[i], &tb[i], sizeof ta[i]) != 0)
            fail_msg("%s: sorted face %d differs (%.17g %.17g %.17g vs %.17g %.17g "
                     "%.17g)",
                     what, i, ta[i].p[0], ta[i].p[1], ta[i].p[2], tb[i].p[0],
                     tb[i].p[1], tb[i].p[2]);
    free(ta);
    free(tb);
}

/* Largest extent of the bounding box. */
static double extent(const mcf_mesh *m)
{
    const double *X = mcf_mesh_positions(m);
    double lo[3], hi[3], e = 0;
    int i, k;
    for (k = 0; k < 3; k++)
        lo[k] = hi[k] = X[k];
    for (i = 0; i < mcf_mesh_nvertices(m); i++)
        for (k = 0; k < 3; k++) {
            if (X[3 * i + k] < lo[k]) lo[k] = X[3 * i + k];
            if (X[3 * i + k] > hi[k]) hi[k] = X[3 * i + k];
        }
    for (k = 0; k < 3; k++)
        if (hi[k] - lo[k] > e)
            e = hi[k] - lo[k];
    return e;
}

/* ------------------------------------------------------------ real files */

static const struct {
    const char *file;
    int nv, nf;
} real[] = {
    {"bunny.drc", 34834, 69451},
    {"car.drc", 920, 1744},             /* 1,856 points welded */
    {"test_nm.obj.edgebreaker.cl10.2.2.drc", 99, 170},
    {"test_nm.obj.sequential.cl3.2.2.drc", 97, 170},
};

static void test_real_counts(void **state)
{
    size_t i;
    (void)state;
    for (i = 0; i < sizeof real / sizeof real[0]; i++) {
        mcf_mesh *m = tl_load(real[i].file);
        if (mcf_mesh_nvertices(m) != real[i].nv || mcf_mesh_nfaces(m) != real[i].nf)
            fail_msg("%s: %d/%d, want %d/%d", real[i].file, mcf_mesh_nvertices(m),
                     mcf_mesh_nfaces(m), real[i].nv, real[i].nf);
        mcf_mesh_free(m);
    }
}

static void test_real_topology(void **state)
{
    mcf_mesh_info info;
    mcf_error err;
    mcf_mesh *m;
    (void)state;

    /* bunny.drc (bitstream v1.1): the Stanford bunny, 5 holes, genus 0. */
    m = tl_load("bunny.drc");
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_int_equal(info.boundary_loops, 5);
    assert_int_equal(info.boundary_edges, 223);
    assert_int_equal(info.components, 1);
    assert_int_equal(info.unreferenced, 0);
    mcf_mesh_free(m);

    /* The sequential test_nm keeps its 2 non-manifold vertices; the
     * edgebreaker one has them split. */
    m = tl_load("test_nm.obj.sequential.cl3.2.2.drc");
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_int_equal(info.nonmanifold_vertices, 2);
    assert_int_equal(info.boundary_loops, 3);
    mcf_mesh_free(m);
    m = tl_load("test_nm.obj.edgebreaker.cl10.2.2.drc");
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_int_equal(info.nonmanifold_vertices, 0);
    assert_int_equal(info.boundary_loops, 3);
    mcf_mesh_free(m);
}

/* dragon_vrip.drc (large, $MCF_MESHES): 435,545 vertices, closed,
 * manifold, one piece, genus 55. */
static void test_real_dragon(void **state)
{
    mcf_mesh_info info;
    mcf_error err;
    mcf_mesh *m = tl_load("dragon_vrip.drc");
    (void)state;
    assert_int_equal(mcf_mesh_nvertices(m), 435545);
    assert_int_equal(mcf_mesh_nfaces(m), 871306);
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_true(info.closed);
    assert_true(info.manifold);
    assert_int_equal(info.components, 1);
    assert_int_equal(info.euler, -108);
    assert_int_equal(info.genus, 55);
    mcf_mesh_free(m);
}

static int cmp_pos(const void *a, const void *b)
{
    return cmp_pt(a, b);
}

/* car.drc is sequential with normals and texcoords: its stream holds one
 * position value per point (1,856, as draco_decoder writes them), so the
 * surface came in 118 pieces cut at every UV and normal seam (1,762
 * boundary edges). The decoder welds such copies of a position: 920
 * vertices (SOURCES.md's count), 80 boundary edges, 9 components; the
 * texcoords keep their seams in the attributes (1,856 values). */
static void test_car_seams(void **state)
{
    mcf_mesh *m = tl_load("car.drc");
    int nv = mcf_mesh_nvertices(m), i, distinct = 1;
    double *P = malloc(sizeof *P * 3 * (size_t)nv);
    mcf_mesh_info info;
    mcf_error err;
    (void)state;
    assert_non_null(P);
    memcpy(P, mcf_mesh_positions(m), sizeof *P * 3 * (size_t)nv);
    qsort(P, (size_t)nv, 3 * sizeof *P, cmp_pos);
    for (i = 1; i < nv; i++)
        distinct += cmp_pt(P + 3 * i, P + 3 * (i - 1)) != 0;
    assert_int_equal(nv, 920);
    assert_int_equal(distinct, 920);
    assert_int_equal(mcf_mesh_inspect(m, &info, &err), MCF_OK);
    assert_int_equal(info.boundary_edges, 80);
    assert_int_equal(info.components, 9);
    free(P);
    mcf_mesh_free(m);
}

/* ------------------------------------------------------------ round trips */

static void lossless(const char *file)
{
    mcf_mesh *m = tl_load(file), *d = NULL;
    mcf_error err;
    int preserve;
    for (preserve = 0; preserve <= 1; preserve++) {
        size_t len;
        double qerr = -1;
        char *bytes = enc(m, 0, 7, preserve, &len, &qerr);
        if (dec(bytes, len, &d, &err) != MCF_OK)
            fail_msg("%s: %s", file, err.msg);
        assert_true(qerr == 0.0);
        assert_same_faces(m, NULL, d, file);
        if (preserve) {
            /* sequential: the very same arrays */
            tl_assert_same_mesh(m, d);
        }
        mcf_mesh_free(d);
        free(bytes);
    }
    mcf_mesh_free(m);
}

/* OBJ coordinates are not floats (stored as float64), bunny.drc's are
 * (stored as float32); snowden has non-manifold edges and stanford-bunny
 * unreferenced vertices (dropped by edgebreaker, kept by sequential). */
static void test_lossless(void **state)
{
    (void)state;
    lossless("sphere_cgal.obj");
    lossless("test_nm.obj");
    lossless("bunny.drc");
}

/* The same on the large scans of $MCF_MESHES. */
static void test_lossless_scans(void **state)
{
    (void)state;
    lossless("fertility.obj");
    lossless("stanford-bunny.obj");
    lossless("snowden.obj");
}

/* Float coordinates are stored as float32: half the bytes of float64. */
static void test_lossless_float_storage(void **state)
{
    mcf_mesh *m = tl_load("sphere_cgal.obj"), *f;
    int nv = mcf_mesh_nvertices(m), i;
    double *X = malloc(sizeof *X * 3 * (size_t)nv);
    size_t l64, l32;
    double qerr;
    char *b64, *b32;
    mcf_error err;
    (void)state;
    assert_non_null(X);
    for (i = 0; i < 3 * nv; i++)
        X[i] = (float)mcf_mesh_positions(m)[i];
    f = mcf_mesh_new(nv, X, mcf_mesh_nfaces(m), mcf_mesh_faces(m), &err);
    assert_non_null(f);
    b64 = enc(m, 0, 7, 1, &l64, &qerr);
    b32 = enc(f, 0, 7, 1, &l32, &qerr);
    /* sequential: 24 vs 12 raw bytes per vertex, same connectivity */
    assert_int_equal(l64 - l32, 12 * (size_t)nv);
    free(b64);
    free(b32);
    free(X);
    mcf_mesh_free(f);
    mcf_mesh_free(m);
}

static void quantized(const char *file, int q)
{
    mcf_mesh *m = tl_load(file), *ds = NULL, *de = NULL;
    mcf_error err;
    int nv = mcf_mesh_nvertices(m), i;
    size_t ls, le;
    double es = -1, ee = -1, direct = 0;
    char *bs = enc(m, q, 7, 1, &ls, &es), *be = enc(m, q, 10, 0, &le, &ee);
    /* Draco's step is extent/(2^q - 1); rounding errs by half a step and
     * float32 storage by ~1e-7 relative, so one full step bounds it. */
    double bound = extent(m) / (ldexp(1.0, q) - 1.0);

    if (dec(bs, ls, &ds, &err) != MCF_OK || dec(be, le, &de, &err) != MCF_OK)
        fail_msg("%s q=%d: %s", file, q, err.msg);
    /* Sequential keeps vertex order: measure directly, index by index. */
    assert_int_equal(mcf_mesh_nvertices(ds), nv);
    for (i = 0; i < 3 * nv; i++) {
        double d = fabs(mcf_mesh_positions(ds)[i] - mcf_mesh_positions(m)[i]);
        if (d > direct)
            direct = d;
    }
    if (!(direct <= bound))
        fail_msg("%s q=%d: error %g above the bound %g", file, q, direct, bound);
    assert_true(direct > 0);
    /* The reported errors are the measured one, exactly (same arithmetic:
     * max of |decoded - input|), for both methods: quantization is per
     * value, with the same parameters. */
    if (es != direct || ee != direct)
        fail_msg("%s q=%d: reported %.17g (sequential) / %.17g (edgebreaker), "
                 "measured %.17g",
                 file, q, es, ee, direct);
    /* Through face corners: the edgebreaker faces are the input faces
     * carrying the sequentially decoded positions, bit for bit. */
    assert_same_faces(m, mcf_mesh_positions(ds), de, file);
    mcf_mesh_free(ds);
    mcf_mesh_free(de);
    free(bs);
    free(be);
    mcf_mesh_free(m);
}

static void test_quantized(void **state)
{
    (void)state;
    quantized("sphere_cgal.obj", 8);
    quantized("sphere_cgal.obj", 11);
    quantized("knot1.obj", 20);
}

static void test_quantized_scans(void **state)
{
    (void)state;
    quantized("fertility.obj", 14);
    quantized("snowden.obj", 16);
}

/* Every compression level encodes and decodes to the same faces. */
static void test_levels(void **state)
{
    mcf_mesh *m = tl_load("bunny_npm_closed.obj"), *d;
    mcf_error err;
    int level;
    (void)state;
    for (level = 0; level <= 10; level++) {
        size_t len;
        double qerr;
        char *b = enc(m, 0, level, 0, &len, &qerr);
        if (dec(b, len, &d, &err) != MCF_OK)
            fail_msg("level %d: %s", level, err.msg);
        assert_same_faces(m, NULL, d, "levels");
        mcf_mesh_free(d);
        free(b);
    }
    mcf_mesh_free(m);
}

/* A repeated-index face is kept by sequential and dropped by edgebreaker;
 * the error measurement skips it. Coordinates beyond float: lossless
 * float64 keeps them, quantization (float32) refuses them. */
static void test_encode_edge_cases(void **state)
{
    static const double X[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const int32_t F[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2, 0, 0, 1};
    static const double Xbig[] = {0, 0, 0, 1e300, 0, 0, 0, 1e-300, 0};
    static const int32_t Fbig[] = {0, 1, 2};
    mcf_error err;
    mcf_mesh *m = mcf_mesh_new(4, X, 5, F, &err), *d;
    api_encode_opts o;
    api_buf b;
    size_t len;
    double qerr;
    char *bytes;
    (void)state;
    assert_non_null(m);
    bytes = enc(m, 0, 7, 1, &len, &qerr);
    assert_int_equal(dec(bytes, len, &d, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(d), 5);
    assert_true(qerr == 0.0);
    mcf_mesh_free(d);
    free(bytes);
    bytes = enc(m, 12, 7, 0, &len, &qerr);
    assert_int_equal(dec(bytes, len, &d, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(d), 4);
    /* a unit tetrahedron with 12 bits: below one step of 1/4095 */
    assert_true(qerr <= 1.0 / 4095);
    mcf_mesh_free(d);
    free(bytes);
    mcf_mesh_free(m);

    m = mcf_mesh_new(3, Xbig, 1, Fbig, &err);
    assert_non_null(m);
    bytes = enc(m, 0, 7, 1, &len, &qerr);
    assert_int_equal(dec(bytes, len, &d, &err), MCF_OK);
    assert_memory_equal(mcf_mesh_positions(d), Xbig, sizeof Xbig);
    mcf_mesh_free(d);
    free(bytes);
    api_encode_opts_init(&o);
    o.quantization_bits = 10;
    api_buf_init(&b, 0);
    assert_int_equal(api_draco_encode(m, &o, &b, NULL, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "exceeds the float range"));
    assert_int_equal(b.len, 0);
    o.quantization_bits = 31;
    assert_int_equal(api_draco_encode(m, &o, &b, NULL, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "quantization_bits 31 out of range"));
    o.quantization_bits = 0;
    o.compression_level = 11;
    assert_int_equal(api_draco_encode(m, &o, &b, NULL, &err), MCF_EINVAL);
    assert_non_null(strstr(err.msg, "compression_level 11 out of range"));
    /* an output maximum too small: ELIMIT, buffer untouched */
    api_buf_free(&b);
    api_buf_init(&b, 16);
    o.compression_level = 7;
    assert_int_equal(api_draco_encode(m, &o, &b, NULL, &err), MCF_ELIMIT);
    assert_int_equal(b.len, 0);
    api_buf_free(&b);
    mcf_mesh_free(m);
}

/* Through api_mesh_encode/api_mesh_decode (the dispatch). */
static void test_dispatch(void **state)
{
    mcf_mesh *m = tl_load("knot1.obj"), *d = NULL;
    api_encode_opts o;
    api_buf b;
    api_format f;
    mcf_error err;
    (void)state;
    api_encode_opts_init(&o);
    o.format = API_FMT_DRACO;
    o.quantization_bits = 0; /* lossless: the default (auto) quantizes */
    api_buf_init(&b, 0);
    assert_int_equal(api_mesh_encode(m, &o, &b, &err), MCF_OK);
    assert_int_equal(api_mesh_decode(b.data, b.len, NULL, &d, &f, &err), MCF_OK);
    assert_int_equal(f, API_FMT_DRACO);
    assert_same_faces(m, NULL, d, "dispatch");
    api_buf_free(&b);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
}

/* ------------------------------------------------- Debian's draco_encoder */

static int have_cli(void)
{
    return system("command -v draco_encoder >/dev/null 2>&1") == 0;
}

/* Writes m as OBJ into dir/x.obj, runs draco_encoder with args, returns
 * the .drc bytes. */
static char *cli_encode(const mcf_mesh *m, const char *dir, const char *args,
                        size_t *len)
{
    char obj[512], drc[512], cmd[2048], *buf = NULL;
    api_buf b;
    mcf_error err;
    FILE *fp;
    snprintf(obj, sizeof obj, "%s/x.obj", dir);
    snprintf(drc, sizeof drc, "%s/x.drc", dir);
    api_buf_init(&b, 0);
    assert_int_equal(api_obj_encode(m, &b, &err), MCF_OK);
    fp = fopen(obj, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(b.data, 1, b.len, fp), b.len);
    assert_int_equal(fclose(fp), 0);
    api_buf_free(&b);
    snprintf(cmd, sizeof cmd, "draco_encoder -i %s -o %s %s >/dev/null 2>&1", obj,
             drc, args);
    if (system(cmd) != 0)
        fail_msg("failed: %s", cmd);
    if (tl_read_file(drc, &buf, len) != 0)
        fail_msg("cannot read %s", drc);
    remove(obj);
    remove(drc);
    return buf;
}

static void test_draco_encoder_cli(void **state)
{
    char tmpl[] = "/tmp/mcf_draco_XXXXXX", *dir, *bytes;
    mcf_mesh *m = tl_load("sphere_cgal.obj"), *f, *d;
    int nv = mcf_mesh_nvertices(m), i, k;
    double *X = malloc(sizeof *X * 3 * (size_t)nv), maxerr = 0, bound;
    size_t len;
    mcf_error err;
    (void)state;
    if (!have_cli()) {
        free(X);
        mcf_mesh_free(m);
        skip();
    }
    dir = mkdtemp(tmpl);
    assert_non_null(dir);
    assert_non_null(X);
    /* draco_encoder reads OBJ into float32: compare with the float values */
    for (i = 0; i < 3 * nv; i++)
        X[i] = (float)mcf_mesh_positions(m)[i];
    f = mcf_mesh_new(nv, X, mcf_mesh_nfaces(m), mcf_mesh_faces(m), &err);
    assert_non_null(f);

    bytes = cli_encode(f, dir, "-cl 7 -qp 0", &len);
    assert_int_equal(dec(bytes, len, &d, &err), MCF_OK);
    assert_int_equal(mcf_mesh_nvertices(d), nv);
    assert_same_faces(f, NULL, d, "draco_encoder -cl 7 -qp 0");
    mcf_mesh_free(d);
    free(bytes);

    bytes = cli_encode(f, dir, "-cl 10 -qp 0", &len);
    assert_int_equal(dec(bytes, len, &d, &err), MCF_OK);
    assert_same_faces(f, NULL, d, "draco_encoder -cl 10 -qp 0");
    mcf_mesh_free(d);
    free(bytes);

    /* -qp 14: draco_encoder may renumber; its quantized positions must be
     * exactly those of our own 14-bit sequential encoding of the same
     * floats (same quantizer), compared through face corners, and within
     * one step (see quantized()) of the input. */
    for (i = 0; i < 2; i++) {
        double qerr;
        char *ours = enc(f, 14, 7, 1, &len, &qerr);
        mcf_mesh *s = NULL;
        assert_int_equal(dec(ours, len, &s, &err), MCF_OK);
        free(ours);
        bytes = cli_encode(f, dir, i ? "-cl 10 -qp 14" : "-cl 0 -qp 14", &len);
        assert_int_equal(dec(bytes, len, &d, &err), MCF_OK);
        assert_same_faces(f, mcf_mesh_positions(s), d, "draco_encoder -qp 14");
        bound = extent(f) / (ldexp(1.0, 14) - 1);
        maxerr = 0;
        for (k = 0; k < 3 * nv; k++)
            if (fabs(mcf_mesh_positions(s)[k] - X[k]) > maxerr)
                maxerr = fabs(mcf_mesh_positions(s)[k] - X[k]);
        if (!(maxerr <= bound && maxerr > 0 && maxerr == qerr))
            fail_msg("draco_encoder -qp 14: error %g (reported %g), bound %g",
                     maxerr, qerr, bound);
        mcf_mesh_free(s);
        mcf_mesh_free(d);
        free(bytes);
    }

    /* A point cloud is refused by name. */
    bytes = cli_encode(f, dir, "-point_cloud", &len);
    assert_int_equal(dec(bytes, len, &d, &err), MCF_EDECODE);
    assert_string_equal(err.msg, "Draco point cloud, not a triangle mesh");
    assert_null(d);
    free(bytes);

    rmdir(dir);
    free(X);
    mcf_mesh_free(f);
    mcf_mesh_free(m);
}

/* ------------------------------------------------------- hostile input */

static void expect_fail(const void *buf, size_t len, mcf_status code,
                        const char *want)
{
    mcf_mesh *m = NULL;
    mcf_error err;
    api_limits lim;
    api_limits_default(&lim);
    mcf_status rc = tl_decode_copy(api_draco_decode, buf, len, &lim, &m, &err);
    if (rc != code || !strstr(err.msg, want))
        fail_msg("%zu bytes: got %s \"%s\", want %s containing \"%s\"", len,
                 mcf_status_name(rc), err.msg, mcf_status_name(code), want);
    assert_null(m);
    assert_int_equal(err.status, code);
}

static void test_malformed(void **state)
{
    static const char hdr[] = "DRACO\x02\x02\x01\x01\x00\x00";
    static const char future[] = "DRACO\x09\x00\x01\x01\x00\x00";
    static const char cloud_type[] = "DRACO\x02\x02\x00\x00\x00\x00";
    static const char junk[] = "\x00\x01\x02\x03\xff\xfe\xfd\xfc";
    mcf_error err;
    mcf_mesh *m = NULL;
    (void)state;
    expect_fail("", 0, MCF_EDECODE, "draco: empty input");
    expect_fail("DRAC", 4, MCF_EDECODE, "no \"DRACO\" magic");
    expect_fail("draco", 5, MCF_EDECODE, "no \"DRACO\" magic");
    expect_fail(junk, sizeof junk - 1, MCF_EDECODE, "no \"DRACO\" magic");
    expect_fail("DRACO", 5, MCF_EDECODE, "draco: bad header");
    expect_fail(hdr, sizeof hdr - 1, MCF_EDECODE, "draco: ");
    expect_fail(future, sizeof future - 1, MCF_EDECODE,
                "draco: Unknown major version");
    expect_fail(cloud_type, sizeof cloud_type - 1, MCF_EDECODE,
                "Draco point cloud, not a triangle mesh");
    assert_int_equal(api_draco_decode(NULL, 3, NULL, &m, &err), MCF_EINVAL);
}

/* Every prefix of a valid stream fails cleanly (or, where the tail held
 * nothing the decoder needs, yields the full mesh); bytes corrupted one at
 * a time either fail with a message or decode to some valid mesh. */
static void torture(const char *what, const mcf_mesh *m, int q, int preserve)
{
    size_t len, cut, i;
    double qerr;
    char *bytes = enc(m, q, 7, preserve, &len, &qerr);
    char *copy = malloc(len);
    int failed = 0;
    assert_non_null(copy);
    for (cut = 0; cut < len; cut++) {
        mcf_mesh *d = NULL;
        mcf_error err;
        char *pre = malloc(cut ? cut : 1);
        mcf_status rc;
        assert_non_null(pre);
        memcpy(pre, bytes, cut);
        rc = dec(pre, cut, &d, &err);
        free(pre);
        if (rc == MCF_OK) {
            assert_int_equal(mcf_mesh_nfaces(d), mcf_mesh_nfaces(m));
            mcf_mesh_free(d);
            continue;
        }
        failed++;
        assert_null(d);
        if (rc != MCF_EDECODE || (strncmp(err.msg, "draco: ", 7) != 0))
            fail_msg("%s cut at %zu: %s \"%s\"", what, cut, mcf_status_name(rc),
                     err.msg);
    }
    /* the header and the connectivity are needed: most cuts must fail */
    assert_true(failed > (int)len / 2);
    for (i = 0; i < len; i++) {
        static const unsigned char flips[] = {0xff, 0x80, 0x01};
        size_t k;
        for (k = 0; k < sizeof flips; k++) {
            mcf_mesh *d = NULL;
            mcf_error err;
            mcf_status rc;
            memcpy(copy, bytes, len);
            copy[i] = (char)(copy[i] ^ flips[k]);
            rc = dec(copy, len, &d, &err);
            if (rc == MCF_OK) {
                assert_true(mcf_mesh_nvertices(d) > 0 && mcf_mesh_nfaces(d) > 0);
                mcf_mesh_free(d);
            } else if ((rc != MCF_EDECODE && rc != MCF_EMESH) || err.msg[0] == '\0') {
                fail_msg("%s byte %zu ^ %02x: %s \"%s\"", what, i, flips[k],
                         mcf_status_name(rc), err.msg);
            }
        }
    }
    free(copy);
    free(bytes);
}

static void test_truncated_and_corrupted(void **state)
{
    mcf_mesh *m = tl_load("test_nm.obj");
    (void)state;
    torture("edgebreaker q11", m, 11, 0);
    torture("sequential q11", m, 11, 1);
    torture("edgebreaker lossless", m, 0, 0);
    mcf_mesh_free(m);
}

/* Regression (found by UBSan in test_truncated_and_corrupted): a stream
 * whose POSITION attribute claims DT_BOOL (one flipped byte of a lossless
 * tetrahedron) made Draco's ConvertValue load 0xf0 as a bool. Positions
 * are now read by hand; a non-numeric type is refused by number. */
static void test_regression_bool_position(void **state)
{
    size_t len;
    char *buf = read_data_file("draco_bool_position.drc", &len);
    (void)state;
    expect_fail(buf, len, MCF_EDECODE, "draco: POSITION data type 11 cannot be read");
    free(buf);
}

/* Regression (fuzz_roundtrip, out-of-memory): a 317-byte v1.249
 * edgebreaker stream declaring 1,044,266,558 faces made libdraco reserve
 * 4 GB before reading them. The counts are now read and limited before
 * libdraco sees the stream. */
static void test_regression_huge_faces(void **state)
{
    size_t len;
    char *buf = read_data_file("draco_fuzz_huge_faces.drc", &len);
    (void)state;
    expect_fail(buf, len, MCF_ELIMIT,
                "draco: header declares 1044266558 faces, more than max_faces "
                "(200000000)");
    free(buf);
}

/* Issue 28: a 26-byte v2.2 edgebreaker header declaring 9,999,999 faces
 * (within max_faces) made libdraco size its corner table, 243 MB, before
 * failing to decode; refused from the header now: more faces than 16384
 * a byte of stream. A real stream is far below (bunny.drc 0.7, a flat
 * 1000 x 1000 grid at 1-bit quantization 684). */
static void test_declared_faces_per_byte(void **state)
{
    size_t len;
    char *buf = read_data_file("draco_declared_faces.drc", &len);
    (void)state;
    assert_int_equal(len, 26);
    expect_fail(buf, len, MCF_ELIMIT,
                "draco: header declares 9999999 faces in a 26-byte stream, more "
                "than 16384 a byte: refused before decoding");
    free(buf);
}

/* Hand-made headers for the other counts libdraco trusts: metadata entry
 * sizes and nesting, hole events of v2.0 streams, split symbols, and the
 * sequential point count. */
static void test_hostile_headers(void **state)
{
    static const char meta_big[] =
        "DRACO\x02\x02\x01\x01\x00\x80" /* metadata flag */
        "\x00"                               /* no attribute metadata */
        "\x01\x01" "a" "\xff\xff\xff\xff\x0f"; /* entry "a", 4 GB */
    static const char meta_entries[] = "DRACO\x02\x02\x01\x01\x00\x80\x00"
                                       "\xff\xff\xff\xff\x0f";
    static const char meta_atts[] = "DRACO\x02\x02\x01\x01\x00\x80"
                                    "\xff\xff\xff\x7f";
    static const char holes[] =
        "DRACO\x02\x00\x01\x01\x00\x00" /* v2.0 edgebreaker */
        "\x00\x00\x03\x01\x00\x01\x00" /* type, new, verts, faces, att, syms, splits */
        "\x01\x00"                          /* connectivity size 1, its byte */
        "\x00\xff\xff\xff\xff\x0f";       /* no splits, 4e9 hole events */
    static const char splits[] = "DRACO\x02\x02\x01\x01\x00\x00"
                                 "\x00\x03\x01\x00\x01\x05";
    static const char seq_points[] = "DRACO\x02\x02\x01\x00\x00\x00"
                                     "\x01\xff\xff\xff\xff\x0f\x01";
    char deep[11 + 1 + 3 * 40 + 2];
    size_t k, n = 0;
    (void)state;
    expect_fail(meta_big, sizeof meta_big - 1, MCF_EDECODE,
                "draco: metadata entry of 4294967295 bytes in 0");
    expect_fail(meta_entries, sizeof meta_entries - 1, MCF_EDECODE,
                "draco: metadata declares 4294967295 entries in 0 bytes");
    expect_fail(meta_atts, sizeof meta_atts - 1, MCF_EDECODE,
                "draco: metadata declares 268435455 attribute blocks in 0 bytes");
    expect_fail(holes, sizeof holes - 1, MCF_EDECODE,
                "draco: 4294967295 hole events in 0 bytes");
    expect_fail(splits, sizeof splits - 1, MCF_EDECODE,
                "draco: 5 split symbols for 1 faces");
    expect_fail(seq_points, sizeof seq_points - 1, MCF_ELIMIT,
                "draco: header declares 4294967295 vertices, more than max_vertices");
    /* 40 nested sub-metadata blocks: refused at depth 33 */
    memcpy(deep, "DRACO\x02\x02\x01\x01\x00\x80", 11);
    n = 11;
    deep[n++] = 0; /* no attribute metadata */
    for (k = 0; k < 40; k++) {
        deep[n++] = 0; /* no entries */
        deep[n++] = 1; /* one sub-metadata */
        deep[n++] = 0; /* with an empty name */
    }
    deep[n++] = 0;
    deep[n++] = 0;
    expect_fail(deep, n, MCF_EDECODE, "draco: metadata nested deeper than 32 levels");
}

static void test_limits(void **state)
{
    size_t len;
    char *buf = read_mesh_file("bunny.drc", &len);
    api_limits lim;
    mcf_mesh *m = NULL;
    mcf_error err;
    (void)state;
    api_limits_default(&lim);
    lim.max_vertices = 34833;
    assert_int_equal(api_draco_decode(buf, len, &lim, &m, &err), MCF_ELIMIT);
    assert_string_equal(err.msg, "draco: header declares 34834 vertices, more than "
                                 "max_vertices (34833)");
    api_limits_default(&lim);
    lim.max_faces = 69450;
    assert_int_equal(api_draco_decode(buf, len, &lim, &m, &err), MCF_ELIMIT);
    assert_string_equal(err.msg, "draco: header declares 69451 faces, more than "
                                 "max_faces (69450)");
    api_limits_default(&lim);
    lim.max_input_bytes = len - 1;
    assert_int_equal(api_draco_decode(buf, len, &lim, &m, &err), MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "exceeds max_input_bytes"));
    assert_null(m);
    lim.max_input_bytes = len;
    assert_int_equal(api_draco_decode(buf, len, &lim, &m, &err), MCF_OK);
    mcf_mesh_free(m);
    free(buf);
}

/* ------------------------------------------------------------ attributes */

/* Reads $MCF_MESHES/name and decodes it with its attributes. */
static mcf_mesh *load_attrs(const char *name, api_attrs **a, size_t *bytes)
{
    char *buf;
    size_t len;
    mcf_mesh *m = NULL;
    mcf_error err;
    buf = read_mesh_file(name, &len);
    if (api_mesh_decode_attrs(buf, len, NULL, &m, a, NULL, &err) != MCF_OK)
        fail_msg("%s: %s", name, err.msg);
    free(buf);
    if (bytes)
        *bytes = len;
    return m;
}

/* A few implicit steps: the vertices move, the connectivity stays. */
static void smooth_a_little(mcf_mesh *m)
{
    mcf_flow_params p;
    mcf_error err;
    mcf_flow_params_init(&p);
    p.scheme = MCF_DESBRUN2;
    p.dt = 1e-5;
    p.iterations = 2;
    if (mcf_flow_run(m, &p, NULL, &err) != MCF_OK)
        fail_msg("flow: %s", err.msg);
}

/* One face corner as float32 values: position, texcoord, normal. */
typedef struct {
    float r[8];
} corner_rec;

static int cmp_corner(const void *a, const void *b)
{
    return memcmp(a, b, sizeof(corner_rec));
}

/* The corners of m (positions as float32) with the texcoord of a and the
 * normal N (per value of a's normal attribute; NULL: a's own values), as
 * a sorted array of 3*nf records: two meshes with the same records carry
 * the same attribute values at the same places, whatever the vertex and
 * face order. */
static corner_rec *corners_of(const mcf_mesh *m, const api_attrs *a,
                              const double *N)
{
    int nf = mcf_mesh_nfaces(m), c, k;
    const double *X = mcf_mesh_positions(m), *tv = NULL, *nv = NULL;
    const int32_t *F = mcf_mesh_faces(m), *tc = NULL, *nc = NULL;
    corner_rec *r = calloc(3 * (size_t)nf, sizeof *r);
    assert_non_null(r);
    api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, &tv, &tc);
    api_attrs_get(a, API_ATTR_NORMAL, NULL, NULL, &nv, &nc);
    if (N)
        nv = N;
    for (c = 0; c < 3 * nf; c++) {
        for (k = 0; k < 3; k++)
            r[c].r[k] = (float)X[3 * (size_t)F[c] + k];
        for (k = 0; tc && k < 2; k++)
            r[c].r[3 + k] = (float)tv[2 * (size_t)tc[c] + k];
        for (k = 0; nc && k < 3; k++)
            r[c].r[5 + k] = (float)nv[3 * (size_t)nc[c] + k];
    }
    qsort(r, 3 * (size_t)nf, sizeof *r, cmp_corner);
    return r;
}

/* Encodes m with a as Draco (bits: quantization_bits; order: the
 * sequential method) into a new buffer. */
static api_buf encode_attrs(const mcf_mesh *m, const api_attrs *a, int bits,
                            int order)
{
    api_encode_opts o;
    api_buf b;
    mcf_error err;
    double qerr = -1;
    api_encode_opts_init(&o);
    o.format = API_FMT_DRACO;
    o.quantization_bits = bits;
    o.preserve_order = order;
    o.attrs = a;
    api_buf_init(&b, 0);
    if (api_draco_encode(m, &o, &b, &qerr, &err) != MCF_OK)
        fail_msg("encode: %s", err.msg);
    assert_true(qerr >= 0);
    return b;
}

/* car.drc (sequential, raw float32, normals and texcoords) through the
 * flow and back through Draco with the defaults and with each method:
 * every corner keeps its texture coordinate bit for bit, its normal is
 * the smoothed surface's (grouped as the input grouped them), positions
 * are the smoothed ones as float32; the output stays raw float32 like the
 * input, no larger than it, and its attributes keep their bits. */
static void test_attrs_car_roundtrip(void **state)
{
    api_attrs *a = NULL;
    size_t in_bytes;
    mcf_mesh *m = load_attrs("car.drc", &a, &in_bytes);
    double *N = NULL;
    corner_rec *want;
    mcf_error err;
    int order, nf = mcf_mesh_nfaces(m), ncomp, nvals;
    (void)state;

    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, &ncomp, &nvals, NULL, NULL));
    assert_int_equal(ncomp, 2);
    assert_int_equal(nvals, 1856);
    assert_true(api_attrs_get(a, API_ATTR_NORMAL, &ncomp, NULL, NULL, NULL));
    assert_int_equal(ncomp, 3);
    assert_false(api_attrs_get(a, API_ATTR_COLOR, NULL, NULL, NULL, NULL));
    assert_int_equal(api_attrs_float32(a), 1);
    assert_int_equal(api_attrs_draco_bits(a, API_ATTR_POSITION), 0);
    assert_int_equal(api_attrs_draco_bits(a, API_ATTR_TEXCOORD), 0);

    smooth_a_little(m);
    assert_int_equal(api__attrs_normals(a, m, &N, &err), MCF_OK);
    want = corners_of(m, a, N);
    for (order = -1; order <= 1; order++) {
        /* -1: the defaults (auto bits, edgebreaker); 0/1 both methods */
        api_buf b = encode_attrs(m, a, -1, order > 0);
        mcf_mesh *d = NULL;
        api_attrs *da = NULL;
        corner_rec *got;
        assert_int_equal(api_draco_decode_attrs(b.data, b.len, NULL, &d, &da, &err),
                         MCF_OK);
        assert_int_equal(mcf_mesh_nfaces(d), nf);
        assert_int_equal(api_attrs_float32(da), 1);
        assert_int_equal(api_attrs_draco_bits(da, API_ATTR_POSITION), 0);
        assert_int_equal(api_attrs_draco_bits(da, API_ATTR_TEXCOORD), 0);
        assert_int_equal(api_attrs_draco_bits(da, API_ATTR_NORMAL), 0);
        got = corners_of(d, da, NULL);
        if (memcmp(got, want, 3 * (size_t)nf * sizeof *got) != 0)
            fail_msg("order %d: corners differ", order);
        if (order < 0 && b.len > in_bytes)
            fail_msg("car: %zu bytes out, %zu in", b.len, in_bytes);
        free(got);
        api_attrs_free(da);
        mcf_mesh_free(d);
        api_buf_free(&b);
    }
    /* The recomputed normals are unit and face outwards like the faces. */
    {
        const int32_t *F = mcf_mesh_faces(m), *nc;
        const double *X = mcf_mesh_positions(m);
        int f, k, agree = 0, total = 0;
        assert_true(api_attrs_get(a, API_ATTR_NORMAL, NULL, &nvals, NULL, &nc));
        for (f = 0; f < nf; f++) {
            const double *p = X + 3 * F[3 * f], *q = X + 3 * F[3 * f + 1],
                         *r = X + 3 * F[3 * f + 2];
            double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            double v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
            double fn[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                            u[0] * v[1] - u[1] * v[0]};
            for (k = 0; k < 3; k++) {
                const double *n = N + 3 * nc[3 * f + k];
                tl_assert_near(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-12,
                               "|n|^2");
                agree += n[0] * fn[0] + n[1] * fn[1] + n[2] * fn[2] >= 0;
                total++;
            }
        }
        if (agree < 0.99 * total)
            fail_msg("only %d of %d corner normals agree with their face", agree,
                     total);
    }
    free(want);
    free(N);
    api_attrs_free(a);
    mcf_mesh_free(m);
}

/* bunny.drc (14-bit positions) and dragon_vrip.drc (16): the default
 * output keeps the input's bits, is float32, and is no larger than about
 * the input (5% slack: smoothing changes what the predictor sees). */
static void test_attrs_sizes(void **state)
{
    static const struct {
        const char *name;
        int bits;
    } files[] = {{"bunny.drc", 14}, {"dragon_vrip.drc", 16}};
    size_t i;
    (void)state;
    for (i = 0; i < sizeof files / sizeof files[0]; i++) {
        api_attrs *a = NULL, *da = NULL;
        size_t in_bytes;
        mcf_mesh *m = load_attrs(files[i].name, &a, &in_bytes), *d = NULL;
        mcf_error err;
        api_buf b;
        assert_int_equal(api_attrs_draco_bits(a, API_ATTR_POSITION), files[i].bits);
        if (i == 0)
            smooth_a_little(m);
        b = encode_attrs(m, a, -1, 0);
        printf("  %s: %zu bytes in, %zu out (%d bits)\n", files[i].name, in_bytes,
               b.len, files[i].bits);
        if ((double)b.len > 1.05 * (double)in_bytes)
            fail_msg("%s: %zu bytes out, %zu in", files[i].name, b.len, in_bytes);
        assert_int_equal(api_draco_decode_attrs(b.data, b.len, NULL, &d, &da, &err),
                         MCF_OK);
        assert_int_equal(api_attrs_draco_bits(da, API_ATTR_POSITION), files[i].bits);
        assert_int_equal(api_attrs_float32(da), 1);
        api_attrs_free(da);
        mcf_mesh_free(d);
        api_buf_free(&b);
        api_attrs_free(a);
        mcf_mesh_free(m);
    }
}

/* A grid of n x n quads in the plane z = 0.1 xy, texcoords (x, y) with a
 * seam down the middle column (the right half's corners use a second copy
 * of the values, shifted by 0.5 in u), colours from the vertex index. */
static mcf_mesh *grid_mesh(int n, api_attrs **out)
{
    int nv = (n + 1) * (n + 1), nf = 2 * n * n, i, j, c = 0;
    double *X = malloc(3 * sizeof *X * (size_t)nv);
    double *T = malloc(4 * sizeof *T * (size_t)nv);
    double *C = malloc(4 * sizeof *C * (size_t)nv);
    int32_t *F = malloc(3 * sizeof *F * (size_t)nf);
    int32_t *TC = malloc(3 * sizeof *TC * (size_t)nf);
    mcf_error err;
    mcf_mesh *m;
    api_attrs *a;
    assert_true(X && T && C && F && TC);
    for (i = 0; i <= n; i++)
        for (j = 0; j <= n; j++) {
            int v = i * (n + 1) + j;
            X[3 * v] = j / (double)n;
            X[3 * v + 1] = i / (double)n;
            X[3 * v + 2] = 0.1 * X[3 * v] * X[3 * v + 1];
            T[2 * v] = X[3 * v];
            T[2 * v + 1] = X[3 * v + 1];
            T[2 * (nv + v)] = X[3 * v] + 0.5;
            T[2 * (nv + v) + 1] = X[3 * v + 1];
            C[4 * v] = (v % 256) / 255.0;
            C[4 * v + 1] = ((v * 7) % 256) / 255.0;
            C[4 * v + 2] = ((v * 13) % 256) / 255.0;
            C[4 * v + 3] = 1.0;
        }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++) {
            int v = i * (n + 1) + j, sh = j >= n / 2 ? nv : 0;
            int32_t q[6] = {v, v + 1, v + n + 2, v, v + n + 2, v + n + 1};
            for (int k = 0; k < 6; k++, c++) {
                F[c] = q[k];
                TC[c] = q[k] + sh;
            }
        }
    m = mcf_mesh_new(nv, X, nf, F, &err);
    assert_non_null(m);
    a = api_attrs_new(nv, nf);
    assert_non_null(a);
    assert_int_equal(api_attrs_set(a, API_ATTR_TEXCOORD, 2, 2 * nv, T, TC, &err), MCF_OK);
    assert_int_equal(api_attrs_set(a, API_ATTR_COLOR, 4, nv, C, F, &err), MCF_OK);
    /* bad input is refused, the handle unchanged */
    TC[0] = 2 * nv;
    assert_int_equal(api_attrs_set(a, API_ATTR_TEXCOORD, 2, 2 * nv, T, TC, &err),
                     MCF_EINVAL);
    assert_int_equal(api_attrs_set(a, API_ATTR_NORMAL, 2, nv, T, F, &err), MCF_EINVAL);
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, NULL, NULL));
    free(X);
    free(T);
    free(C);
    free(F);
    free(TC);
    *out = a;
    return m;
}

/* A generated mesh that did not come from Draco: auto mode quantizes its
 * positions and texcoords at 16 bits (errors within a step), colours
 * come back as the same bytes, the seam stays a seam. */
static void test_attrs_generated(void **state)
{
    api_attrs *a = NULL, *da = NULL;
    mcf_mesh *m = grid_mesh(8, &a), *d = NULL;
    api_buf b = encode_attrs(m, a, -1, 0);
    mcf_error err;
    int ncomp, nvals, c, k;
    const double *tv, *cv, *tv0, *cv0;
    const int32_t *tc, *cc, *tc0, *cc0;
    (void)state;
    assert_int_equal(api_draco_decode_attrs(b.data, b.len, NULL, &d, &da, &err), MCF_OK);
    assert_int_equal(api_attrs_draco_bits(da, API_ATTR_POSITION), API_DRACO_DEFAULT_BITS);
    assert_int_equal(api_attrs_draco_bits(da, API_ATTR_TEXCOORD),
                     API_DRACO_DEFAULT_TEXCOORD_BITS);
    assert_int_equal(api_attrs_draco_bits(da, API_ATTR_COLOR), 0);
    assert_true(api_attrs_get(da, API_ATTR_COLOR, &ncomp, NULL, &cv, &cc));
    assert_int_equal(ncomp, 4);
    assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, &nvals, &tv, &tc));
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, NULL, &tv0, &tc0));
    assert_true(api_attrs_get(a, API_ATTR_COLOR, NULL, NULL, &cv0, &cc0));
    /* Corners matched through their (unique) positions. */
    for (c = 0; c < 3 * mcf_mesh_nfaces(d); c++) {
        const double *y = mcf_mesh_positions(d) + 3 * mcf_mesh_faces(d)[c];
        int best = -1;
        double bd = 1e9;
        for (k = 0; k < 3 * mcf_mesh_nfaces(m); k++) {
            const double *x = mcf_mesh_positions(m) + 3 * mcf_mesh_faces(m)[k];
            double dd = fabs(x[0] - y[0]) + fabs(x[1] - y[1]) + fabs(x[2] - y[2]);
            /* Among the corners at that vertex, the one with the same side
             * of the seam (the decoded u tells). */
            if (dd < 1e-4 && fabs(tv0[2 * tc0[k]] - tv[2 * tc[c]]) < 1e-4) {
                best = k;
                bd = dd;
            }
        }
        if (best < 0)
            fail_msg("corner %d: no input corner (%g)", c, bd);
        for (k = 0; k < 2; k++)
            tl_assert_near(tv[2 * tc[c] + k], tv0[2 * tc0[best] + k], 1.5 / 65535,
                           "texcoord");
        for (k = 0; k < 4; k++)
            assert_true(cv[4 * cc[c] + k] == cv0[4 * cc0[best] + k]);
    }
    assert_int_equal(nvals, 81 + 9); /* referenced values: the seam column twice */
    /* Once quantized, again through the default (after smoothing): the
     * texcoords come back as the very same floats, at the input's bits and
     * on its grid (values spanning the grid, as here, give Draco's own
     * range the same grid, so this checks the result, not which path). */
    {
        api_buf b2;
        mcf_mesh *d2 = NULL;
        api_attrs *da2 = NULL;
        corner_rec *w, *g;
        int nf = mcf_mesh_nfaces(d);
        smooth_a_little(d);
        b2 = encode_attrs(d, da, -1, 0);
        assert_int_equal(api_draco_decode_attrs(b2.data, b2.len, NULL, &d2, &da2, &err),
                         MCF_OK);
        assert_int_equal(api_attrs_draco_bits(da2, API_ATTR_TEXCOORD),
                         API_DRACO_DEFAULT_TEXCOORD_BITS);
        /* texcoords only: positions moved and were quantized again */
        {
            api_attrs *t1 = api_attrs_new(mcf_mesh_nvertices(d), nf);
            api_attrs *t2 = api_attrs_new(mcf_mesh_nvertices(d2), nf);
            const double *v;
            const int32_t *cr;
            int nv1;
            mcf_mesh *flat1, *flat2;
            double *Z1 = calloc(3 * (size_t)mcf_mesh_nvertices(d), sizeof *Z1);
            double *Z2 = calloc(3 * (size_t)mcf_mesh_nvertices(d2), sizeof *Z2);
            assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, &nv1, &v, &cr));
            assert_int_equal(api_attrs_set(t1, API_ATTR_TEXCOORD, 2, nv1, v, cr, &err),
                             MCF_OK);
            assert_true(api_attrs_get(da2, API_ATTR_TEXCOORD, NULL, &nv1, &v, &cr));
            assert_int_equal(api_attrs_set(t2, API_ATTR_TEXCOORD, 2, nv1, v, cr, &err),
                             MCF_OK);
            /* corner records with the positions zeroed: the multisets of
             * texcoords per corner must agree */
            flat1 = mcf_mesh_new(mcf_mesh_nvertices(d), Z1, nf, mcf_mesh_faces(d), &err);
            flat2 = mcf_mesh_new(mcf_mesh_nvertices(d2), Z2, nf, mcf_mesh_faces(d2), &err);
            assert_non_null(flat1);
            assert_non_null(flat2);
            w = corners_of(flat1, t1, NULL);
            g = corners_of(flat2, t2, NULL);
            if (memcmp(w, g, 3 * (size_t)nf * sizeof *w) != 0)
                fail_msg("texcoords left the input's grid");
            free(w);
            free(g);
            free(Z1);
            free(Z2);
            mcf_mesh_free(flat1);
            mcf_mesh_free(flat2);
            api_attrs_free(t1);
            api_attrs_free(t2);
        }
        api_attrs_free(da2);
        mcf_mesh_free(d2);
        api_buf_free(&b2);
    }
    api_attrs_free(da);
    mcf_mesh_free(d);
    api_buf_free(&b);
    api_attrs_free(a);
    mcf_mesh_free(m);
}

/* Writes len bytes to path. */
static void write_file(const char *path, const void *p, size_t len)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(p, 1, len, fp), len);
    assert_int_equal(fclose(fp), 0);
}

/* Every property line of a PLY header names a known type (draco_decoder
 * once wrote "property  x" for float64 positions). */
static void assert_typed_header(const char *buf, const char *what)
{
    static const char *const types[] = {"char", "uchar", "short", "ushort", "int",
                                        "uint", "float", "double", "int8", "uint8",
                                        "int16", "uint16", "int32", "uint32",
                                        "float32", "float64", NULL};
    const char *p = buf, *end = strstr(buf, "end_header");
    assert_non_null(end);
    while ((p = strstr(p, "\nproperty")) && p < end) {
        char w[4][32] = {"", "", "", ""};
        int n = sscanf(p + 1, "%31s %31s %31s %31s", w[0], w[1], w[2], w[3]), i, k;
        int first = strcmp(w[1], "list") == 0 ? 2 : 1, last = first == 2 ? 3 : 1;
        for (k = first; k <= last; k++) {
            int ok = 0;
            for (i = 0; types[i]; i++)
                ok |= strcmp(w[k], types[i]) == 0;
            if (!ok || n < last + 1)
                fail_msg("%s: untyped property line '%.40s'", what, p + 1);
        }
        p++;
    }
}


/* Texture coordinates Draco quantized on a grid whose origin or range
 * six decimals do not hold: libdraco carries an explicit grid as options
 * text, std::to_string's "%f", so re-encoding on "the input's grid" used
 * another one (u and v spanning 1e-8: range 0, every value at one place;
 * an origin of 0.123456789: 0.123457, every value moved). Through the
 * default re-encode (the input's bits and grid) every value must come back
 * bit for bit, compared as each component's sorted values. */
static int cmp_double(const void *x, const void *y)
{
    const double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

static void check_texcoords_regrid(double scale, double offset)
{
    api_attrs *a = NULL, *da = NULL, *da2 = NULL;
    mcf_mesh *m = grid_mesh(8, &a), *d = NULL, *d2 = NULL;
    const double *tv, *v1, *v2;
    const int32_t *tc;
    double *T, *s1, *s2;
    int32_t *TC;
    int nvals, n1, n2, i, c;
    mcf_error err;
    api_buf b, b2;
    assert_true(api_attrs_get(a, API_ATTR_TEXCOORD, NULL, &nvals, &tv, &tc));
    T = malloc(2 * sizeof *T * (size_t)nvals);
    TC = malloc(3 * sizeof *TC * (size_t)mcf_mesh_nfaces(m));
    assert_true(T && TC);
    for (i = 0; i < 2 * nvals; i++)
        T[i] = offset + scale * tv[i];
    memcpy(TC, tc, 3 * sizeof *TC * (size_t)mcf_mesh_nfaces(m));
    assert_int_equal(api_attrs_set(a, API_ATTR_TEXCOORD, 2, nvals, T, TC, &err), MCF_OK);
    b = encode_attrs(m, a, -1, 0);
    assert_int_equal(api_draco_decode_attrs(b.data, b.len, NULL, &d, &da, &err), MCF_OK);
    assert_int_equal(api_attrs_draco_bits(da, API_ATTR_TEXCOORD),
                     API_DRACO_DEFAULT_TEXCOORD_BITS);
    b2 = encode_attrs(d, da, -1, 0);
    assert_int_equal(api_draco_decode_attrs(b2.data, b2.len, NULL, &d2, &da2, &err),
                     MCF_OK);
    assert_int_equal(mcf_mesh_nfaces(d2), mcf_mesh_nfaces(d));
    assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, &n1, &v1, NULL));
    assert_true(api_attrs_get(da2, API_ATTR_TEXCOORD, NULL, &n2, &v2, NULL));
    assert_int_equal(n1, n2);
    s1 = malloc(sizeof *s1 * (size_t)n1);
    s2 = malloc(sizeof *s2 * (size_t)n2);
    assert_true(s1 && s2);
    for (c = 0; c < 2; c++) {
        for (i = 0; i < n1; i++) {
            s1[i] = v1[2 * i + c];
            s2[i] = v2[2 * i + c];
        }
        qsort(s1, (size_t)n1, sizeof *s1, cmp_double);
        qsort(s2, (size_t)n2, sizeof *s2, cmp_double);
        for (i = 0; i < n1; i++)
            if (s1[i] != s2[i])
                fail_msg("scale %g offset %g: texcoord %d of component %d: %.9g came back %.9g",
                         scale, offset, i, c, s1[i], s2[i]);
    }
    free(s1);
    free(s2);
    free(T);
    free(TC);
    api_attrs_free(da2);
    api_attrs_free(da);
    api_attrs_free(a);
    mcf_mesh_free(d2);
    mcf_mesh_free(d);
    mcf_mesh_free(m);
    api_buf_free(&b2);
    api_buf_free(&b);
}

static void test_attrs_grid_through_options_text(void **state)
{
    (void)state;
    check_texcoords_regrid(1e-8, 0.0);
    check_texcoords_regrid(1e-3, 0.123456789);
}

/* Debian's draco_decoder turns every kind of mcfd Draco output into a PLY
 * with typed properties that mcfd reads back (same face count, car's
 * texcoords through the face `texcoord` list); draco_encoder reads mcfd's
 * float PLY. */
static void test_draco_tools_read_outputs(void **state)
{
    char tmpl[] = "/tmp/mcf_dtools_XXXXXX", *dir, path[600], ply[600], cmd[2000];
    api_attrs *car_a = NULL, *bun_a = NULL, *grid_a = NULL;
    mcf_mesh *car = load_attrs("car.drc", &car_a, NULL);
    mcf_mesh *bunny = load_attrs("bunny.drc", &bun_a, NULL);
    mcf_mesh *grid = grid_mesh(6, &grid_a);
    struct {
        const char *name;
        const mcf_mesh *m;
        const api_attrs *a;
        int bits, order;
    } cases[] = {
        {"car-default", car, car_a, -1, 0},   {"car-seq", car, car_a, -1, 1},
        {"car-q12", car, car_a, 12, 0},       {"bunny-default", bunny, bun_a, -1, 0},
        {"bunny-lossless", bunny, bun_a, 0, 0}, {"grid-default", grid, grid_a, -1, 0},
        {"grid-seq", grid, grid_a, -1, 1},
    };
    size_t i;
    (void)state;
    if (system("command -v draco_decoder >/dev/null 2>&1") != 0) {
        tl_skip("draco_decoder", "Debian's draco package is not installed");
        goto out;
    }
    dir = mkdtemp(tmpl);
    assert_non_null(dir);
    smooth_a_little(car);
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        api_buf b = encode_attrs(cases[i].m, cases[i].a, cases[i].bits, cases[i].order);
        char *out;
        size_t len;
        mcf_mesh *d = NULL;
        api_attrs *da = NULL;
        mcf_error err;
        snprintf(path, sizeof path, "%s/%s.drc", dir, cases[i].name);
        snprintf(ply, sizeof ply, "%s/%s.ply", dir, cases[i].name);
        write_file(path, b.data, b.len);
        snprintf(cmd, sizeof cmd, "draco_decoder -i %s -o %s >/dev/null 2>&1", path, ply);
        if (system(cmd) != 0)
            fail_msg("%s: draco_decoder failed", cases[i].name);
        assert_int_equal(tl_read_file(ply, &out, &len), 0);
        assert_typed_header(out, cases[i].name);
        if (api_ply_decode_attrs(out, len, NULL, &d, &da, &err) != MCF_OK)
            fail_msg("%s: %s", cases[i].name, err.msg);
        assert_int_equal(mcf_mesh_nfaces(d), mcf_mesh_nfaces(cases[i].m));
        assert_int_equal(api_attrs_float32(da), 1);
        if (cases[i].a == car_a) {
            /* draco_decoder writes texcoords per face corner */
            corner_rec *w, *g;
            api_attrs *only_tc = api_attrs_new(mcf_mesh_nvertices(car),
                                               mcf_mesh_nfaces(car));
            const double *v;
            const int32_t *c;
            int nvals;
            assert_true(api_attrs_get(car_a, API_ATTR_TEXCOORD, NULL, &nvals, &v, &c));
            assert_int_equal(api_attrs_set(only_tc, API_ATTR_TEXCOORD, 2, nvals, v, c,
                                           &err), MCF_OK);
            assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, NULL, NULL, NULL));
            assert_true(api_attrs_get(da, API_ATTR_NORMAL, NULL, NULL, NULL, NULL));
            if (cases[i].bits != 12) {
                /* raw float32: positions and texcoords bit for bit */
                api_attrs *dt = api_attrs_new(mcf_mesh_nvertices(d), mcf_mesh_nfaces(d));
                assert_true(api_attrs_get(da, API_ATTR_TEXCOORD, NULL, &nvals, &v, &c));
                assert_int_equal(api_attrs_set(dt, API_ATTR_TEXCOORD, 2, nvals, v, c,
                                               &err), MCF_OK);
                w = corners_of(car, only_tc, NULL);
                g = corners_of(d, dt, NULL);
                if (memcmp(w, g, 3 * (size_t)mcf_mesh_nfaces(d) * sizeof *w) != 0)
                    fail_msg("%s: texcoords differ after draco_decoder", cases[i].name);
                free(w);
                free(g);
                api_attrs_free(dt);
            }
            api_attrs_free(only_tc);
        }
        if (cases[i].a == grid_a)
            assert_true(api_attrs_get(da, API_ATTR_COLOR, NULL, NULL, NULL, NULL));
        remove(ply);
        remove(path);
        free(out);
        api_attrs_free(da);
        mcf_mesh_free(d);
        api_buf_free(&b);
    }
    /* mcfd's PLY of a single-precision input is float: draco_encoder
     * reads it (it refuses double coordinates). */
    {
        api_encode_opts o;
        api_buf b;
        mcf_error err;
        api_encode_opts_init(&o);
        o.format = API_FMT_PLY;
        o.attrs = car_a;
        api_buf_init(&b, 0);
        assert_int_equal(api_mesh_encode(car, &o, &b, &err), MCF_OK);
        assert_non_null(strstr(b.data, "property float x\n"));
        snprintf(ply, sizeof ply, "%s/car.ply", dir);
        snprintf(path, sizeof path, "%s/car.drc", dir);
        write_file(ply, b.data, b.len);
        snprintf(cmd, sizeof cmd, "draco_encoder -i %s -o %s >/dev/null 2>&1", ply, path);
        if (system(cmd) != 0)
            fail_msg("draco_encoder refused mcfd's PLY");
        remove(ply);
        remove(path);
        api_buf_free(&b);
    }
    rmdir(dir);
out:
    api_attrs_free(car_a);
    api_attrs_free(bun_a);
    api_attrs_free(grid_a);
    mcf_mesh_free(car);
    mcf_mesh_free(bunny);
    mcf_mesh_free(grid);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_real_counts),
        cmocka_unit_test(test_real_topology),
        cmocka_unit_test(test_real_dragon),
        cmocka_unit_test(test_car_seams),
        cmocka_unit_test(test_lossless),
        cmocka_unit_test(test_lossless_scans),
        cmocka_unit_test(test_lossless_float_storage),
        cmocka_unit_test(test_quantized),
        cmocka_unit_test(test_quantized_scans),
        cmocka_unit_test(test_levels),
        cmocka_unit_test(test_encode_edge_cases),
        cmocka_unit_test(test_dispatch),
        cmocka_unit_test(test_draco_encoder_cli),
        cmocka_unit_test(test_attrs_car_roundtrip),
        cmocka_unit_test(test_attrs_sizes),
        cmocka_unit_test(test_attrs_generated),
        cmocka_unit_test(test_attrs_grid_through_options_text),
        cmocka_unit_test(test_draco_tools_read_outputs),
        cmocka_unit_test(test_malformed),
        cmocka_unit_test(test_truncated_and_corrupted),
        cmocka_unit_test(test_regression_bool_position),
        cmocka_unit_test(test_regression_huge_faces),
        cmocka_unit_test(test_declared_faces_per_byte),
        cmocka_unit_test(test_hostile_headers),
        cmocka_unit_test(test_limits),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
