/* SPDX-License-Identifier: MIT */
/*
 * log.c - structured logging: one JSON object per line on stderr.
 *
 * Every request and every job ends in exactly one line, so a log shipper
 * can parse the stream without multi-line rules. Lines are written with a
 * single fwrite under a mutex: workers and MHD threads never interleave.
 * The level is process-wide and set once by main() before any thread.
 */
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "srv.h"

static srv_log_level g_level = SRV_LOG_INFO;
static pthread_mutex_t g_log_mu = PTHREAD_MUTEX_INITIALIZER;

static const char *const level_names[] = {"error", "warn", "info", "debug"};

void srv_log_set_level(srv_log_level lvl)
{
    g_level = lvl;
}

int srv_log_enabled(srv_log_level lvl)
{
    return lvl <= g_level;
}

double srv_wall(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

double srv_mono(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

void srv_time_rfc3339(double t, char *buf, size_t size)
{
    time_t s = (time_t)t;
    int ms = (int)((t - (double)s) * 1000.0);
    struct tm tm;
    char base[32];

    if (ms < 0)
        ms = 0;
    if (ms > 999)
        ms = 999;
    gmtime_r(&s, &tm);
    strftime(base, sizeof base, "%Y-%m-%dT%H:%M:%S", &tm);
    snprintf(buf, size, "%s.%03dZ", base, ms);
}

void srv_log_json(srv_log_level lvl, cJSON *obj)
{
    char ts[40];
    char *line;
    cJSON *out;

    if (!obj)
        return;
    if (!srv_log_enabled(lvl)) {
        cJSON_Delete(obj);
        return;
    }
    srv_time_rfc3339(srv_wall(), ts, sizeof ts);
    /* ts and level first, then the caller's keys in their order. */
    out = cJSON_CreateObject();
    if (!out || !cJSON_AddStringToObject(out, "ts", ts) ||
        !cJSON_AddStringToObject(out, "level", level_names[lvl])) {
        cJSON_Delete(out);
        cJSON_Delete(obj);
        return;
    }
    while (obj->child) {
        cJSON *item = cJSON_DetachItemViaPointer(obj, obj->child);
        if (!cJSON_AddItemToObject(out, item->string ? item->string : "",
                                   item))
            cJSON_Delete(item);
    }
    cJSON_Delete(obj);
    obj = out;
    line = cJSON_PrintUnformatted(obj);
    cJSON_Delete(obj);
    if (!line)
        return;
    pthread_mutex_lock(&g_log_mu);
    fputs(line, stderr);
    fputc('\n', stderr);
    fflush(stderr);
    pthread_mutex_unlock(&g_log_mu);
    free(line);
}

static void log_msg(srv_log_level lvl, const char *msg, long suppressed)
{
    cJSON *o = cJSON_CreateObject();
    if (!o)
        return;
    cJSON_AddStringToObject(o, "msg", msg);
    if (suppressed > 0)
        cJSON_AddNumberToObject(o, "suppressed", (double)suppressed);
    srv_log_json(lvl, o);
}

void srv_logf_limited(srv_log_limit *l, srv_log_level lvl, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    double now = srv_mono();
    long suppressed = 0;
    int say;

    if (!srv_log_enabled(lvl))
        return;
    pthread_mutex_lock(&g_log_mu);
    if (now - l->window > SRV_LOG_WINDOW) {
        suppressed = l->suppressed;
        l->window = now;
        l->lines = 0;
        l->suppressed = 0;
    }
    say = l->lines < SRV_LOG_BURST;
    if (say)
        l->lines++;
    else
        l->suppressed++;
    pthread_mutex_unlock(&g_log_mu);
    if (!say)
        return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    log_msg(lvl, msg, suppressed);
}

void srv_logf(srv_log_level lvl, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;

    if (!srv_log_enabled(lvl))
        return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    log_msg(lvl, msg, 0);
}
