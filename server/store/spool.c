/* SPDX-License-Identifier: MIT */
/*
 * spool.c - the local store of the job service (store.h): every job a
 * directory on disk, the queue in memory.
 *
 * Layout: <spool>/jobs/<id>/{input, target, request.json, state.json,
 * result.<ext>, metrics.json, fields.bin, events.ndjson, events.idx}. A
 * job exists once state.json exists (create writes it last); every file
 * is written to a temporary name, fsync()ed when it must survive a
 * crash, and renamed into place, so after kill -9 a file is either absent
 * or complete. The directory
 * entries themselves are made durable by fsync()ing the directory. A
 * removal renames the directory to a tombstone first (one durable step);
 * a quarantined job moves to <spool>/quarantine. Nothing here knows
 * about HTTP or JSON.
 *
 * The queue is this process's: a list of IDs under its own lock. After a
 * restart the service pushes the queued jobs again from their records
 * (recovery.c), so the list itself needs no disk. Heartbeats and progress
 * are no-ops: the service keeps a running job's events in memory (and
 * puts them here when it ends).
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include "srv.h"
#include "store.h"

#define SPOOL_PROBE_MAX ((size_t)4 << 20)

/* One ID in the queue. */
typedef struct qnode {
    char id[SVC_ID_LEN + 1];
    struct qnode *next;
} qnode;

typedef struct {
    svc_store base;
    char dir[1024];
    /* What the spool's own writes found, for readiness: whether a write
     * failed with no write as large succeeding since (pending), its size
     * and errno. A removal or a small state.json after a failed result
     * proves nothing about room for the next job: only a write of at
     * least the failed size clears it (a job's, or the probe's of
     * ready). */
    pthread_mutex_t health_mu;
    int pending, fail_errno;
    size_t fail_bytes;
    double probed;             /* srv_mono() of the last job-sized probe */
    int probe_errno;           /* its outcome: 0 or errno */
    /* Each writer its own temporary file: two writers of one name must
     * never rename each other's half-written bytes. */
    pthread_mutex_t seq_mu;
    unsigned long seq;
    /* the queue */
    pthread_mutex_t q_mu;
    qnode *qhead, *qtail;
} spool;

static void remove_tree(const char *dir);

static void note(spool *sp, int ok, size_t bytes)
{
    int e = errno;
    pthread_mutex_lock(&sp->health_mu);
    if (!ok) {
        if (!sp->pending || bytes > sp->fail_bytes)
            sp->fail_bytes = bytes;
        sp->pending = 1;
        sp->fail_errno = e;
    } else if (bytes >= sp->fail_bytes) {
        sp->pending = 0;
        sp->fail_bytes = 0;
    }
    pthread_mutex_unlock(&sp->health_mu);
    errno = e;
}

static int mkdir_p(const char *path)
{
    char buf[1200];
    size_t i, n = strlen(path);

    if (n == 0 || n >= sizeof buf) {
        errno = ENAMETOOLONG;
        return -1;
    }
    memcpy(buf, path, n + 1);
    for (i = 1; i <= n; i++) {
        if (buf[i] == '/' || buf[i] == '\0') {
            char c = buf[i];
            buf[i] = '\0';
            if (mkdir(buf, 0750) != 0 && errno != EEXIST)
                return -1;
            buf[i] = c;
        }
    }
    return 0;
}

/* <spool>/jobs/<id>/<name> (name may be ""). */
static int job_path(const spool *sp, char *buf, size_t size, const char *id,
                    const char *name)
{
    int n = snprintf(buf, size, "%s/jobs/%s%s%s", sp->dir, id,
                     name[0] ? "/" : "", name);
    if (n < 0 || (size_t)n >= size) {
        errno = ENAMETOOLONG;
        return -1;
    }
    return 0;
}

/* Makes dir/jobs, checks it is writable, and removes the tombstones of
 * removals a crash interrupted. */
