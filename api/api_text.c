/* SPDX-License-Identifier: MIT */
/*
 * api_text.c - the text helpers of api_internal.h, shared by the line- and
 * token-based mesh readers (OBJ, OFF, ASCII PLY, ASCII STL), and the raw
 * JSON scan of the parameters' and glTF's checks; and api_nearest_name
 * (api.h), the "did you mean" of the parameters' and mcf's errors.
 *
 * Input buffers are untrusted and not NUL-terminated: every helper takes
 * an explicit end or length and never reads past it. Numbers are copied
 * into a small local buffer before strtod/strtoll see them, and those
 * functions' own leniency (leading white space, a '+' sign for integers)
 * is refused here so that a token means the same to every reader.
 */
#include <ctype.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "api_internal.h"

int api__parse_double(const char *s, size_t n, double *out)
{
    char tmp[64];
    char *end;
    double v;

    if (n == 0 || n >= sizeof tmp)
        return -1;
    memcpy(tmp, s, n);
    tmp[n] = '\0';
    /* strtod skips leading white space; the caller's token has none, and
     * a token with some must not pass for a number. */
    if (api__is_space(tmp[0]) || tmp[0] == '\n')
        return -1;
    v = strtod(tmp, &end);
    if (end != tmp + n)
        return -1;
    *out = v;
    return 0;
}

int api__parse_int(const char *s, size_t n, long long *out)
{
    char tmp[32], *end;
    long long v;

    if (n == 0 || n >= sizeof tmp || api__is_space(s[0]) || s[0] == '\n'
        || s[0] == '+')
        return -1;
    memcpy(tmp, s, n);
    tmp[n] = '\0';
    errno = 0;
    v = strtoll(tmp, &end, 10);
    if (end != tmp + n || errno == ERANGE)
        return -1;
    *out = v;
    return 0;
}

int api__tok_is(const char *t, size_t n, const char *word)
{
    return strlen(word) == n && memcmp(t, word, n) == 0;
}

size_t api__token(const char **s, const char *e, const char **tok)
{
    const char *p = *s;
    while (p < e && api__is_space(*p))
        p++;
    *tok = p;
    while (p < e && !api__is_space(*p))
        p++;
    *s = p;
    return (size_t)(p - *tok);
}

int api__line_next(api__lines *c, const char **s, const char **e)
{
    const char *nl;
    if (c->p >= c->end)
        return 0;
    nl = memchr(c->p, '\n', (size_t)(c->end - c->p));
    *s = c->p;
    *e = nl ? nl : c->end;
    c->p = nl ? nl + 1 : c->end;
    c->line++;
    return 1;
}

/* api__show and api__show_utf8: high is the first byte value that is
 * shown as '?' (0x7f or 0x80; 0x7f, DEL, always is). */
static const char *show(const char *t, size_t n, unsigned high,
                        char out[API__SHOWN])
{
    size_t i, k = n > 32 ? 32 : n;
    for (i = 0; i < k; i++) {
        unsigned char ch = (unsigned char)t[i];
        out[i] = (ch < 0x20 || ch == 0x7f || ch >= high) ? '?' : (char)ch;
    }
    if (n > k) {
        memcpy(out + k, "...", 3);
        k += 3;
    }
    out[k] = '\0';
    return out;
}

const char *api__show(const char *t, size_t n, char out[API__SHOWN])
{
    return show(t, n, 0x7f, out);
}

const char *api__show_utf8(const char *t, size_t n, char out[API__SHOWN])
{
    return show(t, n, 0x100, out);
}

int api__json_next(const char *s, size_t n, size_t *i)
{
    char c;
    if (*i >= n)
        return -1;
    c = s[(*i)++];
    if (c == '"')
        while (*i < n) {
            char d = s[(*i)++];
            if (d == '\\')
                (*i)++;
            else if (d == '"')
                break;
        }
    return (unsigned char)c;
}

/* One character as the nearest name compares it: case and '-'/'_' folded. */
static int fold(char c)
{
    return c == '-' ? '_' : tolower((unsigned char)c);
}

/* The optimal-string-alignment distance of a and b (each < 64 chars). */
static size_t edit_distance(const char *a, size_t la, const char *b, size_t lb)
{
    unsigned char d[64][64];    /* distances are at most 63 */
    size_t i, j;

    for (i = 0; i <= la; i++)
        d[i][0] = (unsigned char)i;
    for (j = 0; j <= lb; j++)
        d[0][j] = (unsigned char)j;
    for (i = 1; i <= la; i++)
        for (j = 1; j <= lb; j++) {
            size_t sub = d[i - 1][j - 1] + (size_t)(fold(a[i - 1]) != fold(b[j - 1]));
            size_t del = d[i - 1][j] + (size_t)1, ins = d[i][j - 1] + (size_t)1;
            size_t v = sub < del ? sub : del;
            if (ins < v)
                v = ins;
            if (i > 1 && j > 1 && fold(a[i - 1]) == fold(b[j - 2]) &&
                fold(a[i - 2]) == fold(b[j - 1]) && d[i - 2][j - 2] + (size_t)1 < v)
                v = d[i - 2][j - 2] + (size_t)1;
            d[i][j] = (unsigned char)v;
        }
    return d[la][lb];
}

const char *api_nearest_name(const char *word, const char *const *names, size_t n)
{
    const char *best = NULL;
    size_t lw = word ? strlen(word) : 64, bd = 3, i;

    if (lw >= 64)
        return NULL;
    for (i = 0; i < n; i++) {
        size_t ln = names[i] ? strlen(names[i]) : 64, dist;
        if (ln >= 64 || (ln > lw ? ln - lw : lw - ln) >= bd)
            continue;
        dist = edit_distance(word, lw, names[i], ln);
        /* a tie goes to a name of word's length (desbrun3: desbrun2) */
        if (2 * dist < lw && (dist < bd || (dist == bd && best && ln == lw && strlen(best) != lw))) {
            bd = dist;
            best = names[i];
        }
    }
    return best;
}
