/*
 * spool.c - the on-disk record of every accepted job.
 *
 * Layout: <spool>/jobs/<id>/{input, target, request.json, state.json,
 * result.<ext>, metrics.json, events.ndjson, events.idx}. A job exists
 * once state.json exists; every file is written to a temporary name,
 * fsync()ed when it must survive a crash, and renamed into place, so
 * after kill -9 a file is either absent or complete. The directory
 * entries themselves are made durable by fsync()ing the directory.
 * Nothing here knows about HTTP or JSON.
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

/* What the spool's own writes found, for readiness: whether a write
 * failed with no write as large succeeding since (pending), its size and
 * errno. A removal or a small state.json after a failed result proves
 * nothing about room for the next job: only a write of at least the
 * failed size clears it (a job's, or the probe's of srv_spool_ready). */
static pthread_mutex_t g_health_mu = PTHREAD_MUTEX_INITIALIZER;
static int g_pending, g_fail_errno;
static size_t g_fail_bytes;
static double g_probed;      /* srv_mono() of the last job-sized probe */
static int g_probe_errno;    /* its outcome: 0 or errno */

static void remove_tree(const char *dir);

static void note(int ok, size_t bytes)
{
    int e = errno;
    pthread_mutex_lock(&g_health_mu);
    if (!ok) {
        if (!g_pending || bytes > g_fail_bytes)
            g_fail_bytes = bytes;
        g_pending = 1;
        g_fail_errno = e;
    } else if (bytes >= g_fail_bytes) {
        g_pending = 0;
        g_fail_bytes = 0;
    }
    pthread_mutex_unlock(&g_health_mu);
    errno = e;
}

static int fsync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY);
    int rc;

    if (fd < 0)
        return -1;
    rc = fsync(fd);
    close(fd);
    return rc;
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

int srv_spool_init(const char *dir, char *msg, size_t msgsize)
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
    /* Removals a crash interrupted: their tombstones (see srv_spool_remove). */
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

int srv_spool_ready(const char *spool, char *why, size_t size)
{
    char probe[1300];
    size_t need;
    int pending, e;

    /* Can a file be made now? (Cheap: no fsync, removed at once.) */
    snprintf(probe, sizeof probe, "%s/jobs/.ready-probe", spool);
    if (write_zeros(probe, 1) != 0) {
        snprintf(why, size, "the spool %s is not writable: %s", spool,
                 strerror(errno));
        return -1;
    }
    /* After a failed write, ready only once a write as large succeeds: a
     * probe of that size (up to SRV_SPOOL_PROBE_MAX), at most twice a
     * second whoever asks, until a job's own write does it. */
    pthread_mutex_lock(&g_health_mu);
    pending = g_pending;
    need = g_fail_bytes < SRV_SPOOL_PROBE_MAX ? g_fail_bytes
                                              : SRV_SPOOL_PROBE_MAX;
    e = g_fail_errno;
    if (pending && srv_mono() - g_probed >= 0.5) {
        g_probed = srv_mono();
        g_probe_errno = write_zeros(probe, need) == 0 ? 0 : errno;
        if (g_probe_errno == 0) {
            g_pending = 0;
            g_fail_bytes = 0;
        }
    }
    if (g_pending && g_probe_errno)
        e = g_probe_errno;
    pending = g_pending;
    pthread_mutex_unlock(&g_health_mu);
    if (pending) {
        snprintf(why, size, "a write of %zu bytes to the spool %s failed: %s",
                 need, spool, strerror(e));
        return -1;
    }
    return 0;
}

int srv_spool_path(char *buf, size_t size, const char *spool, const char *id,
                   const char *name)
{
    int n = snprintf(buf, size, "%s/jobs/%s%s%s", spool, id,
                     name[0] ? "/" : "", name);
    return (n < 0 || (size_t)n >= size) ? -1 : 0;
}

int srv_spool_mkjob(const char *spool, const char *id)
{
    char dir[1300], jobs[1200];

    if (srv_spool_path(dir, sizeof dir, spool, id, "") != 0)
        return -1;
    if (mkdir(dir, 0750) != 0 && errno != EEXIST)
        return -1;
    snprintf(jobs, sizeof jobs, "%s/jobs", spool);
    return fsync_dir(jobs);
}

int srv_spool_write(const char *spool, const char *id, const char *name,
                    const void *data, size_t len, int durable)
{
    char path[1400], tmp[1440], dir[1300];
    const char *p = data;
    size_t done = 0;
    int fd, rc = -1;

    if (srv_spool_path(path, sizeof path, spool, id, name) != 0 ||
        srv_spool_path(dir, sizeof dir, spool, id, "") != 0)
        return -1;
    {
        /* Each writer its own temporary file: two writers of one name
         * must never rename each other's half-written bytes. */
        static unsigned long seq;
        static pthread_mutex_t seq_mu = PTHREAD_MUTEX_INITIALIZER;
        unsigned long k;
        pthread_mutex_lock(&seq_mu);
        k = ++seq;
        pthread_mutex_unlock(&seq_mu);
        snprintf(tmp, sizeof tmp, "%s.%lu.tmp", path, k);
    }
    fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC, 0640);
    if (fd < 0)
        return -1;
    while (done < len) {
        ssize_t w = write(fd, p + done, len - done);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            goto fail;
        }
        done += (size_t)w;
    }
    if (durable && fsync(fd) != 0)
        goto fail;
    if (close(fd) != 0) {
        fd = -1;
        goto fail;
    }
    fd = -1;
    if (rename(tmp, path) != 0)
        goto fail;
    if (durable && fsync_dir(dir) != 0)
        goto fail;
    rc = 0;
