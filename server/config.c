/* SPDX-License-Identifier: MIT */
/*
 * config.c - mcfd's configuration: embedded defaults, then MCFD_*
 * environment variables, then command-line flags (the last word wins).
 *
 * One table lists every setting with its flag, its variable, its type and
 * its help line, so --help, the environment and the flags cannot drift
 * apart. Sizes take K/M/G suffixes (powers of 1024), durations s/m/h/d.
 * Every value is range-checked here; a bad one stops the start with a
 * message naming the flag or variable.
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <microhttpd.h>

#include "srv.h"


typedef enum { T_STR, T_INT, T_SIZE, T_DUR, T_NUM, T_LEVEL, T_FLAG } type;

typedef struct {
    const char *flag;      /* "--port" */
    const char *env;       /* "MCFD_PORT" or NULL */
    type t;
    long lo, hi;           /* T_INT range */
    const char *help;
} option;

enum {
    O_BIND, O_PORT, O_GRPC_PORT, O_WORKERS, O_CORES, O_QUEUE, O_HTTP_THREADS, O_MAX_CONN,
    O_MAX_CONN_IP, O_SPOOL, O_SPOOL_JOBS, O_SPOOL_BYTES, O_STORE, O_STORE_PW,
    O_BLOB_DIR, O_ALLOW_EVICTION,
    O_MAX_UPLOAD, O_MAX_VERTICES, O_MAX_FACES, O_MAX_ITER, O_MAX_WORK,
    O_MAX_JSON, O_TTL, O_JOB_TIMEOUT, O_DRAIN, O_HEADER_TIMEOUT,
    O_BODY_TIMEOUT, O_SEND_TIMEOUT, O_MAX_MEMORY, O_MAX_JOB_MEMORY, O_DECODE_CPU,
    O_DECODE_MEMORY, O_JOB_CPU, O_TOKEN,
    O_LOG, O_PROBE,
    O_HELP, O_VERSION, O_COUNT
};

