/* SPDX-License-Identifier: MIT */
/*
 * cli.h - what the files of `mcf` share (mcf.c: main and the commands;
 * cli_args.c: the options and help; cli_files.c: reading, decoding,
 * encoding and writing). Every function that returns int returns 0, or an
 * exit status after printing the one error line "mcf: ..." (fail); write_file
 * alone leaves the line to its caller (0, or -1 and err).
 */
#ifndef MCF_CLI_H
#define MCF_CLI_H

#include <stddef.h>

#include "api.h"

#define EXIT_USAGE 2
#define EXIT_STRICT 3 /* --strict and the result has warnings */
/* `mcf smooth` stopped by a signal before OUT was in place: 128 + the
 * signal, the shells' status of a process the signal killed (130 SIGINT,
 * 143 SIGTERM) */
#define EXIT_SIGNAL 128

/* What `mcf smooth`/`convert` were given besides job parameters. */
typedef struct {
    const char *pos[3];
    int npos;
    const char *target, *metrics, *fix_file;
    int quiet, progress, strict;
    int threads;            /* --threads, default the online cores */
} cli_opts;

/* mcf.c: the one error line (newlines become spaces), then the exit status;
 * a monotonic clock in seconds. */
int fail(int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
double now(void);

/* cli_files.c: path "-" is stdin or stdout; attrs, fmt, bytes and the
 * timings may be NULL; cancel may be NULL (read_all: EXIT_SIGNAL and no
 * line once it is set; write_file: ECANCELED, OUT untouched). */
int read_all(const char *path, size_t max, const mcf_cancel_flag *cancel, char **buf,
             size_t *len);
int write_file(const char *path, const void *buf, size_t len,
               const mcf_cancel_flag *cancel, mcf_error *err);
int write_all(const char *path, const void *buf, size_t len);
mcf_status decode_bounded(const char *buf, size_t len,
                          const api_limits *lim, mcf_mesh **m,
                          api_attrs **attrs, api_format *fmt,
                          mcf_error *err);
int load_mesh_attrs(const char *path, const api_limits *lim,
                    mcf_mesh **m, api_attrs **attrs, api_format *fmt,
                    size_t *bytes, double *read_s, double *decode_s);
int load_mesh(const char *path, const api_limits *lim, mcf_mesh **m,
              api_format *fmt, size_t *bytes, double *read_s,
              double *decode_s);
int save_mesh(const mcf_mesh *m, const api_encode_opts *opts,
              const char *path, size_t *bytes, double *encode_s,
              double *write_s, double *qerr);

/* cli_args.c: param_table is api_params_describe's (NULL after the error
 * line); cli_limits: the tool's limits before its options; parse_args
 * parses argv[first..] of cmd ("smooth" or "convert"); output_format sets
 * --format from OUT's extension when it was not given. */
cJSON *param_table(void);
void cli_limits(api_limits *lim);
int parse_args(const char *cmd, int argc, char **argv, int first,
               api_params *p, api_limits *lim, cli_opts *o,
               const cJSON *table);
int print_help(const char *head, int smooth, const char *tail);
int output_format(api_params *p, const char *out);

#endif