fail:
    if (fd >= 0)
        close(fd);
    if (rc != 0)
        unlink(tmp);
    note(rc == 0, len);
    return rc;
}

int srv_spool_read(const char *spool, const char *id, const char *name,
                   char **data, size_t *len)
{
    char path[1400];
    struct stat st;
    char *buf = NULL;
    size_t done = 0;
    int fd;

    if (srv_spool_path(path, sizeof path, spool, id, name) != 0)
        return -1;
    fd = open(path, O_RDONLY);
    if (fd < 0)
        return -1;
    if (fstat(fd, &st) != 0 || st.st_size < 0)
        goto fail;
    buf = malloc((size_t)st.st_size + 1);
    if (!buf)
        goto fail;
    while (done < (size_t)st.st_size) {
        ssize_t r = read(fd, buf + done, (size_t)st.st_size - done);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            goto fail;
        done += (size_t)r;
    }
    close(fd);
    buf[done] = '\0';
    *data = buf;
    *len = done;
    return 0;
fail:
    free(buf);
    close(fd);
    return -1;
}

int srv_spool_read_at(const char *spool, const char *id, const char *name,
                      size_t off, void *buf, size_t len)
{
    char path[1400];
    size_t done = 0;
    int fd, e = 0;

    if (srv_spool_path(path, sizeof path, spool, id, name) != 0 ||
        (fd = open(path, O_RDONLY)) < 0)
        return -1;
    while (done < len && !e) {
        ssize_t r = pread(fd, (char *)buf + done, len - done,
                          (off_t)(off + done));
        if (r < 0 && errno != EINTR)
            e = errno;
        else if (r == 0)
            e = EIO; /* shorter than its index says */
        else if (r > 0)
            done += (size_t)r;
    }
    close(fd);
    errno = e;
    return e ? -1 : 0;
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

int srv_spool_remove(const char *spool, const char *id)
{
    char dir[1300], tomb[1300], jobs[1200];

    if (srv_spool_path(dir, sizeof dir, spool, id, "") != 0 ||
        snprintf(tomb, sizeof tomb, "%s/jobs/.del-%s", spool, id) >=
            (int)sizeof tomb) {
        errno = ENAMETOOLONG;
        return -1;
    }
    snprintf(jobs, sizeof jobs, "%s/jobs", spool);
    /* One atomic, durable step takes the job out of the spool: a rename
     * to a tombstone the recovery never reads, and the fsync of jobs/.
     * What fails here leaves the job whole; what is left after it is
     * garbage, removed now or at the next start. */
    if (rename(dir, tomb) != 0) {
        if (errno == ENOENT)
            return 0; /* already gone */
        note(0, 0);
        return -1;
    }
    if (fsync_dir(jobs) != 0) {
        note(0, 0);
        return -1;
    }
    remove_tree(tomb); /* a removal proves no room: no note() */
    return 0;
}

int srv_spool_quarantine(const char *spool, const char *id)
{
    char dir[1300], qdir[1200], dest[1400], jobs[1200];
    int k;

    if (srv_spool_path(dir, sizeof dir, spool, id, "") != 0 ||
        snprintf(qdir, sizeof qdir, "%s/quarantine", spool) >= (int)sizeof qdir) {
        errno = ENAMETOOLONG;
        return -1;
    }
    if (mkdir(qdir, 0750) != 0 && errno != EEXIST)
        return -1;
    /* A name not taken yet: the same ID may be quarantined twice. */
    for (k = 0; k < 100; k++) {
        struct stat st;
        snprintf(dest, sizeof dest, k ? "%s/%s.%d" : "%s/%s", qdir, id, k);
        if (lstat(dest, &st) != 0)
            break;
    }
    snprintf(jobs, sizeof jobs, "%s/jobs", spool);
    if (rename(dir, dest) != 0 || fsync_dir(jobs) != 0 || fsync_dir(qdir) != 0)
        return -1;
    srv_metrics_quarantined();
    return 0;
}

void srv_spool_clean_tmp(const char *spool, const char *id)
{
    char dir[1300], path[1700];
    struct dirent *e;
    DIR *d;

    if (srv_spool_path(dir, sizeof dir, spool, id, "") != 0 ||
        !(d = opendir(dir)))
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

size_t srv_spool_du(const char *spool, const char *id)
{
    char dir[1300], path[1700];
    size_t sum = 0;
    struct stat st;
    struct dirent *e;
    DIR *d;

    if (srv_spool_path(dir, sizeof dir, spool, id, "") != 0 ||
        !(d = opendir(dir)))
        return 0;
    while ((e = readdir(d)) != NULL) {
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (e->d_name[0] != '.' && stat(path, &st) == 0 && S_ISREG(st.st_mode))
            sum += (size_t)st.st_size;
    }
    closedir(d);
    return sum;
}

int srv_spool_list(const char *spool, void (*fn)(const char *id, void *ctx),
                   void *ctx)
{
    char jobs[1200];
    DIR *d;
    struct dirent *e;

    snprintf(jobs, sizeof jobs, "%s/jobs", spool);
    d = opendir(jobs);
    if (!d)
        return -1;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        fn(e->d_name, ctx);
    }
    closedir(d);
    return 0;
}