static const option opts[O_COUNT] = {
    [O_BIND] = {"--bind", "MCFD_BIND", T_STR, 0, 0,
                "address to listen on (default 127.0.0.1)"},
    [O_PORT] = {"--port", "MCFD_PORT", T_INT, 0, 65535,
                "TCP port, 0 picks a free one (default 8080)"},
    [O_GRPC_PORT] = {"--grpc-port", "MCFD_GRPC_PORT", T_STR, 0, 0,
                     "gRPC port on the same address, 0 picks a free one, "
                     "off (or -1) disables it (default 50051)"},
    [O_WORKERS] = {"--workers", "MCFD_WORKERS", T_INT, 1, 1024,
                   "mesh worker threads: jobs run at once, at most one per "
                   "core (default: online CPUs)"},
    [O_CORES] = {"--cores", "MCFD_CORES", T_INT, 1, 1024,
                 "cores the jobs share, never oversubscribed (default: "
                 "online CPUs): a job holds one while it runs, and a job "
                 "of 20,000 vertices or more also takes, as its flow "
                 "starts, every core no other running job holds, for its "
                 "threads; a job finding no core free waits queued for "
                 "one. A lone big scan runs on every core"},
    [O_QUEUE] = {"--queue", "MCFD_QUEUE", T_INT, 0, 1000000,
                 "jobs waiting for a worker before 503 (default 64)"},
    [O_HTTP_THREADS] = {"--http-threads", "MCFD_HTTP_THREADS", T_INT, 1, 64,
                        "HTTP (libmicrohttpd) threads (default 2)"},
    [O_MAX_CONN] = {"--max-connections", "MCFD_MAX_CONNECTIONS", T_INT, 4,
                    100000, "open connections (default 512)"},
    [O_MAX_CONN_IP] = {"--max-connections-per-ip",
                       "MCFD_MAX_CONNECTIONS_PER_IP", T_INT, 0, 100000,
                       "open connections from one address, 0: no limit "
                       "(default 64)"},
    [O_SPOOL] = {"--spool", "MCFD_SPOOL", T_STR, 0, 0,
                 "job spool directory (default ./var/mcfd)"},
    [O_STORE] = {"--store", "MCFD_STORE", T_STR, 0, 0,
                 "redis://HOST[:PORT][/DB]: keep jobs in Redis, shared by "
                 "replicas (default: the local spool)"},
    [O_STORE_PW] = {"--store-password-file", "MCFD_STORE_PASSWORD_FILE", T_STR,
                    0, 0, "file holding the Redis password (default: none)"},
    [O_ALLOW_EVICTION] = {"--redis-allow-eviction",
                          "MCFD_REDIS_ALLOW_EVICTION", T_FLAG, 0, 0,
                          "run on a Redis whose maxmemory-policy may evict "
                          "keys (default: refused at start; env: 1)"},
    [O_BLOB_DIR] = {"--blob-dir", "MCFD_BLOB_DIR", T_STR, 0, 0,
                    "with --store: mesh bytes in files in this directory "
                    "shared by the replicas, not in Redis (default: Redis)"},
    [O_SPOOL_JOBS] = {"--spool-max-jobs", "MCFD_SPOOL_MAX_JOBS", T_INT, 0,
                      1000000000, "jobs kept (queued to expired) before new "
                      "ones get 503, 0: no limit (default 10000)"},
    [O_SPOOL_BYTES] = {"--spool-max-bytes", "MCFD_SPOOL_MAX_BYTES", T_SIZE, 0,
                       0, "bytes of jobs kept before new ones get 503 "
                       "(default 4G)"},
    [O_MAX_UPLOAD] = {"--max-upload", "MCFD_MAX_UPLOAD", T_SIZE, 0, 0,
                      "largest upload: the mesh, or the mesh and a target "
                      "together, e.g. 256M; a Content-Length over it is "
                      "refused before the body (default 256M)"},
    [O_MAX_VERTICES] = {"--max-vertices", "MCFD_MAX_VERTICES", T_INT, 3,
                        2000000000, "vertices per mesh (default 100000000: memory, --max-memory, is "
                        "the wall)"},
    [O_MAX_FACES] = {"--max-faces", "MCFD_MAX_FACES", T_INT, 1, 2000000000,
                     "faces per mesh (default 200000000)"},
    [O_MAX_ITER] = {"--max-iterations", "MCFD_MAX_ITERATIONS", T_INT, 1,
                    2000000000, "steps per job (default 100000)"},
    [O_MAX_WORK] = {"--max-work", "MCFD_MAX_WORK", T_NUM, 0, 0,
                    "iterations x vertices per job (default 2e10)"},
    [O_MAX_JSON] = {"--max-json", "MCFD_MAX_JSON", T_SIZE, 0, 0,
                    "parameter document size (default 64K)"},
    [O_TTL] = {"--result-ttl", "MCFD_RESULT_TTL", T_DUR, 0, 0,
               "how long finished jobs are kept, e.g. 1h (default 1h)"},
    [O_JOB_TIMEOUT] = {"--job-timeout", "MCFD_JOB_TIMEOUT", T_DUR, 0, 0,
                       "longest run of one job, 0: none (default 10m plus "
                       "0.5 s per MiB of its memory estimate; given, this "
                       "alone)"},
    [O_DRAIN] = {"--drain-timeout", "MCFD_DRAIN_TIMEOUT", T_DUR, 0, 0,
                 "SIGTERM: wait for running jobs, then checkpoint "
                 "(default 25s)"},
    [O_HEADER_TIMEOUT] = {"--header-timeout", "MCFD_HEADER_TIMEOUT", T_DUR,
                          0, 0, "a request's line and headers must arrive "
                          "within this of the connection or the last answer, "
                          "0: no limit (default 30s)"},
    [O_BODY_TIMEOUT] = {"--body-timeout", "MCFD_BODY_TIMEOUT", T_DUR, 0, 0,
                        "a request's whole body must arrive within this of "
                        "its head, 0: no limit (default 60s + --max-upload at "
                        "1 MiB/s: 316s)"},
    [O_SEND_TIMEOUT] = {"--send-timeout", "MCFD_SEND_TIMEOUT", T_DUR, 0, 0,
                        "a client that reads nothing of its answer for this "
                        "long loses its connection (REST, also an idle "
                        "keep-alive one) or its gRPC call (default 60s)"},
    [O_MAX_MEMORY] = {"--max-memory", "MCFD_MAX_MEMORY", T_SIZE, 0, 0,
                      "estimated peak memory of the jobs running at once; "
                      "others wait in the queue (default: half the RAM, or of "
                      "the container's cgroup limit when lower)"},
    [O_MAX_JOB_MEMORY] = {"--max-job-memory", "MCFD_MAX_JOB_MEMORY", T_SIZE,
                          0, 0, "estimated peak memory of one job; a larger "
                          "one is refused with 422 (default --max-memory)"},
    [O_DECODE_CPU] = {"--decode-cpu", "MCFD_DECODE_CPU", T_DUR, 0, 0,
                      "CPU seconds of a sandboxed Draco decode, plus 1 us per "
                      "declared face (default 2s)"},
    [O_JOB_CPU] = {"--job-cpu", "MCFD_JOB_CPU", T_DUR, 0, 0,
                   "a job's CPU budget: this plus 0.5 s per MiB of its memory "
                   "estimate, 0: none (default 30s)"},
    [O_DECODE_MEMORY] = {"--decode-memory", "MCFD_DECODE_MEMORY", T_SIZE, 0,
                         0, "smallest memory limit of a sandboxed Draco "
                         "decode; above it twice the estimate (default 64M)"},
    [O_TOKEN] = {"--token-file", "MCFD_TOKEN_FILE", T_STR, 0, 0,
                 "file holding the bearer token (default: no auth)"},
    [O_LOG] = {"--log-level", "MCFD_LOG_LEVEL", T_LEVEL, 0, 0,
               "error|warn|info|debug (default info)"},
    [O_PROBE] = {"--probe", NULL, T_FLAG, 0, 0,
                 "check GET /healthz of the configured daemon, exit 0/1"},
    [O_HELP] = {"--help", NULL, T_FLAG, 0, 0, "this text"},
    [O_VERSION] = {"--version", NULL, T_FLAG, 0, 0, "print the version"},
};

