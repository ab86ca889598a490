/* SPDX-License-Identifier: MIT */
/*
 * rstore_files.c - the large blobs of the Redis store in a directory the
 * replicas share (--blob-dir, rstore.h): a blob is written under a name
 * of its own (temp file, fsync, rename, fsync of the directory), and only
 * then is the name published in the job's hash by the same fenced script
 * that would have written the bytes; the sweep removes what no record
 * names (a stale runner's, replaced or expired jobs' files).
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "rstore_internal.h"
#include "srv.h"

#define PATH_LEN 1024             /* blob_dir (512) and a job's part */

static unsigned long counter;     /* names written by this process */

static int job_dir(const rstore *s, const char *id, char *p, size_t n)
{
    int w = snprintf(p, n, "%s/%s/%s", s->cfg.blob_dir, s->cfg.prefix, id);
    if (w < 0 || (size_t)w >= n) {
        errno = ENAMETOOLONG;
        return -1;
    }
    return 0;
}

int rstore__files_check(rstore *s, char *msg, size_t msgsize)
{
    char p[PATH_LEN + 64];
    int fd;

    snprintf(p, sizeof p, "%s/%s", s->cfg.blob_dir, s->cfg.prefix);
    if ((mkdir(p, 0755) != 0 && errno != EEXIST)) {
        snprintf(msg, msgsize, "--blob-dir %s: %s", s->cfg.blob_dir,
                 strerror(errno));
        return -1;
    }
    snprintf(p, sizeof p, "%s/%s/.probe.XXXXXX", s->cfg.blob_dir,
             s->cfg.prefix);
    if ((fd = mkstemp(p)) < 0) {
        snprintf(msg, msgsize, "--blob-dir %s: not writable: %s",
                 s->cfg.blob_dir, strerror(errno));
        return -1;
    }
    close(fd);
    unlink(p);
    return 0;
}

/* A failed write's files removed, and the job's directory when that
 * leaves it empty (a submission refused on a full disk leaves nothing;
 * a writer of the same job that made it meanwhile makes it again, as
 * after the sweep). -1, errno kept. */
static int gone(const char *dir, const char *tmp, const char *path)
{
    int e = errno;

    if (tmp)
        unlink(tmp);
    if (path)
        unlink(path);
    rmdir(dir);
    errno = e;
    return -1;
}

/* The blob's bytes in a file of its own; its name (relative to the
 * directory) in ref. 0, or -1 and errno (ENOSPC: disk full), nothing
 * left behind. */
int rstore__file_write(rstore *s, const char *id, const char *name,
                       const void *data, size_t len, char *ref,
                       size_t refsize)
{
    char dir[PATH_LEN], path[PATH_LEN + 128], tmp[PATH_LEN + 160];
    struct timespec ts;
    unsigned long c = __atomic_add_fetch(&counter, 1, __ATOMIC_RELAXED);
    int fd, e;

    if (job_dir(s, id, dir, sizeof dir) != 0)
        return -1;
    if (mkdir(dir, 0755) != 0 && errno != EEXIST)
        return -1;
    clock_gettime(CLOCK_REALTIME, &ts);
    /* unique across replicas: the consumer's hash, the time, a count */
    {
        unsigned long h = 5381;
        const char *q;
        for (q = s->cfg.consumer; *q; q++)
            h = h * 33 + (unsigned char)*q;
        snprintf(ref, refsize, "%s/%s/%s.%08lx%lx%lx%lx", s->cfg.prefix, id,
                 name, h & 0xffffffffUL, (unsigned long)ts.tv_sec,
                 (unsigned long)ts.tv_nsec, c);
    }
    snprintf(path, sizeof path, "%s/%s", s->cfg.blob_dir, ref);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0 && errno == ENOENT &&      /* a sweep took the empty dir */
        (mkdir(dir, 0755) == 0 || errno == EEXIST))
        fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0)
        return gone(dir, NULL, NULL);
    if (srv_write_all(fd, data, len) != 0 || fsync(fd) != 0) {
        e = errno;
        close(fd);
        errno = e;
        return gone(dir, tmp, NULL);
    }
    if (close(fd) != 0 || rename(tmp, path) != 0 || srv_sync_dir(dir) != 0)
        return gone(dir, tmp, path);
    return 0;
}

void rstore__file_unlink(rstore *s, const char *ref)
{
    char path[PATH_LEN + 128];

    snprintf(path, sizeof path, "%s/%s", s->cfg.blob_dir, ref);
    unlink(path);
}

/* An open descriptor of the file ref names (its size checked), or -1
 * and errno (ENOENT: removed, the job gone or the blob replaced). */
