/* SPDX-License-Identifier: MIT */
/*
 * test_api_mesh.c - the byte buffer (api_buf.c), the default limits
 * (api_limits.c), format detection and naming and the decode/encode
 * dispatchers (api_mesh.c).
 *
 * Detection is checked on the real files of tests/data/meshes (OBJ and
 * Draco) and on minimal headers of every other format, including a binary
 * STL whose header begins with "solid".
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api.h"

static void test_buf_append_printf(void **state)
{
    api_buf b;
    char *p;
    size_t len = 99;
    int i;
    (void)state;
    api_buf_init(&b, 0);
    assert_null(b.data);
    assert_int_equal(api_buf_append(&b, "ab", 2), MCF_OK);
    assert_int_equal(api_buf_printf(&b, "%d-%s", 42, "x"), MCF_OK);
    assert_int_equal(b.len, 6);
    assert_string_equal(b.data, "ab42-x");
    /* Growth through many doublings keeps the content and the NUL. */
    for (i = 0; i < 10000; i++)
        assert_int_equal(api_buf_printf(&b, "%05d", i), MCF_OK);
    assert_int_equal(b.len, 6 + 5 * 10000);
    assert_memory_equal(b.data + 6 + 5 * 9999, "09999", 6);
    p = api_buf_detach(&b, &len);
    assert_int_equal(len, 6 + 5 * 10000);
    assert_int_equal(p[len], '\0');
    assert_null(b.data);
    assert_int_equal(b.len, 0);
    free(p);
    /* Detaching an empty buffer gives an empty string. */
    p = api_buf_detach(&b, &len);
    assert_non_null(p);
    assert_int_equal(len, 0);
    assert_string_equal(p, "");
    free(p);
    api_buf_free(&b);
    api_buf_free(&b); /* twice is fine */
}

static void test_buf_max(void **state)
{
    api_buf b;
    char big[300];
    (void)state;
    api_buf_init(&b, 10);
    assert_int_equal(api_buf_append(&b, "0123456", 7), MCF_OK);
    assert_int_equal(api_buf_append(&b, "7890", 4), MCF_ELIMIT);
    assert_int_equal(b.len, 7);
    assert_string_equal(b.data, "0123456");
    assert_int_equal(api_buf_printf(&b, "%s", "abcd"), MCF_ELIMIT);
    assert_int_equal(b.len, 7);
    assert_string_equal(b.data, "0123456");
    assert_int_equal(api_buf_printf(&b, "%s", "abc"), MCF_OK); /* exactly max */
    assert_string_equal(b.data, "0123456abc");
    assert_int_equal(api_buf_append(&b, "", 0), MCF_OK);
    assert_int_equal(api_buf_append(&b, "x", 1), MCF_ELIMIT);
    api_buf_free(&b);
    /* max = SIZE_MAX is "no limit" too: max + 1 must not wrap to 0 (it
     * used to shrink the buffer to nothing and free it under the data) */
    api_buf_init(&b, (size_t)-1);
    for (int i = 0; i < 100; i++)
        assert_int_equal(api_buf_append(&b, "0123456789", 10), MCF_OK);
    assert_int_equal(b.len, 1000);
    assert_int_equal(b.data[999], '9');
    api_buf_free(&b);
    /* printf through the measuring path (text larger than the spare room). */
    memset(big, 'z', sizeof big - 1);
    big[sizeof big - 1] = '\0';
    api_buf_init(&b, 298);
    assert_int_equal(api_buf_printf(&b, "%s", big), MCF_ELIMIT);
    assert_int_equal(b.len, 0);
    big[sizeof big - 2] = '\0';
    assert_int_equal(api_buf_printf(&b, "%s", big), MCF_OK);
    assert_int_equal(b.len, 298);
    api_buf_free(&b);
}

static void test_limits_default(void **state)
{
    api_limits l;
    (void)state;
    api_limits_default(&l);
    assert_int_equal(l.max_input_bytes, 256u << 20);
    assert_int_equal(l.max_vertices, 100000000);
    assert_int_equal(l.max_faces, 200000000);
    assert_int_equal(l.max_iterations, 100000);
    assert_true(l.max_work == 2e10);
    assert_int_equal(l.max_json_bytes, 64u << 10);
    assert_int_equal(l.max_json_depth, 16);
    assert_int_equal(l.max_fixed, l.max_vertices);
}

static api_format detect_str(const char *s)
{
    return api_format_detect(s, strlen(s));
}

static api_format detect_file(const char *name)
{
    char path[4096], *buf;
    size_t len;
    api_format f;
    snprintf(path, sizeof path, "%s", tl_need_mesh(name));
    if (tl_read_file(path, &buf, &len) != 0)
        fail_msg("cannot read %s", path);
    f = api_format_detect(buf, len);
    free(buf);
    return f;
}

