/* SPDX-License-Identifier: MIT */
/*
 * mcf.c - the `mcf` command-line tool: smooth, inspect and convert meshes.
 *
 *   mcf smooth IN OUT [flags]   mean curvature flow, optional metrics file
 *   mcf info IN                 JSON: counts, topology, curvature summary
 *   mcf schemes                 JSON: every scheme and what it costs
 *   mcf params                  JSON: every job parameter (api_params_describe)
 *   mcf convert IN OUT          any input format to OUT's (or --format)
 *
 * Like curl's tool, this is only a client of the libraries: every job
 * parameter of the api table (api_params_describe) is an option, its name
 * with dashes for underscores, set through api_params_set, so the CLI and
 * the daemon accept and refuse exactly the same values with the same
 * messages, and `mcf smooth --help` lists them from the same table. The
 * input format is detected from the bytes, the output format comes from
 * OUT's extension unless --format says otherwise. "-" reads stdin / writes
 * stdout.
 *
 * Errors: exactly one line "mcf: <message>" on stderr; exit status 2 for
 * usage errors (unknown flag, missing argument, invalid parameter value),
 * 1 for everything else, 3 for `smooth --strict` with warnings, 128 + the
 * signal for `smooth` stopped by SIGINT/SIGTERM (EXIT_SIGNAL). Output
 * files are written to a temporary name and renamed, so a failed run never
 * leaves a half-written OUT behind. `mcf smooth` also says what happened
 * on stderr: the core's warnings about the result (always), a summary line
 * (unless --quiet), and progress (a bar on a terminal; with --progress,
 * one plain line per 10% elsewhere).
 *
 * This file: main and the commands; cli_args.c the options and help,
 * cli_files.c reading, decoding and writing (cli.h).
 */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "api.h"
#include "cli.h"
#include "prog.h"

/* `mcf --help`: the commands; each command's own --help has its options. */
static const char usage_text[] =
    "usage: mcf COMMAND [ARGS] [OPTIONS]\n"
    "\n"
    "  mcf smooth IN OUT [options]   smooth a mesh (mean curvature flow or a filter)\n"
    "  mcf info IN                   JSON on stdout: counts, topology, curvature summary\n"
    "  mcf schemes                   JSON on stdout: every scheme with order, stability, cost\n"
    "  mcf params                    JSON on stdout: every job parameter with its type,\n"
    "                                range, default and unit (the daemon's too)\n"
    "  mcf convert IN OUT [options]  any mesh format to OUT's (texture coordinates, colours\n"
    "                                pass through; normals recomputed)\n"
    "  mcf --version                 the version\n"
    "\n"
    "`mcf COMMAND --help` lists that command's options with their defaults and units.\n"
    "Formats: obj, draco (.drc), ply, stl, off, glb and gltf (glTF 2.0), detected from\n"
    "the bytes on input and taken from OUT's extension (or --format) on output; IN or\n"
    "OUT may be '-' (stdin/stdout; OUT '-' needs --format).\n"
    "Exit status: 0 done; 1 failed (one line 'mcf: ...' on stderr); 2 usage error;\n"
    "3 `mcf smooth --strict` and the result has warnings; 130 or 143 `mcf smooth`\n"
    "stopped by SIGINT or SIGTERM (within a phase of its work; OUT not written).\n";

/* The limits on the input (api_limits), options of smooth and convert:
 * none below memory by default (a 10M-vertex scan needs no option). */
#define LIMITS_HELP \
    "  --max-input-bytes N   refuse an input file larger than N bytes (default: no\n" \
    "                        limit; the daemon's --max-upload is 256 MiB)\n" \
    "  --max-vertices N      refuse a mesh of more than N vertices (default 100000000)\n" \
    "  --max-faces N         refuse a mesh of more than N triangles (default 200000000)\n" \
    "  --max-work N          refuse a job of more than N steps x vertices (default 2e10)\n"

