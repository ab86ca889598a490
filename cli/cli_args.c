/* SPDX-License-Identifier: MIT */
/*
 * cli_args.c - the options of `mcf smooth` and `mcf convert`: every job
 * parameter of the api table (api_params_describe) is an option, set
 * through api_params_set, and each command's --help is printed from the
 * same table, so the tool, the daemon and the help cannot disagree.
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api.h"
#include "cli.h"

/* -------------------------------------------------------------- arguments */


/* The parameter table (api_params_describe): every job parameter is an
 * option of `mcf smooth`, the output ones of `mcf convert` too, so the
 * tool, the daemon and the help cannot disagree on names or ranges. */
cJSON *param_table(void)
{
    cJSON *t = api_params_describe(NULL);
    if (!t)
        fail(1, "out of memory");
    return t;
}

static const cJSON *find_param(const cJSON *table, const char *key, int smooth)
{
    const cJSON *e;
    cJSON_ArrayForEach(e, table) {
        if (strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(e, "name")), key) == 0)
            return (smooth || cJSON_IsTrue(cJSON_GetObjectItem(e, "output"))) ? e : NULL;
    }
    return NULL;
}

static int is_type(const cJSON *e, const char *type)
{
    return strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(e, "type")), type) == 0;
}

/* Applies one parameter; a refusal is a usage error (exit 2), a limit 1. */
static int set_param(api_params *p, const char *key, const char *value,
                     const api_limits *lim)
{
    mcf_error err = {MCF_OK, ""};
    mcf_status st = api_params_set(p, key, value, lim, &err);
    if (st != MCF_OK)
        return fail(st == MCF_EINVAL ? EXIT_USAGE : 1, "%s", err.msg);
    return 0;
}

/* Parses argv[first..] of command cmd ("smooth" or "convert"). */
/* The tool's limit options (LIMITS_HELP), in limit_option's order. */
static const char *const limit_names[] = {"max_input_bytes", "max_vertices", "max_faces",
                                          "max_work", NULL};

static int limit_index(const char *key)
{
    int k;
    for (k = 0; limit_names[k]; k++)
        if (!strcmp(key, limit_names[k]))
            return k;
    return -1;
}

/* Sets limit k (limit_index) of lim from the value val of option opt; a
 * value that is not a whole number in range is a usage error. */
static int limit_option(int k, const char *opt, const char *val, api_limits *lim)
{
    int count = k == 1 || k == 2; /* core's int counts (api_limits.c) */
    char *end;
    double v;

    errno = 0;
    v = strtod(val, &end);
    if (end == val || *end || errno || !(v >= 1) || v != floor(v) ||
        v > (count ? 2147483647.0 : 9e18))
        return fail(EXIT_USAGE, "option '--%s' needs a whole number from 1%s, got '%s'", opt,
                    count ? " to 2147483647" : "", val);
    if (k == 0)
        lim->max_input_bytes = (size_t)v;
    else if (k == 1)
        lim->max_vertices = lim->max_fixed = (int)v;
    else if (k == 2)
        lim->max_faces = (int)v;
    else
        lim->max_work = v;
    return 0;
}

/* The tool's limits before its options: api_limits_default's, without a
 * bound on the input's bytes (a local file; the mesh's counts and memory
 * are what bound a job). */
/* The usage error of an unknown option --NAME (key: NAME with '_' for
 * '-'), offering the nearest option cmd takes (api_nearest_name). */
static int unknown_option(const char *cmd, const char *a, size_t nl, const char *key,
                          const cJSON *table, int smooth)
{
    static const char *const own[] = {"quiet", "progress", "strict", "fix_vertices",
                                      "target", "metrics", "threads"};
    const char *names[96], *near;
    const cJSON *e;
    size_t n = 0, k, off = 0;
    char flag[64];

    cJSON_ArrayForEach(e, table) {
        const char *name = cJSON_GetStringValue(cJSON_GetObjectItem(e, "name"));
        if (n < 64 && find_param(table, name, smooth))
            names[n++] = name;
    }
    for (k = 0; limit_names[k]; k++)
        names[n++] = limit_names[k];
    for (k = 0; smooth && k < sizeof own / sizeof own[0]; k++)
        names[n++] = own[k];
    near = api_nearest_name(key, names, n);
    if (!near && strncmp(key, "no_", 3) == 0) {       /* --no-NAME of a boolean */
        near = api_nearest_name(key + 3, names, n);
        e = near ? find_param(table, near, smooth) : NULL;
        if (!e || !is_type(e, "boolean"))
            near = NULL;
        else
            off = 3;
    }
    if (!near)
        return fail(EXIT_USAGE, "%s: unknown option '--%.*s' (try mcf %s --help)",
                    cmd, (int)nl, a, cmd);
    memcpy(flag, "no-", off);
    for (k = 0; near[k] && off + k + 1 < sizeof flag; k++)
        flag[off + k] = near[k] == '_' ? '-' : near[k];
    flag[off + k] = '\0';
    return fail(EXIT_USAGE, "%s: unknown option '--%.*s', did you mean '--%s'? (try mcf %s --help)",
                cmd, (int)nl, a, flag, cmd);
}