static void test_detect(void **state)
{
    unsigned char stl[84 + 2 * 50];
    (void)state;
    assert_int_equal(detect_file("sphere_cgal.obj"), API_FMT_OBJ);
    assert_int_equal(detect_file("bunny_npm_closed.obj"), API_FMT_OBJ);
    /* no comment: the first byte is the 'v' of a vertex (as in spot.obj) */
    assert_int_equal(detect_str("v 0.348799 -0.334989 -0.0832331\nv 0 1 0\nv 1 0 0\n"
                                "f 1 2 3\n"), API_FMT_OBJ);
    assert_int_equal(detect_file("bunny.drc"), API_FMT_DRACO);
    assert_int_equal(detect_file("car.drc"), API_FMT_DRACO);
    assert_int_equal(detect_str("ply\nformat ascii 1.0\n"), API_FMT_PLY);
    assert_int_equal(detect_str("ply\r\nformat ascii 1.0\r\n"), API_FMT_PLY);
    assert_int_equal(detect_str("OFF\n3 1 0\n"), API_FMT_OFF);
    assert_int_equal(detect_str("  COFF 3 1 0\n"), API_FMT_OFF);
    assert_int_equal(detect_str("OFF"), API_FMT_OFF);
    assert_int_equal(detect_str("solid cube\n  facet normal 0 0 1\n"), API_FMT_STL);
    assert_int_equal(detect_str("solid empty\nendsolid empty\n"), API_FMT_STL);
    /* Binary STL: 84-byte header + 50 bytes per triangle; the header may
     * say "solid" and must still be taken as binary. */
    memset(stl, 0, sizeof stl);
    memcpy(stl, "solid but binary", 16);
    stl[80] = 2;
    assert_int_equal(api_format_detect(stl, sizeof stl), API_FMT_STL);
    stl[80] = 3; /* size rule broken: "solid" without "facet" is nothing */
    assert_int_equal(api_format_detect(stl, sizeof stl), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("# only a comment"), API_FMT_OBJ);
    assert_int_equal(detect_str("\n\nv 1 2 3\n"), API_FMT_OBJ);
    assert_int_equal(detect_str("o thing\nv 1 2 3\n"), API_FMT_OBJ);
    assert_int_equal(detect_str("hello world"), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("{\"json\": 1}"), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("plyx"), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("OFFICE"), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("DRAC"), API_FMT_UNKNOWN);
    assert_int_equal(api_format_detect(NULL, 0), API_FMT_UNKNOWN);
    assert_int_equal(api_format_detect("", 0), API_FMT_UNKNOWN);
}

/* An OFF file may open with '#' comment and blank lines (api_off_decode
 * skips them); detection used to stop at the first '#' and answer
 * UNKNOWN, so api_mesh_decode refused the file with EFORMAT. */
static void test_detect_commented_off(void **state)
{
    static const char off[] = "# written by a modeller\n"
                              "\n"
                              "   # indented comment\r\n"
                              "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    char *big;
    size_t n;
    mcf_mesh *m = NULL;
    mcf_error err;
    api_format f = API_FMT_UNKNOWN;
    (void)state;
    assert_int_equal(detect_str(off), API_FMT_OFF);
    assert_int_equal(detect_str("#\n#\nCOFF 3 1 0\n"), API_FMT_OFF);
    assert_int_equal(detect_str("  \n# c\n\n  NOFF\n"), API_FMT_OFF);
    assert_int_equal(api_mesh_decode(off, sizeof off - 1, NULL, &m, &f, &err),
                     MCF_OK);
    assert_int_equal(f, API_FMT_OFF);
    assert_int_equal(mcf_mesh_nvertices(m), 3);
    assert_int_equal(mcf_mesh_nfaces(m), 1);
    mcf_mesh_free(m);
    /* Only whole keywords count, as without comments. */
    assert_int_equal(detect_str("# c\nOFFICE\n"), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("# c\nOFF"), API_FMT_OFF);
    /* An OBJ with a comment header stays OBJ, even when a comment names
     * OFF; so does a file of comments only. */
    assert_int_equal(detect_str("# exported\n# OFF\nv 1 2 3\nf 1 1 1\n"),
                     API_FMT_OBJ);
    assert_int_equal(detect_str("# OFF"), API_FMT_OBJ);
    assert_int_equal(detect_str("# a\n# b"), API_FMT_OBJ);
    assert_int_equal(detect_file("sphere_cgal.obj"), API_FMT_OBJ); /* '#' first */
    /* Comments do not make other formats: PLY and Draco need their magic
     * at byte 0, ASCII STL its "solid" first. */
    assert_int_equal(detect_str("# c\nply\nformat ascii 1.0\n"), API_FMT_UNKNOWN);
    assert_int_equal(detect_str("# c\nsolid x\nfacet normal 0 0 1\n"),
                     API_FMT_UNKNOWN);
    assert_int_equal(detect_str("# c\nDRACO"), API_FMT_UNKNOWN);
    /* Bounded: the keyword is looked for within the first 64 KiB after
     * the leading white space (DETECT_WINDOW in api_mesh.c); a comment
     * header just inside that passes, one running past it does not. */
    n = 65536 + 100;
    big = malloc(n);
    assert_non_null(big);
    memset(big, 'c', n);
    big[0] = '#';
    memcpy(big + 65536 - 5, "\nOFF\n", 5); /* keyword at byte 65532 */
    assert_int_equal(api_format_detect(big, n), API_FMT_OFF);
    big[65536 - 5] = 'c'; /* now the comment line runs past the window */
    memcpy(big + n - 5, "\nOFF\n", 5);
    assert_int_equal(api_format_detect(big, n), API_FMT_UNKNOWN);
    free(big);
}