static const char smooth_head[] =
    "usage: mcf smooth IN OUT [options]\n"
    "\n"
    "Smooths the mesh IN into OUT. Without --scheme: the fairing denoiser (fairing;\n"
    "fairing_explicit above 150,000 vertices): as many steps as Stein's unbiased risk\n"
    "estimate says for the noise it reads off the mesh, along the normals only;\n"
    "--iterations sets its steps, --strength the noise level (mean edges). With\n"
    "--time, --dt, --adaptive, --laplacian, --mass or --rescale and no --scheme:\n"
    "desbrun2, as before. An MCF scheme's (and taubin's) amount is automatic too, by\n"
    "the same risk estimate, unless --strength, --time, or --iterations with --dt set\n"
    "it (--iterations or --dt alone: strength 0.33). The job parameters are the\n"
    "daemon's (dashes here, underscores there); a boolean is --NAME or --no-NAME.\n"
    "\n"
    "Job parameters:\n";

static const char smooth_tail[] =
    "\n"
    "Options of the tool:\n"
    "  --fix-vertices FILE   vertices held in place: 0-based indices in FILE, separated\n"
    "                        by white space or commas\n"
    "  --target FILE         a clean mesh with the same connectivity: the metrics compare\n"
    "                        the result (and the input) with it\n"
    "  --metrics FILE.json   write the metrics document (the daemon's /v1/jobs/ID/metrics)\n"
    "  --progress            progress on stderr when it is not a terminal: one line per\n"
    "                        10% of the work (the flow's steps; the filter's phases,\n"
    "                        steps and passes) and one when a phase of the filter ends,\n"
    "                        with the time elapsed and an estimate of the time left\n"
    "                        (on a terminal the bar is always shown)\n"
    "  --quiet               no progress bar and no summary line (warnings still print)\n"
    "  --threads N           threads of the fairing filters' passes (default: the\n"
    "                        online cores); the result is one thread's bit for bit\n"
    "  --strict              a warning (folds, edge_collapse, area_loss,\n"
    "                        little_smoothing) fails the run: exit status 3, OUT not\n"
    "                        written (the metrics file is, when asked for)\n"
    LIMITS_HELP
    "\n"
    "On stderr, unless --quiet: a summary line (vertices, steps, time, strength, seconds).\n"
    "Always: one line per warning about the result, 'mcf: warning: NAME: ...'.\n"
    "SIGINT or SIGTERM stops the run at its next phase or step (seconds, also while it\n"
    "reads the mesh and sets up): exit status 128 + the signal (130, 143), OUT not\n"
    "written (an existing OUT left as it was).\n";

static const char convert_head[] =
    "usage: mcf convert IN OUT [options]\n"
    "\n"
    "Reads any mesh format (detected from the bytes) and writes OUT's (its extension or\n"
    "--format). Texture coordinates and colours pass through, normals are recomputed;\n"
    "Draco keeps a Draco input's quantization.\n"
    "\n"
    "Options of the tool:\n"
    LIMITS_HELP
    "\n"
    "Options (the daemon's output parameters):\n";

static const char info_usage[] =
    "usage: mcf info IN\n"
    "\n"
    "Prints JSON on stdout: vertex and face counts, topology (boundary, components,\n"
    "genus, manifoldness, degenerate and duplicate faces), area, volume, edge lengths,\n"
    "bounding box, the curvature summary, the format and the size in bytes.\n";

static const char schemes_usage[] =
    "usage: mcf schemes\n"
    "\n"
    "Prints JSON on stdout: every scheme with its order, stability, cost per step and\n"
    "best use (the daemon's GET /v1/schemes).\n";

static const char params_usage[] =
    "usage: mcf params\n"
    "\n"
    "Prints JSON on stdout: every job parameter (mcf smooth's options, the daemon's query\n"
    "parameters, JSON keys and gRPC Params fields) with its type, range, default, unit\n"
    "and meaning, from the one table that validates them.\n";

/* Set by SIGINT/SIGTERM from the start of `mcf smooth`: the job loads it
 * before every step of the flow, between the phases of its set-up and its
 * stages, and before OUT is renamed into place (api_job_hooks.cancel). A
 * lock-free C11 atomic (mcf_cancel_flag), which a signal handler may
 * store to; stop_signal says which signal (the exit status). */
static mcf_cancel_flag cancel_flag;
static volatile sig_atomic_t stop_signal;

static void on_signal(int sig)
{
    stop_signal = sig;
    cancel_flag = 1;
}

/* A run stopped by SIGINT/SIGTERM before OUT was in place: the one line
 * and 128 + the signal (EXIT_SIGNAL). */
static int stopped(const cli_opts *o, const char *when)
{
    int sig = stop_signal ? (int)stop_signal : SIGTERM;
    return fail(EXIT_SIGNAL + sig, "smooth: stopped by %s %s: '%s' not written",
                sig == SIGINT ? "SIGINT" : "SIGTERM", when, o->pos[1]);
}

