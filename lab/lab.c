/* SPDX-License-Identifier: MIT */
/*
 * lab.c - the lab's shared helpers (lab.h): messages, folders, CSV files,
 * mesh files and gnuplot figures.
 */
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "lab.h"

const char *lab_prog = "mcflab";
const char *lab_topic = NULL;

int lab_fail(int code, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (size_t i = 0; msg[i]; i++)
        if (msg[i] == '\n' || msg[i] == '\r')
            msg[i] = ' ';
    if (lab_topic)
        fprintf(stderr, "%s: %s: %s\n", lab_prog, lab_topic, msg);
    else
        fprintf(stderr, "%s: %s\n", lab_prog, msg);
    return code;
}

/* ------------------------------------------------------------------- files */

int lab_mkdir_p(const char *dir)
{
    char path[4096];
    if (snprintf(path, sizeof path, "%s", dir) >= (int)sizeof path)
        return lab_fail(1, "%s: path too long", dir);
    for (char *p = path + 1; ; p++) {
        if (*p == '/' || *p == '\0') {
            char c = *p;
            *p = '\0';
            if (mkdir(path, 0777) != 0 && errno != EEXIST)
                return lab_fail(1, "cannot create '%s': %s", path, strerror(errno));
            *p = c;
            if (c == '\0')
                break;
        }
    }
    struct stat sb;
    if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode))
        return lab_fail(1, "'%s' is not a folder", dir);
    return 0;
}

FILE *lab_csv_open(const char *path)
{
    FILE *f = fopen(path, "w");
    if (!f)
        lab_fail(1, "cannot write '%s': %s", path, strerror(errno));
    return f;
}

int lab_csv_close(FILE *f, const char *path)
{
    int bad = ferror(f);
    if (fclose(f) != 0 || bad)
        return lab_fail(1, "cannot write '%s'", path);
    return 0;
}

void lab_csv_clean(const char *in, char *out, size_t size)
{
    size_t i;
    for (i = 0; in[i] && i + 1 < size; i++)
        out[i] = (in[i] == ',' || in[i] == '"' || in[i] == '\n' || in[i] == '\r') ? ';' : in[i];
    out[i] = '\0';
}

int lab_load_mesh(const char *path, mcf_mesh **out)
{
    api_limits lim;
    mcf_error err = {MCF_OK, ""};
    FILE *f = fopen(path, "rb");
    char *buf = NULL;
    size_t n = 0, cap = 0;
    int rc = 1;

    api_limits_default(&lim);
    if (!f)
        return lab_fail(1, "cannot read '%s': %s", path, strerror(errno));
    for (;;) {
        if (cap - n < 65536) {
            size_t ncap = cap ? 2 * cap : 1 << 20;
            char *p = ncap > lim.max_input_bytes + 65536 ? NULL : realloc(buf, ncap);
            if (!p) {
                lab_fail(1, "'%s': too large or out of memory", path);
                goto done;
            }
            buf = p;
            cap = ncap;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f)) {
                lab_fail(1, "cannot read '%s': %s", path, strerror(errno));
                goto done;
            }
            break;
        }
    }
    if (api_mesh_decode(buf, n, &lim, out, NULL, &err) != MCF_OK) {
        lab_fail(1, "%s: %s", path, err.msg);
        goto done;
    }
    rc = 0;
done:
    free(buf);
    fclose(f);
    return rc;
}

/* ----------------------------------------------------------------- gnuplot */

int lab_gnuplot(const char *dir, const char *script)
{
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        if (chdir(dir) != 0)
            _exit(126);
        execlp("gnuplot", "gnuplot", script, (char *)NULL);
        _exit(127);
    }
    int ws;
    while (waitpid(pid, &ws, 0) < 0)
        if (errno != EINTR)
            return -1;
    if (WIFEXITED(ws) && WEXITSTATUS(ws) == 127)
        return 1;
    return WIFEXITED(ws) && WEXITSTATUS(ws) == 0 ? 0 : -1;
}