void cli_limits(api_limits *lim)
{
    api_limits_default(lim);
    lim->max_input_bytes = SIZE_MAX;
}

int parse_args(const char *cmd, int argc, char **argv, int first,
               api_params *p, api_limits *lim, cli_opts *o,
               const cJSON *table)
{
    int smooth = strcmp(cmd, "smooth") == 0, i, rc;

    for (i = first; i < argc; i++) {
        const char *a = argv[i], *val = NULL, *eq;
        const cJSON *e;
        char key[64];
        size_t nl, k;
        int off = 0;

        if (a[0] != '-' || strcmp(a, "-") == 0) {
            if (o->npos >= 2)
                return fail(EXIT_USAGE, "%s: unexpected argument '%s' (try mcf %s --help)",
                            cmd, a, cmd);
            o->pos[o->npos++] = a;
            continue;
        }
        if (a[1] != '-')
            return fail(EXIT_USAGE, "%s: unknown option '%s' (try mcf %s --help)", cmd, a, cmd);
        a += 2;
        eq = strchr(a, '=');
        nl = eq ? (size_t)(eq - a) : strlen(a);
        if (nl >= sizeof key)
            return fail(EXIT_USAGE, "%s: unknown option '--%.40s' (try mcf %s --help)",
                        cmd, a, cmd);
        for (k = 0; k < nl; k++)   /* the daemon's name: dashes become underscores */
            key[k] = a[k] == '-' ? '_' : a[k];
        key[nl] = '\0';

        /* The tool's own switches and files. */
        if (smooth && (!strcmp(key, "quiet") || !strcmp(key, "progress")
                       || !strcmp(key, "strict"))) {
            if (eq)
                return fail(EXIT_USAGE, "option '--%s' takes no value", key);
            *(key[0] == 'q' ? &o->quiet : key[0] == 'p' ? &o->progress : &o->strict) = 1;
            continue;
        }
        if (smooth && (!strcmp(key, "fix_vertices") || !strcmp(key, "target")
                       || !strcmp(key, "metrics"))) {
            if (eq)
                val = eq + 1;
            else if (i + 1 < argc)
                val = argv[++i];
            else
                return fail(EXIT_USAGE, "option '--%.*s' needs a value", (int)nl, a);
            *(key[0] == 'f' ? &o->fix_file : key[0] == 't' ? &o->target : &o->metrics) = val;
            continue;
        }
        if (smooth && !strcmp(key, "threads")) {
            char *end;
            long n;
            if (eq)
                val = eq + 1;
            else if (i + 1 < argc)
                val = argv[++i];
            else
                return fail(EXIT_USAGE, "option '--threads' needs a value");
            errno = 0;
            n = strtol(val, &end, 10);
            if (end == val || *end || errno || n < 1 || n > 64)
                return fail(EXIT_USAGE, "option '--threads' needs a whole number from 1 to 64, "
                            "got '%s'", val);
            o->threads = (int)n;
            continue;
        }
        if (limit_index(key) >= 0) {
            if (eq)
                val = eq + 1;
            else if (i + 1 < argc)
                val = argv[++i];
            else
                return fail(EXIT_USAGE, "option '--%.*s' needs a value", (int)nl, a);
            char opt[64];
            snprintf(opt, sizeof opt, "%.*s", (int)nl, a);
            if ((rc = limit_option(limit_index(key), opt, val, lim)) != 0)
                return rc;
            continue;
        }
        /* A job parameter: --NAME VALUE, --NAME=VALUE; a boolean --NAME or --no-NAME. */
        e = find_param(table, key, smooth);
        if (!e && strncmp(key, "no_", 3) == 0) {
            e = find_param(table, key + 3, smooth);
            off = 1;
            if (e && !is_type(e, "boolean"))
                e = NULL;
        }
        if (!e)
            return unknown_option(cmd, a, nl, key, table, smooth);
        if (is_type(e, "boolean")) {
            if (eq)
                return fail(EXIT_USAGE, "option '--%.*s' takes no value", (int)nl, a);
            val = off ? "false" : "true";
        } else if (eq) {
            val = eq + 1;
        } else if (i + 1 < argc) {
            val = argv[++i];
        } else {
            return fail(EXIT_USAGE, "option '--%.*s' needs a value", (int)nl, a);
        }
        if ((rc = set_param(p, cJSON_GetStringValue(cJSON_GetObjectItem(e, "name")), val,
                            lim)) != 0)
            return rc;
    }
    if (o->npos < 2)
        return fail(EXIT_USAGE, "%s: needs IN and OUT (try mcf %s --help)", cmd, cmd);
    return 0;
}

