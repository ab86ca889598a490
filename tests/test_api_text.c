/* SPDX-License-Identifier: MIT */
/*
 * test_api_text.c - the helpers the mesh codecs share (api_internal.h):
 * the text helpers of api_text.c, the inline byte helpers, and the
 * decode prologue, triangle array, core-mesh step and encode roll-back
 * of api_mesh.c.
 *
 * The codecs' own tests exercise these through every reader and writer;
 * here each contract is pinned down on its own, boundaries first: inputs
 * are exact-size heap copies without a NUL (or a length shorter than the
 * text), so a read past the end fails under AddressSanitizer, and the
 * messages the codecs build from them are compared byte for byte.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "../api/api_internal.h"

/* A malloc'ed copy of s without its NUL (free it). */
static char *bytes(const char *s, size_t *n)
{
    char *p;
    *n = strlen(s);
    p = malloc(*n ? *n : 1);
    assert_non_null(p);
    memcpy(p, s, *n);
    return p;
}

static void test_is_space_tok_is(void **state)
{
    const char *sp = " \t\r\f\v";
    (void)state;
    for (; *sp; sp++)
        assert_true(api__is_space(*sp));
    assert_false(api__is_space('\n')); /* ends a line: never in-line space */
    assert_false(api__is_space('\0'));
    assert_false(api__is_space('a'));
    assert_false(api__is_space((char)0xa0)); /* negative as a char */
    assert_false(api__is_space(0xa0));
    assert_true(api__tok_is("vertex", 6, "vertex"));
    assert_true(api__tok_is("vertex_indices", 6, "vertex")); /* only n bytes */
    assert_false(api__tok_is("vert", 4, "vertex"));
    assert_false(api__tok_is("vertex", 6, "vert"));
    assert_true(api__tok_is("", 0, ""));
}

static void test_token(void **state)
{
    size_t n;
    char *buf = bytes("  ab\tc \r", &n);
    const char *s = buf, *e = buf + n, *t = NULL;
    (void)state;
    assert_int_equal(api__token(&s, e, &t), 2);
    assert_ptr_equal(t, buf + 2);
    assert_int_equal(api__token(&s, e, &t), 1);
    assert_ptr_equal(t, buf + 5);
    assert_int_equal(api__token(&s, e, &t), 0); /* trailing space and '\r' */
    assert_ptr_equal(s, e);
    assert_int_equal(api__token(&s, e, &t), 0);
    /* The end bounds the token even inside a word. */
    s = buf;
    e = buf + 3;
    assert_int_equal(api__token(&s, e, &t), 1);
    assert_ptr_equal(t, buf + 2);
    free(buf);
    /* Nothing at all. */
    s = e = "";
    assert_int_equal(api__token(&s, e, &t), 0);
}

static void test_line_next(void **state)
{
    size_t n;
    char *buf = bytes("a\r\nb\n\nlast", &n);
    api__lines c = {buf, buf + n, 0};
    const char *s, *e;
    (void)state;
    assert_true(api__line_next(&c, &s, &e));
    assert_int_equal(c.line, 1);
    assert_int_equal(e - s, 2); /* "a\r": the '\r' stays */
    assert_memory_equal(s, "a\r", 2);
    assert_true(api__line_next(&c, &s, &e));
    assert_int_equal(c.line, 2);
    assert_int_equal(e - s, 1);
    assert_int_equal(*s, 'b');
    assert_true(api__line_next(&c, &s, &e));
    assert_int_equal(c.line, 3);
    assert_ptr_equal(s, e); /* the empty line */
    assert_true(api__line_next(&c, &s, &e)); /* no final '\n' */
    assert_int_equal(c.line, 4);
    assert_int_equal(e - s, 4);
    assert_ptr_equal(e, buf + n);
    assert_false(api__line_next(&c, &s, &e));
    assert_int_equal(c.line, 4);
    free(buf);
    /* An empty buffer has no line; "\n" one, empty. */
    c.p = c.end = "";
    c.line = 0;
    assert_false(api__line_next(&c, &s, &e));
    c.p = "\n";
    c.end = c.p + 1;
    assert_true(api__line_next(&c, &s, &e));
    assert_ptr_equal(s, e);
    assert_false(api__line_next(&c, &s, &e));
    assert_int_equal(c.line, 1);
}

static void test_parse_int(void **state)
{
    static const char *const bad[] = {
        "", "+1", " 1", "\n1", "1 ", "12a", "0x10", "1.0", "-", "--1",
        "9223372036854775808", "-9223372036854775809",
        "1234567890123456789012345678901", /* 31 bytes: too long */
        NULL};
    long long v;
    size_t n;
    int i;
    (void)state;
    for (i = 0; bad[i]; i++) {
        char *b = bytes(bad[i], &n);
        v = 77;
        if (api__parse_int(b, n, &v) != -1)
            fail_msg("'%s' parsed as an integer", bad[i]);
        assert_int_equal(v, 77); /* unchanged */
        free(b);
    }
    assert_int_equal(api__parse_int("0", 1, &v), 0);
    assert_int_equal(v, 0);
    assert_int_equal(api__parse_int("-12", 3, &v), 0);
    assert_int_equal(v, -12);
    assert_int_equal(api__parse_int("007", 3, &v), 0);
    assert_int_equal(v, 7);
    assert_int_equal(api__parse_int("9223372036854775807", 19, &v), 0);
    assert_true(v == 9223372036854775807LL);
    assert_int_equal(api__parse_int("-9223372036854775808", 20, &v), 0);
    assert_true(v == -9223372036854775807LL - 1);
    /* Only n bytes are read: "123" with n = 2 is 12. */
    {
        char *b = bytes("123", &n);
        assert_int_equal(api__parse_int(b, 2, &v), 0);
        assert_int_equal(v, 12);
        free(b);
    }
}