/* The memory this process may use: the machine's RAM, or the limit of
 * its cgroup when that is lower (a container's --memory: cgroup v2's
 * memory.max, or v1's memory.limit_in_bytes; "max" or a huge v1 value
 * mean none). 8 GiB when sysconf cannot tell. The default --max-memory is
 * half of it: the daemon shares it with its spool's page cache, the
 * sandboxed decoders and, outside a container, its host. */
static size_t memory_available(void)
{
    static const char *const limits[] = {
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    };
    long pages = sysconf(_SC_PHYS_PAGES), psz = sysconf(_SC_PAGESIZE);
    size_t ram = pages > 0 && psz > 0 ? (size_t)pages * (size_t)psz
                                      : (size_t)8 << 30;
    size_t i;

    for (i = 0; i < sizeof limits / sizeof limits[0]; i++) {
        FILE *f = fopen(limits[i], "r");
        unsigned long long v;

        if (!f)
            continue;
        if (fscanf(f, "%llu", &v) == 1 && v > 0 && v < ram)
            ram = (size_t)v;
        fclose(f);
    }
    return ram;
}

static int parse_int(const char *s, long lo, long hi, long *out)
{
    char *end;
    long v;

    errno = 0;
    v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi)
        return -1;
    *out = v;
    return 0;
}