static void test_names(void **state)
{
    (void)state;
    assert_int_equal(api_format_from_name("obj"), API_FMT_OBJ);
    assert_int_equal(api_format_from_name(".drc"), API_FMT_DRACO);
    assert_int_equal(api_format_from_name("draco"), API_FMT_DRACO);
    assert_int_equal(api_format_from_name("out.ply"), API_FMT_PLY);
    assert_int_equal(api_format_from_name("/tmp/a.b/MODEL.STL"), API_FMT_STL);
    assert_int_equal(api_format_from_name("x.off"), API_FMT_OFF);
    assert_int_equal(api_format_from_name("dir.obj/file"), API_FMT_UNKNOWN);
    assert_int_equal(api_format_from_name("x.gltf"), API_FMT_GLTF);
    assert_int_equal(api_format_from_name("scan.GLB"), API_FMT_GLB);
    assert_int_equal(api_format_from_name("x.fbx"), API_FMT_UNKNOWN);
    assert_int_equal(api_format_from_name(""), API_FMT_UNKNOWN);
    assert_int_equal(api_format_from_name(NULL), API_FMT_UNKNOWN);
    assert_string_equal(api_format_name(API_FMT_DRACO), "draco");
    assert_string_equal(api_format_ext(API_FMT_DRACO), ".drc");
    assert_string_equal(api_format_ext(API_FMT_OBJ), ".obj");
    assert_string_equal(api_format_mime(API_FMT_OBJ), "model/obj");
    assert_string_equal(api_format_mime(API_FMT_STL), "model/stl");
    assert_string_equal(api_format_name((api_format)99), "unknown");
    /* Every format's name and extension lead back to it. */
    for (int f = API_FMT_OBJ; f <= API_FMT_OFF; f++) {
        assert_int_equal(api_format_from_name(api_format_name((api_format)f)), f);
        assert_int_equal(api_format_from_name(api_format_ext((api_format)f)), f);
    }
}

static void test_encode_opts(void **state)
{
    api_encode_opts o;
    (void)state;
    memset(&o, 0x55, sizeof o);
    api_encode_opts_init(&o);
    assert_int_equal(o.format, API_FMT_UNKNOWN);
    assert_int_equal(o.quantization_bits, -1); /* auto */
    assert_int_equal(o.compression_level, 7);
    assert_int_equal(o.preserve_order, 0);
    assert_int_equal(o.ply_binary, 1);
    assert_int_equal(o.stl_binary, 1);
    assert_null(o.ply_mean_curvature);
    assert_null(o.ply_gaussian_curvature);
    assert_int_equal(o.ply_curvature, 0);
    assert_null(o.attrs);
}

static void test_dispatch(void **state)
{
    const char obj[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    mcf_mesh *m = NULL;
    mcf_error err;
    api_format f = API_FMT_UNKNOWN;
    api_limits lim;
    api_encode_opts o;
    api_buf out;
    (void)state;
    api_limits_default(&lim);
    assert_int_equal(api_mesh_decode(obj, sizeof obj - 1, &lim, &m, &f, &err),
                     MCF_OK);
    assert_int_equal(f, API_FMT_OBJ);
    assert_int_equal(mcf_mesh_nfaces(m), 1);
    api_encode_opts_init(&o);
    api_buf_init(&out, 0);
    assert_int_equal(api_mesh_encode(m, &o, &out, &err), MCF_EINVAL);
    o.format = API_FMT_OBJ;
    assert_int_equal(api_mesh_encode(m, &o, &out, &err), MCF_OK);
    assert_non_null(strstr(out.data, "\nf 1 2 3\n"));
    api_buf_free(&out);
    mcf_mesh_free(m);
    m = NULL;

    assert_int_equal(api_mesh_decode("hello", 5, &lim, &m, &f, &err), MCF_EFORMAT);
    assert_int_equal(f, API_FMT_UNKNOWN);
    assert_non_null(strstr(err.msg, "unknown mesh format"));
    assert_int_equal(api_mesh_decode("", 0, &lim, &m, NULL, &err), MCF_EDECODE);
    lim.max_input_bytes = 8;
    assert_int_equal(api_mesh_decode(obj, sizeof obj - 1, &lim, &m, NULL, &err),
                     MCF_ELIMIT);
    assert_non_null(strstr(err.msg, "max_input_bytes"));
    assert_null(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_buf_append_printf),
        cmocka_unit_test(test_buf_max),
        cmocka_unit_test(test_limits_default),
        cmocka_unit_test(test_detect),
        cmocka_unit_test(test_detect_commented_off),
        cmocka_unit_test(test_names),
        cmocka_unit_test(test_encode_opts),
        cmocka_unit_test(test_dispatch),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