static int spool_init(const char *dir, char *msg, size_t msgsize)
{
    char jobs[1200];
    char probe[1300];
    int fd;

    if (snprintf(jobs, sizeof jobs, "%s/jobs", dir) >= (int)sizeof jobs) {
        snprintf(msg, msgsize, "spool path too long: %s", dir);
        return -1;
    }
    if (mkdir_p(jobs) != 0) {
        snprintf(msg, msgsize, "cannot create spool %s: %s", jobs,
                 strerror(errno));
        return -1;
    }
    /* Fail at start, not at the first upload, when it is not writable. */
    snprintf(probe, sizeof probe, "%s/.write-test", dir);
    fd = open(probe, O_WRONLY | O_CREAT | O_TRUNC, 0640);
    if (fd < 0) {
        snprintf(msg, msgsize, "spool %s is not writable: %s", dir,
                 strerror(errno));
        return -1;
    }
    close(fd);
    unlink(probe);
    {
        DIR *d = opendir(jobs);
        struct dirent *e;
        char path[1500];
        while (d && (e = readdir(d)) != NULL)
            if (strncmp(e->d_name, ".del-", 5) == 0) {
                snprintf(path, sizeof path, "%s/%s", jobs, e->d_name);
                remove_tree(path);
            }
        if (d)
            closedir(d);
    }
    return 0;
}

/* Writes len bytes of zeros to path (no fsync: the question is room, and
 * tmpfs, ext4 and xfs all reserve blocks at write()); 0 or -1 (errno). */
static int write_zeros(const char *path, size_t len)
{
    static const char zeros[65536];
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0640), e = 0;

    if (fd < 0)
        return -1;
    while (len > 0 && !e) {
        ssize_t w = write(fd, zeros, len < sizeof zeros ? len : sizeof zeros);
        if (w < 0 && errno != EINTR)
            e = errno;
        else if (w > 0)
            len -= (size_t)w;
    }
    if (close(fd) != 0 && !e)
        e = errno;
    unlink(path);
    errno = e;
    return e ? -1 : 0;
}

/* Ready when a file can be made in the spool and no write failed without
 * a write at least as large succeeding since (this call probes one, of at
 * most SPOOL_PROBE_MAX bytes, twice a second at most); removals and
 * smaller writes do not count. */
static int sp_ready(svc_store *st, char *why, size_t size)
{
    spool *sp = (spool *)st;
    char probe[1300];
    size_t need;
    int pending, e;

    /* Can a file be made now? (Cheap: no fsync, removed at once.) */
    snprintf(probe, sizeof probe, "%s/jobs/.ready-probe", sp->dir);
    if (write_zeros(probe, 1) != 0) {
        snprintf(why, size, "the spool %s is not writable: %s", sp->dir,
                 strerror(errno));
        return -1;
    }
    /* After a failed write, ready only once a write as large succeeds: a
     * probe of that size (up to SPOOL_PROBE_MAX), at most twice a second
     * whoever asks, until a job's own write does it. */
    pthread_mutex_lock(&sp->health_mu);
    pending = sp->pending;
    need = sp->fail_bytes < SPOOL_PROBE_MAX ? sp->fail_bytes : SPOOL_PROBE_MAX;
    e = sp->fail_errno;
    if (pending && srv_mono() - sp->probed >= 0.5) {
        sp->probed = srv_mono();
        sp->probe_errno = write_zeros(probe, need) == 0 ? 0 : errno;
        if (sp->probe_errno == 0) {
            sp->pending = 0;
            sp->fail_bytes = 0;
        }
    }
    if (sp->pending && sp->probe_errno)
        e = sp->probe_errno;
    pending = sp->pending;
    pthread_mutex_unlock(&sp->health_mu);
    if (pending) {
        snprintf(why, size, "a write of %zu bytes to the spool %s failed: %s",
                 need, sp->dir, strerror(e));
        return -1;
    }
    return 0;
}

/* Makes the job directory (and fsyncs jobs/ so it survives a crash). */
static int mkjob(spool *sp, const char *id)
{
    char dir[1300], jobs[1200];

    if (job_path(sp, dir, sizeof dir, id, "") != 0)
        return -1;
    if (mkdir(dir, 0750) != 0 && errno != EEXIST)
        return -1;
    snprintf(jobs, sizeof jobs, "%s/jobs", sp->dir);
    return srv_sync_dir(jobs);
}

/* Writes data to <job>/<name> through a temporary file, fsync()s it when
 * durable, and renames it into place. */