/* The one error line, then the exit status (cli.h). */
int fail(int code, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    size_t i;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (i = 0; msg[i]; i++) /* one line, whatever a message holds */
        if (msg[i] == '\n' || msg[i] == '\r')
            msg[i] = ' ';
    fprintf(stderr, "mcf: %s\n", msg);
    return code;
}

double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* --------------------------------------------------------------- progress */

/* The flow's share of work done (the core's estimate at its milestones:
 * every step, the fairing filters' phases and passes), the time since
 * the flow started and an estimate of the time left from both. */
typedef struct {
    int bar;              /* 1: a bar redrawn in place (a terminal) */
    double start;         /* when the flow started (the ready hook) */
    double last;          /* when the bar was last drawn */
    int drawn;
    int next_tenth;       /* plain lines: the next 10% to report */
    int step;             /* the last step the flow reported */
    char phase[16];       /* plain lines: the last phase printed */
} progress_state;

static void on_work(progress_state *ps, const char *phase, double frac)
{
    double tn = now(), el = tn - ps->start;
    int i, fill;
    char bar[41], left[48] = "";

    if (!(frac >= 0))
        frac = 0;
    if (frac > 1)
        frac = 1;
    /* the time left: the elapsed time scaled by the share still to do,
     * once a share worth extrapolating (2%) is done */
    if (frac >= 0.02 && frac < 1)
        snprintf(left, sizeof left, ", about %.0f s left", ceil(el * (1 - frac) / frac));
    if (!ps->bar) {
        /* Plain lines (a log or a pipe, not a terminal): one per 10%
         * reached and one when a phase of the filter first ends, so that
         * a run whose plan shrinks (nothing to remove: no steps) still
         * shows what it did. The share is the core's, never decreasing. */
        int tenth = (int)(frac * 10 + 1e-9);
        if ((tenth >= ps->next_tenth && ps->next_tenth <= 10) || strcmp(phase, ps->phase)) {
            fprintf(stderr, "mcf: %3d%%  %s, step %d  %.1f s elapsed%s\n",
                    (int)(frac * 100 + 1e-9), phase, ps->step, el, left);
            fflush(stderr);
            if (tenth >= ps->next_tenth)
                ps->next_tenth = tenth + 1;
            snprintf(ps->phase, sizeof ps->phase, "%s", phase);
        }
        return;
    }
    if (tn - ps->last < 0.1)
        return;
    ps->last = tn;
    fill = (int)(frac * 40 + 0.5);
    for (i = 0; i < 40; i++)
        bar[i] = i < fill ? '#' : '.';
    bar[40] = '\0';
    fprintf(stderr, "\r[%s] %3d%%  %s, step %d  %.1f s%s \033[K", bar,
            (int)(frac * 100 + 0.5), phase, ps->step, el, left);
    fflush(stderr);
    ps->drawn = 1;
}

static void progress_clear(progress_state *ps)
{
    if (ps->drawn)
        fprintf(stderr, "\r\033[K");
    ps->drawn = 0;
}

/* One line per warning of the core about the result, with the figure
 * behind it (mcf_flow_stats); returns how many. */
static int print_warnings(const mcf_flow_stats *st)
{
    unsigned bit;
    int n = 0;

    for (bit = 1; bit; bit <<= 1) {
        char why[96];
        if (!(st->warnings & bit) || !mcf_warning_name(bit))
            continue;
        if (bit == MCF_WARN_FOLDS)
            snprintf(why, sizeof why, "%d faces folded", st->folded_faces);
        else if (bit == MCF_WARN_EDGE_COLLAPSE)
            snprintf(why, sizeof why, "shortest edge x %.3g", st->min_edge_ratio);
        else if (bit == MCF_WARN_AREA_LOSS)
            snprintf(why, sizeof why, "area x %.3g", st->area_ratio);
        else if (bit == MCF_WARN_LITTLE_SMOOTHING)
            snprintf(why, sizeof why, "strength %.3g mean edges", st->strength);
        else
            why[0] = '\0';
        fprintf(stderr, "mcf: warning: %s: %s%s%s%s\n", mcf_warning_name(bit),
                mcf_warning_text(bit), why[0] ? " (" : "", why, why[0] ? ")" : "");
        n++;
    }
    return n;
}