static int parse_size(const char *s, size_t *out)
{
    char *end;
    double v, mul = 1;

    errno = 0;
    v = strtod(s, &end);
    if (errno || end == s || !(v >= 0))
        return -1;
    switch (toupper((unsigned char)*end)) {
    case 'K': mul = 1024.0; end++; break;
    case 'M': mul = 1048576.0; end++; break;
    case 'G': mul = 1073741824.0; end++; break;
    default: break;
    }
    if (toupper((unsigned char)*end) == 'B')
        end++;
    if (*end || v * mul > 1e15)
        return -1;
    *out = (size_t)(v * mul);
    return 0;
}

static int parse_duration(const char *s, double *out)
{
    char *end;
    double v;

    errno = 0;
    v = strtod(s, &end);
    if (errno || end == s || !(v >= 0) || !isfinite(v))
        return -1;
    if (*end == 's')
        end++;
    else if (*end == 'm')
        v *= 60, end++;
    else if (*end == 'h')
        v *= 3600, end++;
    else if (*end == 'd')
        v *= 86400, end++;
    if (*end)
        return -1;
    *out = v;
    return 0;
}

static int set(srv_config *cfg, int o, const char *v, const char *src,
               char *msg, size_t msgsize)
{
    long i = 0;
    size_t z = 0;
    double d = 0;
    const option *op = &opts[o];

    if (op->t == T_INT && parse_int(v, op->lo, op->hi, &i) != 0) {
        snprintf(msg, msgsize, "%s: expected an integer in [%ld, %ld], got "
                 "\"%s\"", src, op->lo, op->hi, v);
        return -1;
    }
    if (op->t == T_SIZE && (parse_size(v, &z) != 0 || z == 0)) {
        snprintf(msg, msgsize, "%s: expected a size > 0 such as 64K, 256M, "
                 "1G, got \"%s\"", src, v);
        return -1;
    }
    if (op->t == T_DUR && parse_duration(v, &d) != 0) {
        snprintf(msg, msgsize, "%s: expected a duration such as 30s, 10m, "
                 "1h, got \"%s\"", src, v);
        return -1;
    }
    if (op->t == T_NUM) {
        char *end;
        d = strtod(v, &end);
        if (end == v || *end || !(d > 0) || !isfinite(d)) {
            snprintf(msg, msgsize, "%s: expected a number > 0, got \"%s\"",
                     src, v);
            return -1;
        }
    }
    switch (o) {
    case O_ALLOW_EVICTION:        /* from the environment: 1 or 0 */
        if (strcmp(v, "1") != 0 && strcmp(v, "0") != 0) {
            snprintf(msg, msgsize, "%s: expected 1 or 0, got \"%s\"", src, v);
            return -1;
        }
        cfg->svc.redis_allow_eviction = v[0] == '1';
        break;
    case O_BIND:
        if (!*v || strlen(v) >= sizeof cfg->bind) {
            snprintf(msg, msgsize, "%s: bad address \"%s\"", src, v);
            return -1;
        }
        snprintf(cfg->bind, sizeof cfg->bind, "%s", v);
        break;
    case O_PORT: cfg->port = (int)i; break;
    case O_GRPC_PORT:
        if (strcmp(v, "off") == 0)
            cfg->grpc_port = -1;
        else if (parse_int(v, -1, 65535, &i) == 0)
            cfg->grpc_port = (int)i;
        else {
            snprintf(msg, msgsize, "%s: expected a port in [0, 65535], -1 or "
                     "off, got \"%s\"", src, v);
            return -1;
        }
        break;
    case O_WORKERS: cfg->svc.workers = (int)i; break;
    case O_CORES: cfg->svc.cores = (int)i; break;
    case O_QUEUE: cfg->svc.queue = (int)i; break;
    case O_HTTP_THREADS: cfg->http_threads = (int)i; break;
    case O_MAX_CONN: cfg->max_connections = (int)i; break;
    case O_MAX_CONN_IP: cfg->max_connections_per_ip = (int)i; break;
    case O_SPOOL:
        if (!*v || strlen(v) >= sizeof cfg->svc.spool - 64) {
            snprintf(msg, msgsize, "%s: bad directory \"%s\"", src, v);
            return -1;
        }
        snprintf(cfg->svc.spool, sizeof cfg->svc.spool, "%s", v);
        break;
    case O_STORE:
        if (strncmp(v, "redis://", 8) != 0 || strlen(v) >= sizeof cfg->svc.store) {
            snprintf(msg, msgsize, "%s: expected redis://HOST[:PORT][/DB], "
                     "got \"%s\"", src, v);
            return -1;
        }
        snprintf(cfg->svc.store, sizeof cfg->svc.store, "%s", v);
        break;
    case O_BLOB_DIR:
        if (!*v || strlen(v) >= sizeof cfg->svc.blob_dir - 128) {
            snprintf(msg, msgsize, "%s: bad directory \"%s\"", src, v);
            return -1;
        }
        snprintf(cfg->svc.blob_dir, sizeof cfg->svc.blob_dir, "%s", v);
        break;
    case O_STORE_PW:
        snprintf(cfg->svc.store_password_file, sizeof cfg->svc.store_password_file,
                 "%s", v);
        break;
    case O_SPOOL_JOBS: cfg->svc.spool_max_jobs = (int)i; break;
    case O_SPOOL_BYTES: cfg->svc.spool_max_bytes = z; break;
    case O_MAX_UPLOAD: cfg->svc.lim.max_input_bytes = z; break;
    case O_MAX_VERTICES: cfg->svc.lim.max_vertices = (int)i; break;
    case O_MAX_FACES: cfg->svc.lim.max_faces = (int)i; break;
    case O_MAX_ITER: cfg->svc.lim.max_iterations = (int)i; break;
    case O_MAX_WORK: cfg->svc.lim.max_work = d; break;
    case O_MAX_JSON: cfg->svc.lim.max_json_bytes = z; break;
    case O_TTL: cfg->svc.result_ttl = d; break;
    case O_JOB_TIMEOUT:
        cfg->svc.job_timeout = d;
        cfg->svc.job_timeout_per_mib = 0;
        break;
    case O_JOB_CPU: cfg->svc.job_cpu = d; break;
    case O_DRAIN: cfg->drain_timeout = d; break;
    case O_HEADER_TIMEOUT: cfg->header_timeout = d; break;
    case O_BODY_TIMEOUT: cfg->body_timeout = d; break;
    case O_SEND_TIMEOUT: cfg->send_timeout = d; break;
    case O_MAX_MEMORY: cfg->svc.max_memory = z; break;
    case O_MAX_JOB_MEMORY: cfg->svc.max_job_memory = z; break;
    case O_DECODE_CPU:
        if (!(d > 0)) {
            snprintf(msg, msgsize, "%s: must be > 0", src);
            return -1;
        }
        cfg->svc.decode_cpu = d;
        break;
    case O_DECODE_MEMORY: cfg->svc.decode_memory = z; break;
    case O_TOKEN:
        snprintf(cfg->token_file, sizeof cfg->token_file, "%s", v);
        break;
    case O_LOG: {
        static const char *const names[] = {"error", "warn", "info", "debug"};
        int k;
        for (k = 0; k < 4; k++)
            if (strcasecmp(v, names[k]) == 0)
                break;
        if (k == 4) {
            snprintf(msg, msgsize, "%s: expected error, warn, info or debug, "
                     "got \"%s\"", src, v);
            return -1;
        }
        cfg->log_level = (srv_log_level)k;
        break;
    }
    default:
        break;
    }
    return 0;
}