int lab_plot_render(lab_plot *pl, const char *stem, const api_buf *body)
{
    char script[4096];
    int fd, rc = 0;
    FILE *f;

    if (!pl->enabled)
        return 0;
    if (pl->keep_scripts) {
        snprintf(script, sizeof script, "%s/%s.gp", pl->dir, stem);
        fd = open(script, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    } else {
        snprintf(script, sizeof script, "%s/.mcf-plot-XXXXXX", pl->dir);
        fd = mkstemp(script);
    }
    if (fd < 0)
        return lab_fail(1, "cannot write a gnuplot script in '%s': %s", pl->dir, strerror(errno));
    f = fdopen(fd, "w");
    if (!f) {
        close(fd);
        return lab_fail(1, "cannot write a gnuplot script: %s", strerror(errno));
    }
    fprintf(f, "# %s; run in this folder: gnuplot %s.gp\n", pl->header ? pl->header : lab_prog, stem);
    fprintf(f, "set encoding utf8\n"
               "set terminal pngcairo size 1200,720 enhanced font \"DejaVu Sans,13\" background rgb \"white\"\n"
               "set output \"%s.png\"\n%s\nunset output\n",
            stem, body->data);
    fprintf(f, "set terminal svg size 1200,720 dynamic enhanced font \"DejaVu Sans,13\" background rgb \"white\"\n"
               "set output \"%s.svg\"\nreplot\nunset output\n",
            stem);
    if (fclose(f) != 0) {
        remove(script);
        return lab_fail(1, "cannot write the gnuplot script '%s'", script);
    }
    switch (lab_gnuplot(pl->dir, strrchr(script, '/') + 1)) {
    case 0:
        if (!pl->quiet)
            fprintf(stderr, "wrote %s/%s.png and .svg\n", pl->dir, stem);
        break;
    case 1:
        pl->enabled = 0; /* once is enough: the rest of the run skips figures */
        fprintf(stderr, "%s: gnuplot not found on the PATH: plots skipped, CSV files written\n", lab_prog);
        break;
    default:
        rc = lab_fail(1, "gnuplot failed on %s/%s.png (script %s)", pl->dir, stem, script);
        break;
    }
    if (!pl->keep_scripts && rc == 0)
        remove(script);
    return rc;
}

void lab_gp_str(api_buf *b, const char *s)
{
    api_buf_append(b, "\"", 1);
    for (; *s; s++) {
        if (*s == '\n') {
            api_buf_append(b, "\\n", 2);
            continue;
        }
        if (*s == '"' || *s == '\\')
            api_buf_append(b, "\\", 1);
        api_buf_append(b, s, 1);
    }
    api_buf_append(b, "\"", 1);
}

void lab_gp_axes(api_buf *b, const char *title, const char *xlabel, const char *ylabel, int logx, int logy)
{
    api_buf_printf(b, "set title ");
    lab_gp_str(b, title);
    api_buf_printf(b, "\nset xlabel ");
    lab_gp_str(b, xlabel);
    api_buf_printf(b, "\nset ylabel ");
    lab_gp_str(b, ylabel);
    api_buf_printf(b, "\nset grid xtics ytics mxtics mytics lc rgb \"#e0e0e0\" lw 1, lc rgb \"#f2f2f2\" lw 1\n"
                      "set key outside right top spacing 1.15 box lc rgb \"#bbbbbb\"\n"
                      "set border lw 1.2\nset tics nomirror\n");
    if (logx)
        api_buf_printf(b, "set logscale x\nset format x \"10^{%%L}\"\n");
    if (logy)
        api_buf_printf(b, "set logscale y\nset format y \"10^{%%L}\"\n");
}

void lab_gp_block_begin(api_buf *b, const char *name)
{
    api_buf_printf(b, "$%s << EOD\n", name);
}

void lab_gp_block_end(api_buf *b)
{
    api_buf_printf(b, "EOD\n");
}