/* ---------------------------------------------------------------- helpers */

/* Adds item to o under key; on allocation failure the document is simply
 * missing that member (the metrics file is best-effort detail). */
static void add(cJSON *o, const char *key, cJSON *item)
{
    if (item && !cJSON_AddItemToObject(o, key, item))
        cJSON_Delete(item);
}

static cJSON *info_json(const mcf_mesh *m, const mcf_curvature_summary *cs,
                        mcf_error *err)
{
    mcf_mesh_info info;
    if (mcf_mesh_inspect(m, &info, err) != MCF_OK)
        return NULL;
    return api_json_mesh_info(&info, cs);
}

/* ----------------------------------------------------------------- smooth */

/* The tool's side of the job (api_job_run's hooks): the bounded decode,
 * the progress bar, the warnings and --strict, and OUT's file. */
typedef struct {
    const cli_opts *o;
    progress_state ps;
    int show;             /* progress shown */
    int nwarn;            /* warnings printed */
} smooth_ctx;

static mcf_status hook_decode(void *ctx, const char *part, const void *buf, size_t len,
                              const api_limits *lim, mcf_mesh **out, api_attrs **attrs,
                              api_format *fmt, api_job_stage *stage, mcf_error *err)
{
    (void)ctx;
    (void)part;
    (void)stage;
    return decode_bounded(buf, len, lim, out, attrs, fmt, err);
}

static int hook_progress(void *ctx, const api_job_step *s)
{
    ((smooth_ctx *)ctx)->ps.step = s->step;
    return 0;
}

static void hook_ready(void *ctx, const api_params *p, api_format in_fmt)
{
    (void)p;
    (void)in_fmt;
    ((smooth_ctx *)ctx)->ps.start = now();
}

static void hook_work(void *ctx, const char *phase, double done)
{
    smooth_ctx *sc = ctx;
    if (sc->show)
        on_work(&sc->ps, phase, done);
}

/* What the core says about the result, whatever --quiet says; under
 * --strict a warning withholds OUT (a pipeline must not take it). */
static int hook_flowed(void *ctx, const mcf_flow_stats *st)
{
    smooth_ctx *sc = ctx;
    if (sc->show)
        progress_clear(&sc->ps);
    sc->nwarn = print_warnings(st);
    return sc->o->strict && sc->nwarn > 0;
}

static mcf_status hook_store(void *ctx, const api_buf *out, const char *name,
                             mcf_error *err)
{
    (void)ctx;
    return write_file(name, out->data ? out->data : "", out->len, &cancel_flag, err) == 0
               ? MCF_OK : err->status;
}

/* The job's failure as the tool's one error line and exit status: a
 * parameter the mesh refuses is a usage error (2), anything else 1. */
static int job_failed(const api_job_result *res, const cli_opts *o)
{
    const char *part = res->part ? res->part : "";
    const char *msg = res->err.msg;

    if (!strcmp(part, "mesh"))
        return fail(1, "%s: %s", o->pos[0], msg);
    if (!strcmp(part, "target"))
        return res->stage == API_JOB_DECODE ? fail(1, "%s: %s", o->target, msg)
                                            : fail(1, "--target '%s': %s", o->target, msg);
    if (!strcmp(part, "params"))
        return fail(res->err.status == MCF_EINVAL ? EXIT_USAGE : 1, "%s", msg);
    if (!strcmp(part, "flow"))
        return fail(1, "smooth: %s", msg);
    if (!strcmp(part, "encode"))
        return fail(1, "%s: %s", o->pos[1], msg);
    if (!strcmp(part, "output"))
        return fail(1, "%s", msg);
    return fail(1, "%s: %s", part, msg);
}

/* --fix-vertices FILE: its indices as the fixed_vertices parameter. */
static int fix_vertices(api_params *p, const char *path, const api_limits *lim)
{
    mcf_error err = {MCF_OK, ""};
    char *txt = NULL;
    size_t n = 0, k;
    int rc;

    if ((rc = read_all(path, lim->max_input_bytes, NULL, &txt, &n)) != 0)
        return rc;
    for (k = 0; k < n && strchr(" \t\r\n,", txt[k]); k++)
        ;
    if (k == n || memchr(txt, '\0', n)) {
        free(txt);
        return fail(EXIT_USAGE, "--fix-vertices '%s': %s", path,
                    k == n ? "the file holds no vertex index" : "binary data");
    }
    rc = api_params_set(p, "fixed_vertices", txt, lim, &err);
    free(txt);
    if (rc != MCF_OK)
        return fail(rc == MCF_EINVAL ? EXIT_USAGE : 1, "--fix-vertices '%s': %s", path,
                    err.msg);
    return 0;
}