static void usage(FILE *f)
{
    int o;
    fprintf(f, "usage: mcfd [options]\n"
               "The mcfd mesh-smoothing daemon (mean curvature flow over HTTP).\n"
               "Every option can also be set through its environment variable;"
               "\nflags win.\n\n");
    for (o = 0; o < O_COUNT; o++) {
        char left[64];
        snprintf(left, sizeof left, "%s%s", opts[o].flag,
                 opts[o].t == T_FLAG ? "" : " VALUE");
        fprintf(f, "  %-20s %s\n", left, opts[o].help);
        if (opts[o].env)
            fprintf(f, "  %-20s   env: %s\n", "", opts[o].env);
    }
}

static int read_token(srv_config *cfg, char *msg, size_t msgsize)
{
    FILE *f = fopen(cfg->token_file, "r");
    size_t n;

    if (!f) {
        snprintf(msg, msgsize, "--token-file %s: %s", cfg->token_file,
                 strerror(errno));
        return -1;
    }
    n = fread(cfg->token, 1, sizeof cfg->token - 1, f);
    fclose(f);
    cfg->token[n] = '\0';
    while (n > 0 && isspace((unsigned char)cfg->token[n - 1]))
        cfg->token[--n] = '\0';
    if (n == 0 || n >= sizeof cfg->token - 2) {
        snprintf(msg, msgsize, "--token-file %s: the token must be 1 to %zu "
                 "bytes on one line", cfg->token_file, sizeof cfg->token - 3);
        return -1;
    }
    cfg->token_len = n;
    return 0;
}