static int sp_put(svc_store *st, const char *id, const char *name,
                  const void *data, size_t len, int durable)
{
    spool *sp = (spool *)st;
    char path[1400], tmp[1440], dir[1300];
    unsigned long k;
    int fd, rc = -1;

    if (job_path(sp, path, sizeof path, id, name) != 0 ||
        job_path(sp, dir, sizeof dir, id, "") != 0)
        return -1;
    pthread_mutex_lock(&sp->seq_mu);
    k = ++sp->seq;
    pthread_mutex_unlock(&sp->seq_mu);
    snprintf(tmp, sizeof tmp, "%s.%lu.tmp", path, k);
    fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC, 0640);
    if (fd < 0)
        return -1;
    if (srv_write_all(fd, data, len) != 0)
        goto fail;
    if (durable && fsync(fd) != 0)
        goto fail;
    if (close(fd) != 0) {
        fd = -1;
        goto fail;
    }
    fd = -1;
    if (rename(tmp, path) != 0)
        goto fail;
    if (durable && srv_sync_dir(dir) != 0)
        goto fail;
    rc = 0;
fail:
    if (fd >= 0)
        close(fd);
    if (rc != 0)
        unlink(tmp);
    note(sp, rc == 0, len);
    return rc;
}

static int sp_remove(svc_store *st, const char *id);

/* The directory, then each blob durably: state.json, the last, makes the
 * job exist. What fails is removed. */
static int sp_create(svc_store *st, const char *id, const svc_blob *blobs,
                     int n)
{
    spool *sp = (spool *)st;
    int i, e;

    if (mkjob(sp, id) != 0)
        goto fail;
    for (i = 0; i < n; i++)
        if (sp_put(st, id, blobs[i].name, blobs[i].data, blobs[i].len, 1) != 0)
            goto fail;
    return 0;
fail:
    e = errno;
    sp_remove(st, id);
    errno = e;
    return -1;
}

static int sp_get(svc_store *st, const char *id, const char *name,
                  char **data, size_t *len)
{
    spool *sp = (spool *)st;
    char path[1400];
    struct stat sb;
    char *buf = NULL;
    size_t done = 0;
    int fd, e;

    if (job_path(sp, path, sizeof path, id, name) != 0)
        return -1;
    fd = open(path, O_RDONLY);
    if (fd < 0)
        return -1;
    if (fstat(fd, &sb) != 0 || sb.st_size < 0)
        goto fail;
    buf = malloc((size_t)sb.st_size + 1);
    if (!buf)
        goto fail;
    while (done < (size_t)sb.st_size) {
        ssize_t r = read(fd, buf + done, (size_t)sb.st_size - done);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0) {
            if (r == 0)
                errno = EIO;
            goto fail;
        }
        done += (size_t)r;
    }
    close(fd);
    buf[done] = '\0';
    *data = buf;
    *len = done;
    return 0;
fail:
    e = errno;
    free(buf);
    close(fd);
    errno = e;
    return -1;
}

static int sp_get_at(svc_store *st, const char *id, const char *name,
                     size_t off, void *buf, size_t len)
{
    spool *sp = (spool *)st;
    char path[1400];
    size_t done = 0;
    int fd, e;

    if (job_path(sp, path, sizeof path, id, name) != 0)
        return -1;
    fd = open(path, O_RDONLY);
    if (fd < 0)
        return -1;
    while (done < len) {
        ssize_t r = pread(fd, (char *)buf + done, len - done, (off_t)(off + done));
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0) {
            e = r == 0 ? EIO : errno;
            close(fd);
            errno = e;
            return -1;
        }
        done += (size_t)r;
    }
    close(fd);
    return 0;
}

static int sp_stat(svc_store *st, const char *id, const char *name,
                   size_t *size)
{
    spool *sp = (spool *)st;
    char path[1400];
    struct stat sb;

    if (job_path(sp, path, sizeof path, id, name) != 0 || stat(path, &sb) != 0)
        return -1;
    *size = (size_t)sb.st_size;
    return 0;
}

static int sp_open(svc_store *st, const char *id, const char *name, int *fd,
                   size_t *size)
{
    spool *sp = (spool *)st;
    char path[1400];
    struct stat sb;
    int e;

    if (job_path(sp, path, sizeof path, id, name) != 0 ||
        (*fd = open(path, O_RDONLY)) < 0)
        return -1;
    if (fstat(*fd, &sb) != 0) {
        e = errno;
        close(*fd);
        *fd = -1;
        errno = e;
        return -1;
    }
    *size = (size_t)sb.st_size;
    return 0;
}