/* The summary line: what ran, on how many vertices, how far, how long. */
static void print_summary(const cli_opts *o, const api_params *p, const api_job_result *res,
                          int nwarn)
{
    const mcf_flow_stats *st = &res->stats;

    if (p->flow.scheme == MCF_FAIRING || p->flow.scheme == MCF_FAIRING_EXPLICIT ||
        p->flow.scheme == MCF_FAIRING_FEATURE) {
        /* a filter: its steps and the noise they were chosen for */
        fprintf(stderr, "mcf: %s -> %s: %d vertices, %s %d step%s for noise %.3g mean edges in %.2f s%s\n",
                o->pos[0], o->pos[1], res->nv, mcf_scheme_get(p->flow.scheme)->name, st->steps,
                st->steps == 1 ? "" : "s", st->noise, res->flow_s, nwarn ? " (with warnings)" : "");
    } else {
        char strength[48] = "";
        if (st->strength > 0)
            snprintf(strength, sizeof strength, ", strength %.3g mean edges", st->strength);
        fprintf(stderr, "mcf: %s -> %s: %d vertices, %d step%s to t = %.4g%s in %.2f s%s\n",
                o->pos[0], o->pos[1], res->nv, st->steps, st->steps == 1 ? "" : "s",
                st->t_final, strength, res->flow_s, nwarn ? " (with warnings)" : "");
    }
}

/* The job (api_job_run) on IN's bytes (and --target's), OUT and the
 * metrics file written by the tool. */
static int run_smooth(const cli_opts *o, api_params *p, const api_limits *lim)
{
    api_job_request rq;
    api_job_hooks h;
    api_job_result res;
    smooth_ctx sc;
    char *in = NULL, *tg = NULL, *s;
    size_t in_len = 0, tg_len = 0;
    double t0 = now();
    struct sigaction sa;
    int rc;

    api_job_request_init(&rq);
    api_job_result_init(&res);
    /* SIGINT/SIGTERM from here on: the job stops at its next phase or
     * step, OUT not written (stopped) */
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    if ((rc = read_all(o->pos[0], lim->max_input_bytes, &cancel_flag, &in, &in_len)) != 0 ||
        (o->target &&
         (rc = read_all(o->target, lim->max_input_bytes, &cancel_flag, &tg, &tg_len)) != 0)) {
        if (rc == EXIT_SIGNAL)
            rc = stopped(o, "while its input was read");
        goto done;
    }
    rq.read_s = now() - t0;
    rq.input = in;
    rq.input_len = in_len;
    rq.target = tg;
    rq.target_len = tg_len;
    rq.free_bytes = 1;
    in = tg = NULL;
    rq.lim = lim;
    rq.metrics = o->metrics != NULL;
    rq.input_name = o->pos[0];
    rq.output_name = o->pos[1];
    rq.target_name = o->target;
    rq.process_rss = 1;
    rq.threads = o->threads;

    /* progress: a bar on a terminal, plain lines with --progress
     * elsewhere */
    memset(&sc, 0, sizeof sc);
    sc.o = o;
    sc.ps.bar = isatty(STDERR_FILENO);
    sc.show = !o->quiet && (sc.ps.bar || o->progress);
    sc.ps.start = now();
    sc.ps.next_tenth = 1;
    memset(&h, 0, sizeof h);
    h.ctx = &sc;
    h.decode = hook_decode;
    /* no progress hook when none is shown (the step number is all it
     * takes; the core computes no area for it without the step log) */
    h.progress = sc.show ? hook_progress : NULL;
    h.ready = hook_ready;
    h.work = hook_work;
    h.flowed = hook_flowed;
    h.store = hook_store;
    h.cancel = &cancel_flag;

    if (api_job_run(&rq, p, &h, &res) != MCF_OK) {
        if (sc.show)
            progress_clear(&sc.ps);
        if (cancel_flag) { /* whatever the signal made fail */
            char when[sizeof res.err.msg + 8];
            snprintf(when, sizeof when, "(%s)", res.err.msg);
            rc = stopped(o, when);
        } else {
            rc = job_failed(&res, o);
        }
        goto done;
    }
    if (o->metrics) {
        s = api_json_print(res.metrics, 1);
        if (!s) {
            rc = fail(1, "metrics: out of memory");
            goto done;
        }
        rc = write_all(o->metrics, s, strlen(s));
        free(s);
        if (rc)
            goto done;
    }
    if (res.withheld) {
        rc = fail(EXIT_STRICT, "--strict: the result has %d warning%s (above): '%s' not written",
                  sc.nwarn, sc.nwarn > 1 ? "s" : "", o->pos[1]);
        goto done;
    }
    if (!o->quiet && res.not_kept_n)
        fprintf(stderr, "mcf: note: %s does not keep the input's %s\n", o->pos[1], res.not_kept);
    if (!o->quiet)
        print_summary(o, p, &res, sc.nwarn);
    rc = 0;
done:
    api_job_result_free(&res);
    free(rq.input);
    free(rq.target);
    free(in);
    free(tg);
    return rc;
}