int srv_config_load(srv_config *cfg, int argc, char **argv, char *msg,
                    size_t msgsize)
{
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    int o, a;

    memset(cfg, 0, sizeof *cfg);
    snprintf(cfg->bind, sizeof cfg->bind, "127.0.0.1");
    cfg->port = 8080;
    cfg->grpc_port = 50051;
    cfg->svc.workers = ncpu > 0 ? (int)(ncpu < 1024 ? ncpu : 1024) : 1;
    cfg->svc.cores = cfg->svc.workers;   /* online CPUs */
    cfg->svc.queue = 64;
    cfg->http_threads = 2;
    cfg->max_connections = 512;
    cfg->max_connections_per_ip = 64;
    cfg->svc.spool_max_jobs = 10000;
    cfg->svc.spool_max_bytes = (size_t)4 << 30;
    snprintf(cfg->svc.spool, sizeof cfg->svc.spool, "./var/mcfd");
    api_limits_default(&cfg->svc.lim);
    cfg->svc.result_ttl = 3600;
    cfg->svc.job_timeout = 600;
    cfg->svc.job_cpu = 30;
    cfg->drain_timeout = 25;
    cfg->header_timeout = 30;
    cfg->body_timeout = -1;    /* derived from --max-upload below */
    cfg->send_timeout = 60;
    cfg->svc.decode_cpu = API_DECODE_CPU_S;
    cfg->svc.decode_memory = API_DECODE_MEMORY;
    /* CPU seconds per MiB of a job's memory estimate in its budget: the
     * estimate grows with the vertices (640-2,900 B each) and a step's
     * CPU with them; the dragon (435k vertices, estimate 673 MiB, default
     * parameters) takes 27 s, its budget 366 s. A knob for tests and
     * tuning, like MCFD_REDIS_CLAIM_IDLE. */
    cfg->svc.job_cpu_per_mib = getenv("MCFD_JOB_CPU_PER_MIB") &&
                                       atof(getenv("MCFD_JOB_CPU_PER_MIB")) >= 0
                                   ? atof(getenv("MCFD_JOB_CPU_PER_MIB"))
                                   : 0.5;
    /* The default job timeout grows like the CPU budget: 10 minutes were
     * 584 s of a 7M-vertex scan's flow on one of 2 cores at load 15
     * (2026-11-29, lab/bench/README.md); its estimate, 4,303 MiB, gives
     * it 10 + 36 minutes. */
    cfg->svc.job_timeout_per_mib = getenv("MCFD_JOB_TIMEOUT_PER_MIB") &&
                                           atof(getenv("MCFD_JOB_TIMEOUT_PER_MIB")) >= 0
                                       ? atof(getenv("MCFD_JOB_TIMEOUT_PER_MIB"))
                                       : 0.5;
    cfg->svc.max_memory = memory_available() / 2;
    cfg->log_level = SRV_LOG_INFO;

    for (o = 0; o < O_COUNT; o++) {
        const char *v = opts[o].env ? getenv(opts[o].env) : NULL;
        if (v && *v && set(cfg, o, v, opts[o].env, msg, msgsize) != 0)
            return -1;
    }
    for (a = 1; a < argc; a++) {
        const char *arg = argv[a], *eq = strchr(arg, '='), *v = NULL;
        size_t n = eq ? (size_t)(eq - arg) : strlen(arg);
        for (o = 0; o < O_COUNT; o++)
            if (strlen(opts[o].flag) == n && strncmp(arg, opts[o].flag, n) == 0)
                break;
        if (o == O_COUNT) {
            snprintf(msg, msgsize, "unknown option \"%s\" (see --help)", arg);
            return -1;
        }
        if (opts[o].t == T_FLAG) {
            if (eq) {
                snprintf(msg, msgsize, "%s takes no value", opts[o].flag);
                return -1;
            }
            if (o == O_HELP) {
                usage(stdout);
                return 1;
            }
            if (o == O_VERSION) {
                printf("mcfd %s (libmicrohttpd %s)\n", API_VERSION,
                       MHD_get_version());
                return 1;
            }
            if (o == O_ALLOW_EVICTION)
                cfg->svc.redis_allow_eviction = 1;
            else
                cfg->probe = 1;
            continue;
        }
        if (eq)
            v = eq + 1;
        else if (a + 1 < argc)
            v = argv[++a];
        else {
            snprintf(msg, msgsize, "%s needs a value", opts[o].flag);
            return -1;
        }
        if (set(cfg, o, v, opts[o].flag, msg, msgsize) != 0)
            return -1;
    }
    /* A multipart body carries the mesh, an optional target and params. */
    if (cfg->svc.lim.max_input_bytes > SIZE_MAX / 2 - 2 * cfg->svc.lim.max_json_bytes -
                                       (1u << 20)) {
        snprintf(msg, msgsize, "--max-upload is too large");
        return -1;
    }
    /* a multipart body: the mesh and a target together within
     * --max-upload, the params part and the plain fields within the JSON
     * limit each, and 1 MiB for the parts' headers and boundaries */
    cfg->max_body = cfg->svc.lim.max_input_bytes + 2 * cfg->svc.lim.max_json_bytes +
                    (1u << 20);
    /* A minute for the head's round trips plus the largest upload at
     * 1 MiB/s (8 Mbit/s): a client trickling at the 4 KiB/s the average
     * rule allows cannot keep a slot for the 18 h a 256 MiB upload would
     * take it. */
    if (cfg->body_timeout < 0)
        cfg->body_timeout = 60.0 + (double)cfg->svc.lim.max_input_bytes / 1048576.0;
    if (cfg->svc.max_job_memory == 0 || cfg->svc.max_job_memory > cfg->svc.max_memory)
        cfg->svc.max_job_memory = cfg->svc.max_memory;
    if (cfg->token_file[0] && !cfg->probe && read_token(cfg, msg, msgsize) != 0)
        return -1;
    if (cfg->svc.blob_dir[0] && !cfg->svc.store[0]) {
        snprintf(msg, msgsize, "--blob-dir needs --store redis://...: the "
                 "local spool keeps its blobs in its own directory");
        return -1;
    }
    return 0;
}

/* Constant time in the length of the configured token, whatever the
 * given value (REST's Authorization header, gRPC's authorization
 * metadata). */
int srv_bearer_ok(const srv_config *cfg, const char *authorization)
{
    volatile unsigned char d;
    size_t i, glen;
    const char *given = authorization;

    if (cfg->token_len == 0)
        return 1;
    if (!given || strncasecmp(given, "Bearer ", 7) != 0)
        return 0;
    given += 7;
    while (*given == ' ')
        given++;
    glen = strlen(given);
    d = (unsigned char)(glen != cfg->token_len);
    for (i = 0; i < cfg->token_len; i++)
        d |= (unsigned char)(cfg->token[i] ^ (i < glen ? given[i] : 0));
    return d == 0;
}