/* Removes a directory and the files in it (best effort). */
static void remove_tree(const char *dir)
{
    char path[1700];
    DIR *d = opendir(dir);
    struct dirent *e;

    if (d) {
        while ((e = readdir(d)) != NULL) {
            if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
                continue;
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            unlink(path);
        }
        closedir(d);
    }
    rmdir(dir);
}

static int sp_remove(svc_store *st, const char *id)
{
    spool *sp = (spool *)st;
    char dir[1300], tomb[1300], jobs[1200];

    if (job_path(sp, dir, sizeof dir, id, "") != 0 ||
        snprintf(tomb, sizeof tomb, "%s/jobs/.del-%s", sp->dir, id) >=
            (int)sizeof tomb) {
        errno = ENAMETOOLONG;
        return -1;
    }
    snprintf(jobs, sizeof jobs, "%s/jobs", sp->dir);
    /* One atomic, durable step takes the job out of the spool: a rename
     * to a tombstone the recovery never reads, and the fsync of jobs/.
     * What fails here leaves the job whole; what is left after it is
     * garbage, removed now or at the next start. */
    if (rename(dir, tomb) != 0) {
        if (errno == ENOENT)
            return 0; /* already gone */
        note(sp, 0, 0);
        return -1;
    }
    if (srv_sync_dir(jobs) != 0) {
        note(sp, 0, 0);
        return -1;
    }
    remove_tree(tomb); /* a removal proves no room: no note() */
    return 0;
}

static int sp_quarantine(svc_store *st, const char *id)
{
    spool *sp = (spool *)st;
    char dir[1300], qdir[1200], dest[1400], jobs[1200];
    int k;

    if (job_path(sp, dir, sizeof dir, id, "") != 0 ||
        snprintf(qdir, sizeof qdir, "%s/quarantine", sp->dir) >= (int)sizeof qdir) {
        errno = ENAMETOOLONG;
        return -1;
    }
    if (mkdir(qdir, 0750) != 0 && errno != EEXIST)
        return -1;
    /* A name not taken yet: the same ID may be quarantined twice. */
    for (k = 0; k < 100; k++) {
        struct stat sb;
        snprintf(dest, sizeof dest, k ? "%s/%s.%d" : "%s/%s", qdir, id, k);
        if (lstat(dest, &sb) != 0)
            break;
    }
    snprintf(jobs, sizeof jobs, "%s/jobs", sp->dir);
    if (rename(dir, dest) != 0 || srv_sync_dir(jobs) != 0 || srv_sync_dir(qdir) != 0)
        return -1;
    srv_metrics_quarantined();
    return 0;
}

/* Removes the temporary files a crash left in a job directory. */
static void clean_tmp(spool *sp, const char *id)
{
    char dir[1300], path[1700];
    struct dirent *e;
    DIR *d;

    if (job_path(sp, dir, sizeof dir, id, "") != 0 || !(d = opendir(dir)))
        return;
    while ((e = readdir(d)) != NULL) {
        size_t n = strlen(e->d_name);
        if (n > 4 && strcmp(e->d_name + n - 4, ".tmp") == 0) {
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            unlink(path);
        }
    }
    closedir(d);
}

static size_t sp_usage(svc_store *st, const char *id)
{
    spool *sp = (spool *)st;
    char dir[1300], path[1700];
    size_t sum = 0;
    struct stat sb;
    struct dirent *e;
    DIR *d;

    if (job_path(sp, dir, sizeof dir, id, "") != 0 || !(d = opendir(dir)))
        return 0;
    while ((e = readdir(d)) != NULL) {
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (e->d_name[0] != '.' && stat(path, &sb) == 0 && S_ISREG(sb.st_mode))
            sum += (size_t)sb.st_size;
    }
    closedir(d);
    return sum;
}

static int sp_scan(svc_store *st, void (*fn)(const char *id, void *ctx),
                   void *ctx)
{
    spool *sp = (spool *)st;
    char jobs[1200];
    DIR *d;
    struct dirent *e;

    snprintf(jobs, sizeof jobs, "%s/jobs", sp->dir);
    d = opendir(jobs);
    if (!d)
        return -1;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        clean_tmp(sp, e->d_name); /* writes a crash interrupted */
        fn(e->d_name, ctx);
    }
    closedir(d);
    return 0;
}