/* The cores this process may run on (1 when that cannot be told), at
 * most 64: the default of --threads. */
static int online_cores(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > 64 ? 64 : (int)n;
}

static int cmd_smooth(int argc, char **argv)
{
    api_limits lim;
    api_params p;
    cli_opts o;
    cJSON *table;
    int rc;

    memset(&o, 0, sizeof o);
    o.threads = online_cores();
    cli_limits(&lim);
    api_params_init(&p);
    if (!(table = param_table()))
        return 1;
    if ((rc = parse_args("smooth", argc, argv, 2, &p, &lim, &o, table)) == 0 &&
        (rc = output_format(&p, o.pos[1])) == 0 &&
        (!o.fix_file || (rc = fix_vertices(&p, o.fix_file, &lim)) == 0))
        rc = run_smooth(&o, &p, &lim);
    cJSON_Delete(table);
    api_params_free(&p);
    return rc;
}

/* ------------------------------------------------------------------- info */

static int cmd_info(int argc, char **argv)
{
    api_limits lim;
    mcf_mesh *m = NULL;
    mcf_error err = {MCF_OK, ""};
    mcf_curvature_summary cs;
    api_format fmt = API_FMT_UNKNOWN;
    size_t bytes = 0;
    cJSON *j = NULL;
    char *s = NULL;
    int rc;

    if (argc != 3 || (argv[2][0] == '-' && argv[2][1] != '\0'))
        return fail(EXIT_USAGE, "info: needs exactly one input file (try mcf --help)");
    cli_limits(&lim);
    if ((rc = load_mesh(argv[2], &lim, &m, &fmt, &bytes, NULL, NULL)) != 0)
        return rc;
    rc = 1;
    if (mcf_curvature_summarize(m, &cs, &err) != MCF_OK || !(j = info_json(m, &cs, &err))) {
        fail(1, "info: %s", err.msg[0] ? err.msg : "out of memory");
        goto done;
    }
    add(j, "format", cJSON_CreateString(api_format_name(fmt)));
    add(j, "bytes", cJSON_CreateNumber((double)bytes));
    if (!(s = api_json_print(j, 1))) {
        fail(1, "info: out of memory");
        goto done;
    }
    if (printf("%s\n", s) < 0 || fflush(stdout) != 0) {
        fail(1, "cannot write to stdout: %s", strerror(errno));
        goto done;
    }
    rc = 0;
done:
    free(s);
    cJSON_Delete(j);
    mcf_mesh_free(m);
    return rc;
}

/* ------------------------------------------------------- schemes, params */

/* `mcf schemes` and `mcf params`: a document of the libraries, printed
 * as JSON on stdout (j is taken and freed; NULL: out of memory). */
static int print_document(const char *cmd, int argc, cJSON *j)
{
    char *s;
    int rc = 0;

    if (argc != 2) {
        cJSON_Delete(j);
        return fail(EXIT_USAGE, "%s: takes no arguments", cmd);
    }
    s = j ? api_json_print(j, 1) : NULL;
    cJSON_Delete(j);
    if (!s)
        return fail(1, "%s: out of memory", cmd);
    if (printf("%s\n", s) < 0 || fflush(stdout) != 0)
        rc = fail(1, "cannot write to stdout: %s", strerror(errno));
    free(s);
    return rc;
}

