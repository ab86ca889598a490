/* SPDX-License-Identifier: MIT */
/*
 * lab.h - what every program of the lab shares: the one error line and
 * progress notes, folders and CSV files, reading a mesh, and gnuplot
 * figures (a script of inline data rendered to PNG and SVG in the output
 * folder). The lab is a client of libmcf and libmcfapi (core/mcf.h,
 * api/api.h); nothing outside lab/ includes this.
 */
#ifndef LAB_H
#define LAB_H

#include <stdio.h>

#include "api.h"

#define LAB_EXIT_USAGE 2

/* The program's name in every message ("mcflab"); set once by main. */
extern const char *lab_prog;

/* Prints one line "PROG: TOPIC: message" (newlines in the message become
 * spaces; no topic part when lab_topic is NULL) to stderr and returns
 * code, so a failure is `return lab_fail(1, "...")`. */
extern const char *lab_topic;
int lab_fail(int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Creates dir and its parents (mkdir -p). 0, or 1 after lab_fail. */
int lab_mkdir_p(const char *dir);

/* Opens path for writing: the FILE, or NULL after lab_fail. */
FILE *lab_csv_open(const char *path);
/* Closes f, checking every write went through. 0, or 1 after lab_fail. */
int lab_csv_close(FILE *f, const char *path);
/* A message made safe for one CSV field: no comma, quote or newline. */
void lab_csv_clean(const char *in, char *out, size_t size);

/* Reads a mesh file and decodes it under the default limits. 0, or 1
 * after lab_fail. */
int lab_load_mesh(const char *path, mcf_mesh **out);

/* ---- gnuplot figures. A figure is a script body (the plot commands,
 * data inline as $blocks) that lab_plot_render writes to a temporary
 * script in the output folder with a PNG and an SVG terminal around it,
 * and runs gnuplot on there. */
typedef struct {
    const char *dir;      /* output folder */
    const char *header;   /* first comment line of the script ("what made it") */
    int enabled;          /* 0: no figures (--no-plots, or gnuplot missing) */
    int keep_scripts;     /* keep DIR/STEM.gp, else the script is removed */
    int quiet;            /* no "wrote ..." line */
} lab_plot;

/* Renders body to dir/stem.png and dir/stem.svg (1200 x 720). Returns 0,
 * also when gnuplot is not on the PATH (one line says so, and pl->enabled
 * is cleared so the rest of the run skips figures), or 1 after lab_fail
 * when the script cannot be written or gnuplot fails on it. */
int lab_plot_render(lab_plot *pl, const char *stem, const api_buf *body);

/* Runs gnuplot on dir/script inside dir. 0 when it succeeded, 1 when
 * gnuplot is not on the PATH, -1 when it failed. */
int lab_gnuplot(const char *dir, const char *script);

/* Script text: a double-quoted gnuplot string (backslash and quote
 * escaped, a newline written \n); the title, axis labels, grid and legend
 * every figure shares (log axes when asked); a data block $name. */
void lab_gp_str(api_buf *b, const char *s);
void lab_gp_axes(api_buf *b, const char *title, const char *xlabel, const char *ylabel, int logx, int logy);
void lab_gp_block_begin(api_buf *b, const char *name);
void lab_gp_block_end(api_buf *b);

#endif /* LAB_H */