/* ------------------------------------------------------------------ queue */

static int sp_push(svc_store *st, const char *id, int front)
{
    spool *sp = (spool *)st;
    qnode *q = calloc(1, sizeof *q);

    if (!q)
        return -1;
    snprintf(q->id, sizeof q->id, "%s", id);
    pthread_mutex_lock(&sp->q_mu);
    if (front) {
        q->next = sp->qhead;
        sp->qhead = q;
        if (!sp->qtail)
            sp->qtail = q;
    } else {
        if (sp->qtail)
            sp->qtail->next = q;
        else
            sp->qhead = q;
        sp->qtail = q;
    }
    pthread_mutex_unlock(&sp->q_mu);
    return 0;
}

static int sp_claim(svc_store *st, int (*fits)(void *ctx, const char *id),
                    void *ctx, char id[SVC_ID_LEN + 1])
{
    spool *sp = (spool *)st;
    qnode *q;

    pthread_mutex_lock(&sp->q_mu);
    q = sp->qhead;
    if (q && (!fits || fits(ctx, q->id))) {
        sp->qhead = q->next;
        if (!sp->qhead)
            sp->qtail = NULL;
    } else {
        q = NULL;
    }
    pthread_mutex_unlock(&sp->q_mu);
    if (!q)
        return 0;
    snprintf(id, SVC_ID_LEN + 1, "%s", q->id);
    free(q);
    return 1;
}

static int sp_drop(svc_store *st, const char *id)
{
    spool *sp = (spool *)st;
    qnode *q, *prev = NULL;

    pthread_mutex_lock(&sp->q_mu);
    for (q = sp->qhead; q && strcmp(q->id, id) != 0; prev = q, q = q->next)
        ;
    if (q) {
        if (prev)
            prev->next = q->next;
        else
            sp->qhead = q->next;
        if (sp->qtail == q)
            sp->qtail = prev;
    }
    pthread_mutex_unlock(&sp->q_mu);
    free(q);
    return 0;
}

/* A claim here ends with the process: nothing to acknowledge, no
 * heartbeat to send, no one elsewhere to tell of progress. */
static int sp_ack(svc_store *st, const char *id)
{
    (void)st;
    (void)id;
    return 0;
}

static int sp_heartbeat(svc_store *st, const char *id)
{
    return sp_ack(st, id);
}

static int sp_progress(svc_store *st, const char *id, const char *line,
                       size_t len)
{
    (void)line;
    (void)len;
    return sp_ack(st, id);
}

static int sp_follow(svc_store *st, const char *id, char *after,
                     void (*fn)(const char *line, size_t len, void *ctx),
                     void *ctx)
{
    (void)after;
    (void)fn;
    (void)ctx;
    return sp_ack(st, id);
}

static void sp_close(svc_store *st)
{
    spool *sp = (spool *)st;
    char id[SVC_ID_LEN + 1];

    while (sp_claim(st, NULL, NULL, id) == 1)
        ;
    pthread_mutex_destroy(&sp->health_mu);
    pthread_mutex_destroy(&sp->seq_mu);
    pthread_mutex_destroy(&sp->q_mu);
    free(sp);
}

static const svc_store_ops spool_ops = {
    "spool", sp_close, sp_ready,
    sp_create, sp_put, sp_get, sp_get_at, sp_stat, sp_open, sp_remove,
    sp_quarantine, sp_usage, sp_scan,
    sp_push, sp_claim, sp_ack, sp_drop,
    sp_heartbeat, sp_progress, sp_follow,
    NULL,                          /* a put per blob: a file each */
    NULL,                          /* no other replica to watch */
    0,                             /* only this process pushes */
    0,                             /* one process */
};

svc_store *store_spool_open(const char *dir, char *msg, size_t msgsize)
{
    spool *sp;

    if (spool_init(dir, msg, msgsize) != 0)
        return NULL;
    sp = calloc(1, sizeof *sp);
    if (!sp) {
        snprintf(msg, msgsize, "out of memory");
        return NULL;
    }
    sp->base.ops = &spool_ops;
    snprintf(sp->dir, sizeof sp->dir, "%s", dir);
    pthread_mutex_init(&sp->health_mu, NULL);
    pthread_mutex_init(&sp->seq_mu, NULL);
    pthread_mutex_init(&sp->q_mu, NULL);
    return &sp->base;
}