/* ---------------------------------------------------------------- convert */

static int cmd_convert(int argc, char **argv)
{
    api_limits lim;
    api_params p;
    cli_opts o;
    mcf_mesh *m = NULL;
    api_attrs *attrs = NULL;
    api_format in_fmt = API_FMT_UNKNOWN;
    cJSON *table = param_table();
    char not_kept[256];
    int rc;

    if (!table)
        return 1;
    memset(&o, 0, sizeof o);
    cli_limits(&lim);
    api_params_init(&p);
    if ((rc = parse_args("convert", argc, argv, 2, &p, &lim, &o, table)) == 0
        && (rc = output_format(&p, o.pos[1])) == 0
        && (rc = load_mesh_attrs(o.pos[0], &lim, &m, &attrs, &in_fmt, NULL, NULL, NULL)) == 0) {
        p.encode.attrs = attrs;
        rc = save_mesh(m, &p.encode, o.pos[1], NULL, NULL, NULL, NULL);
        if (rc == 0 && !o.quiet
            && api_attrs_not_kept(attrs, p.encode.format == API_FMT_UNKNOWN ? in_fmt
                                                                            : p.encode.format,
                                  not_kept, sizeof not_kept))
            fprintf(stderr, "mcf: note: %s does not keep the input's %s\n", o.pos[1], not_kept);
    }
    mcf_mesh_free(m);
    api_attrs_free(attrs);
    api_params_free(&p);
    cJSON_Delete(table);
    return rc;
}

/* A command's --help (argv[1] is the command; "help" and --help alone give
 * the overview). */
static int command_help(const char *cmd)
{
    if (!strcmp(cmd, "smooth"))
        return print_help(smooth_head, 1, smooth_tail);
    if (!strcmp(cmd, "convert"))
        return print_help(convert_head, 0, "");
    fputs(!strcmp(cmd, "info") ? info_usage : !strcmp(cmd, "schemes") ? schemes_usage
          : !strcmp(cmd, "params") ? params_usage : usage_text, stdout);
    return 0;
}

int main(int argc, char **argv)
{
    const char *cmd = argc > 1 ? argv[1] : NULL;
    static const char *const commands[] = {"smooth", "info", "schemes", "params", "convert", NULL};
    int i, known = 0;

    int huge = prog_heap_huge_pages();
    prog_bound_blas_threads(argv);
    /* prog_bound_blas_threads executes the program again when it sets the
     * BLAS variables (the tunables with them); when it did not, this does
     * (no /proc: carry on with 4 KiB pages) */
    if (huge)
        prog_reexec(argv);
#ifdef __GLIBC__
    /* a run's big arrays from the heap, and what it frees kept for the
     * next: glibc maps every block over its mmap threshold (32 MiB at
     * most) anew, and the kernel clears each page of it again at its first
     * touch. The 435k dragon's default request faulted 175k pages (685 MB
     * for a 412 MB peak); 102k with these, 0.3 s less system time, the
     * same peak RSS within 0.4% (2026-11-29). One process, one request:
     * what it keeps is freed at its exit (the daemon does not do this). */
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
    if (!cmd)
        return fail(EXIT_USAGE, "missing command: smooth, info, schemes, params or convert "
                    "(try mcf --help)");
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help"))
        return command_help(argc > 2 && strcmp(cmd, "help") == 0 ? argv[2] : "");
    if (!strcmp(cmd, "--version") || !strcmp(cmd, "-V")) {
        printf("mcf %s\n", API_VERSION);
        return fflush(stdout) == 0 ? 0 : 1;
    }
    for (i = 0; commands[i]; i++)
        known |= !strcmp(cmd, commands[i]);
    if (!known)
        return fail(EXIT_USAGE, "unknown command '%s' (try mcf --help)", cmd);
    for (i = 2; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h"))
            return command_help(cmd);
    if (!strcmp(cmd, "smooth"))
        return cmd_smooth(argc, argv);
    if (!strcmp(cmd, "info"))
        return cmd_info(argc, argv);
    if (!strcmp(cmd, "schemes"))
        return print_document(cmd, argc, api_json_schemes());
    if (!strcmp(cmd, "params"))
        return print_document(cmd, argc, api_params_describe(NULL));
    return cmd_convert(argc, argv);
}