static void test_parse_double(void **state)
{
    char big[64];
    double v;
    size_t n;
    char *b;
    (void)state;
    b = bytes("1.5e3", &n);
    assert_int_equal(api__parse_double(b, n, &v), 0);
    assert_true(v == 1500.0);
    assert_int_equal(api__parse_double(b, 3, &v), 0); /* "1.5" */
    assert_true(v == 1.5);
    free(b);
    assert_int_equal(api__parse_double("-0", 2, &v), 0);
    assert_true(v == 0.0 && signbit(v));
    /* Non-finite values pass: the callers decide. */
    assert_int_equal(api__parse_double("nan", 3, &v), 0);
    assert_true(isnan(v));
    assert_int_equal(api__parse_double("1e999", 5, &v), 0);
    assert_true(isinf(v));
    assert_int_equal(api__parse_double("", 0, &v), -1);
    assert_int_equal(api__parse_double(" 1", 2, &v), -1);
    assert_int_equal(api__parse_double("\n1", 2, &v), -1);
    assert_int_equal(api__parse_double("1,5", 3, &v), -1);
    /* 63 bytes is the longest number; 64 is refused. */
    memset(big, '0', sizeof big);
    big[0] = '1';
    assert_int_equal(api__parse_double(big, 63, &v), 0);
    assert_true(v == 1e62);
    assert_int_equal(api__parse_double(big, 64, &v), -1);
}

static void test_show(void **state)
{
    char out[API__SHOWN], in[40];
    (void)state;
    assert_string_equal(api__show("abc", 3, out), "abc");
    assert_string_equal(api__show("", 0, out), "");
    assert_string_equal(api__show("a\tb\x01\x7f", 5, out), "a?b??");
    /* Bytes >= 0x80: '?' for api__show, kept by api__show_utf8. */
    assert_string_equal(api__show("\xc3\xa9t\xc3\xa9", 5, out), "??t??");
    assert_string_equal(api__show_utf8("\xc3\xa9t\xc3\xa9", 5, out),
                        "\xc3\xa9t\xc3\xa9");
    assert_string_equal(api__show_utf8("a\tb\x01\x7f", 5, out), "a?b??");
    /* 32 bytes are shown whole; a longer token is cut and marked. */
    memset(in, 'x', sizeof in);
    assert_string_equal(api__show(in, 32, out),
                        "xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx");
    assert_string_equal(api__show(in, 40, out),
                        "xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx...");
    assert_int_equal(strlen(api__show_utf8(in, 33, out)), 35);
    assert_true(35 < API__SHOWN); /* the longest result and its NUL fit */
}

static void test_le_bytes(void **state)
{
    unsigned char b[4];
    (void)state;
    api__put_le32(b, 0x12345678u);
    assert_int_equal(b[0], 0x78);
    assert_int_equal(b[1], 0x56);
    assert_int_equal(b[2], 0x34);
    assert_int_equal(b[3], 0x12);
    assert_int_equal(api__get_le32(b), 0x12345678u);
    api__put_le32(b, 0xffffffffu);
    assert_int_equal(api__get_le32(b), 0xffffffffu);
    api__put_f32(b, 1.0f); /* IEEE 754: 0x3f800000 */
    assert_int_equal(api__get_le32(b), 0x3f800000u);
    assert_int_equal(b[3], 0x3f);
    api__put_f32(b, -FLT_MAX);
    assert_int_equal(api__get_le32(b), 0xff7fffffu);
}

static void test_decode_begin(void **state)
{
    api_limits def, small;
    const api_limits *lim = NULL;
    mcf_error err;
    (void)state;
    assert_int_equal(api__decode_begin("xyz", "a", 1, &lim, &def, &err), MCF_OK);
    assert_ptr_equal(lim, &def); /* NULL limits: the defaults, in def */
    assert_int_equal(def.max_vertices, 100000000);
    api_limits_default(&small);
    small.max_input_bytes = 4;
    lim = &small;
    assert_int_equal(api__decode_begin("xyz", "abcd", 4, &lim, &def, &err),
                     MCF_OK);
    assert_ptr_equal(lim, &small); /* given limits are kept */
    assert_int_equal(api__decode_begin("xyz", "abcde", 5, &lim, &def, &err),
                     MCF_ELIMIT);
    assert_string_equal(err.msg,
                        "xyz: input of 5 bytes exceeds max_input_bytes (4)");
    assert_int_equal(err.status, MCF_ELIMIT);
    assert_int_equal(api__decode_begin("xyz", NULL, 3, &lim, &def, &err),
                     MCF_EINVAL);
    assert_string_equal(err.msg, "xyz: NULL buffer");
    assert_int_equal(api__decode_begin("xyz", "", 0, &lim, &def, &err),
                     MCF_EDECODE);
    assert_string_equal(err.msg, "xyz: empty input");
    assert_int_equal(api__decode_begin("xyz", NULL, 0, &lim, &def, &err),
                     MCF_EDECODE); /* NULL with 0 bytes is just empty */
    assert_int_equal(api__decode_begin("xyz", "", 0, &lim, &def, NULL),
                     MCF_EDECODE); /* err may be NULL */
}