int rstore__file_open(rstore *s, const char *ref, size_t size)
{
    char path[PATH_LEN + 128];
    struct stat st;
    int fd;

    if (strstr(ref, "..") || ref[0] == '/') {
        errno = EIO;             /* not a name this store wrote */
        return -1;
    }
    snprintf(path, sizeof path, "%s/%s", s->cfg.blob_dir, ref);
    if ((fd = open(path, O_RDONLY | O_CLOEXEC)) < 0)
        return -1;
    if (fstat(fd, &st) != 0 || (size_t)st.st_size != size) {
        close(fd);
        errno = EIO;
        return -1;
    }
    return fd;
}

int rstore__file_read(int fd, size_t off, char *buf, size_t len)
{
    while (len > 0) {
        ssize_t r = pread(fd, buf, len, (off_t)off);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0) {
            errno = EIO;
            return -1;
        }
        buf += r;
        off += (size_t)r;
        len -= (size_t)r;
    }
    return 0;
}

/* ------------------------------------------------------------ the sweep */

/* The file names the record of id publishes ("f:" fields), in one
 * malloc'ed reply; NULL with *gone set when the job has no record. */
static redisReply *refs_of(rstore *s, const char *id, int *gone)
{
    job_keys k;
    const char *argv[2] = {"HGETALL", NULL};
    redisReply *r;

    *gone = 0;
    rstore__keys(s, id, &k);
    argv[1] = k.hash;
    if (!(r = rstore__cmd(s, 0, 2, argv)))
        return NULL;
    if (r->type != REDIS_REPLY_ARRAY) {
        rds_reply_free(r);
        errno = EIO;
        return NULL;
    }
    if (r->elements == 0) {
        rds_reply_free(r);
        *gone = 1;
        return NULL;
    }
    return r;
}

static int referenced(const redisReply *h, const char *ref)
{
    size_t i;

    for (i = 0; h && i + 1 < h->elements; i += 2)
        if (h->element[i]->type == REDIS_REPLY_STRING &&
            strncmp(h->element[i]->str, "f:", 2) == 0 &&
            h->element[i + 1]->type == REDIS_REPLY_STRING &&
            strcmp(h->element[i + 1]->str, ref) == 0)
            return 1;
    return 0;
}

/* One job's directory: the files no record names and older than the
 * grace (a write whose script has not run yet is younger) go; the
 * directory too when empty. The files removed, or -1. */
static int sweep_job(rstore *s, const char *id, time_t now)
{
    char dir[PATH_LEN], path[PATH_LEN + 300], ref[KEY_MAX + 300];
    redisReply *h;
    DIR *d;
    struct dirent *de;
    int gone, n = 0;

    if (!rstore__name_ok(id) || job_dir(s, id, dir, sizeof dir) != 0)
        return 0;
    h = refs_of(s, id, &gone);
    if (!h && !gone)
        return -1;                 /* Redis down: keep everything */
    if (!(d = opendir(dir))) {
        rds_reply_free(h);
        return 0;
    }
    while ((de = readdir(d))) {
        struct stat st;

        if (de->d_name[0] == '.')
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
        snprintf(ref, sizeof ref, "%s/%s/%s", s->cfg.prefix, id, de->d_name);
        if (lstat(path, &st) != 0 || !S_ISREG(st.st_mode) ||
            referenced(h, ref) ||
            difftime(now, st.st_mtime) < s->cfg.blob_grace)
            continue;
        if (unlink(path) == 0)
            n++;
    }
    closedir(d);
    rds_reply_free(h);
    (void)rmdir(dir);              /* fails while files are left: fine */
    return n;
}

int rstore_sweep(rstore *s)
{
    char top[PATH_LEN + 64];
    DIR *d;
    struct dirent *de;
    time_t now = time(NULL);
    int n = 0, k;

    if (!s->cfg.blob_dir[0])
        return 0;
    snprintf(top, sizeof top, "%s/%s", s->cfg.blob_dir, s->cfg.prefix);
    if (!(d = opendir(top)))
        return -1;
    while ((de = readdir(d))) {
        if (de->d_name[0] == '.')
            continue;
        if ((k = sweep_job(s, de->d_name, now)) < 0) {
            n = -1;
            break;
        }
        n += k;
    }
    closedir(d);
    return n;
}

/* The job's directory and every file in it (rstore_remove). */
void rstore__files_remove(rstore *s, const char *id)
{
    char dir[PATH_LEN], path[PATH_LEN + 300];
    DIR *d;
    struct dirent *de;

    if (!s->cfg.blob_dir[0] || job_dir(s, id, dir, sizeof dir) != 0 ||
        !(d = opendir(dir)))
        return;
    while ((de = readdir(d))) {
        if (strcmp(de->d_name, ".") == 0 || strcmp(de->d_name, "..") == 0)
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
        unlink(path);
    }
    closedir(d);
    rmdir(dir);
}