/* One command's help: head, then every parameter of the table it takes
 * (with its placeholder, meaning, unit, range and default), then tail. */
int print_help(const char *head, int smooth, const char *tail)
{
    cJSON *table = param_table();
    const cJSON *e;
    int pass;

    if (!table)
        return 1;
    fputs(head, stdout);
    /* smooth: the flow's parameters first, then the output ones */
    for (pass = smooth ? 0 : 1; pass < 2; pass++) {
        if (smooth && pass == 1)
            fputs("\nOutput (also `mcf convert`'s):\n", stdout);
        cJSON_ArrayForEach(e, table) {
            const char *name = cJSON_GetStringValue(cJSON_GetObjectItem(e, "name"));
            const char *unit = cJSON_GetStringValue(cJSON_GetObjectItem(e, "unit"));
            const cJSON *dv = cJSON_GetObjectItem(e, "default");
            char flag[64], meta[24], *dtext = NULL;
            size_t k;

            if (cJSON_IsTrue(cJSON_GetObjectItem(e, "output")) != (pass == 1))
                continue;
            for (k = 0; name[k] && k + 1 < sizeof flag; k++)
                flag[k] = name[k] == '_' ? '-' : name[k];
            flag[k] = '\0';
            if (is_type(e, "boolean"))
                snprintf(meta, sizeof meta, "%s", "");
            else
                snprintf(meta, sizeof meta, " %s%s",
                         is_type(e, "number") ? "X" : is_type(e, "integer") ? "N"
                         : is_type(e, "array") ? "I,J,..." : "NAME",
                         cJSON_IsTrue(cJSON_GetObjectItem(e, "auto")) ? "|auto" : "");
            if (is_type(e, "boolean"))
                printf("  --%s, --no-%s\n", flag, flag);
            else
                printf("  --%s%s\n", flag, meta);
            printf("      %s%s%s\n", cJSON_GetStringValue(cJSON_GetObjectItem(e, "help")),
                   unit ? "; unit: " : "", unit ? unit : "");
            if (dv && !cJSON_IsString(dv))
                dtext = cJSON_PrintUnformatted(dv);
            printf("      %s; default %s\n",
                   cJSON_GetStringValue(cJSON_GetObjectItem(e, "accepts")),
                   dtext ? dtext : dv ? cJSON_GetStringValue(dv)
                   : cJSON_GetStringValue(cJSON_GetObjectItem(e, "default_text")));
            cJSON_free(dtext);
        }
    }
    fputs(tail, stdout);
    cJSON_Delete(table);
    return fflush(stdout) == 0 ? 0 : 1;
}

/* The output format: --format, else OUT's extension. */
int output_format(api_params *p, const char *out)
{
    char list[64] = "";
    size_t used = 0;
    int f;

    if (p->encode.format != API_FMT_UNKNOWN)
        return 0;
    p->encode.format = api_format_from_name(out);
    if (p->encode.format != API_FMT_UNKNOWN)
        return 0;
    for (f = API_FMT_OBJ; f <= API_FMT_GLTF && used < sizeof list; f++)
        used += (size_t)snprintf(list + used, sizeof list - used, "%s%s", f > API_FMT_OBJ ? "|" : "",
                                 api_format_name((api_format)f));
    return fail(EXIT_USAGE, "cannot tell the output format from '%s' (use --format %s)", out, list);
}