static void test_mesh_new(void **state)
{
    const double X[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const int32_t F[3] = {0, 1, 2}, bad[3] = {0, 1, 3};
    mcf_mesh *m = NULL, *first;
    mcf_error err;
    (void)state;
    assert_int_equal(api__mesh_new(3, X, 1, F, &m, &err), MCF_OK);
    assert_non_null(m);
    assert_int_equal(mcf_mesh_nvertices(m), 3);
    assert_int_equal(mcf_mesh_nfaces(m), 1);
    first = m;
    assert_int_equal(api__mesh_new(3, X, 1, bad, &m, &err), MCF_EMESH);
    assert_ptr_equal(m, first); /* *out unchanged on failure */
    assert_int_equal(err.status, MCF_EMESH);
    assert_int_equal(api__mesh_new(3, X, 1, bad, &m, NULL), MCF_EMESH);
    assert_ptr_equal(m, first);
    mcf_mesh_free(m);
}

static void test_tris_add(void **state)
{
    api__tris t = {NULL, 0, 0};
    long long want = -1;
    int32_t i;
    (void)state;
    /* first = 2, max = 5: room for 2, then 4, then 5 (capped), then no
     * more; the capacity asked for is reported on the way. */
    for (i = 0; i < 5; i++) {
        assert_int_equal(api__tris_add(&t, i, i + 1, i + 2, 5, 2, &want), MCF_OK);
        assert_int_equal(t.n, i + 1);
        assert_int_equal(t.cap, i < 2 ? 2 : i < 4 ? 4 : 5);
        assert_int_equal(want, t.cap);
    }
    assert_int_equal(api__tris_add(&t, 9, 9, 9, 5, 2, NULL), MCF_ELIMIT);
    assert_int_equal(t.n, 5); /* unchanged */
    for (i = 0; i < 5; i++) {
        assert_int_equal(t.F[3 * i], i);
        assert_int_equal(t.F[3 * i + 1], i + 1);
        assert_int_equal(t.F[3 * i + 2], i + 2);
    }
    free(t.F);
    /* max = 0 refuses the first triangle without allocating. */
    t.F = NULL;
    t.n = t.cap = 0;
    assert_int_equal(api__tris_add(&t, 0, 1, 2, 0, 1024, NULL), MCF_ELIMIT);
    assert_null(t.F);
}

static void test_encode_end(void **state)
{
    api_buf b;
    mcf_error err;
    (void)state;
    api_buf_init(&b, 0);
    assert_int_equal(api_buf_append(&b, "keep", 4), MCF_OK);
    assert_int_equal(api_buf_append(&b, "junk", 4), MCF_OK);
    assert_int_equal(api__encode_end(&b, 8, MCF_OK, "c", 1, "x", &err), MCF_OK);
    assert_int_equal(b.len, 8); /* success: nothing dropped */
    b.max = 100;
    assert_int_equal(api__encode_end(&b, 4, MCF_ELIMIT, "c", 7, "things", &err),
                     MCF_ELIMIT);
    assert_int_equal(b.len, 4);
    assert_string_equal(b.data, "keep"); /* earlier content kept */
    assert_string_equal(err.msg, "c: output exceeds its maximum of 100 bytes");
    assert_int_equal(api_buf_append(&b, "more", 4), MCF_OK);
    assert_int_equal(api__encode_end(&b, 4, MCF_ENOMEM, "c", 7, "things", &err),
                     MCF_ENOMEM);
    assert_string_equal(b.data, "keep");
    assert_string_equal(err.msg, "c: out of memory writing 7 things");
    assert_int_equal(err.status, MCF_ENOMEM);
    api_buf_free(&b);
    /* A buffer that never got data: nothing to cut, no NUL to write. */
    api_buf_init(&b, 0);
    assert_int_equal(api__encode_end(&b, 0, MCF_ELIMIT, "c", 0, "x", NULL),
                     MCF_ELIMIT);
    assert_null(b.data);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_is_space_tok_is),
        cmocka_unit_test(test_token),
        cmocka_unit_test(test_line_next),
        cmocka_unit_test(test_parse_int),
        cmocka_unit_test(test_parse_double),
        cmocka_unit_test(test_show),
        cmocka_unit_test(test_le_bytes),
        cmocka_unit_test(test_decode_begin),
        cmocka_unit_test(test_mesh_new),
        cmocka_unit_test(test_tris_add),
        cmocka_unit_test(test_encode_end),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
