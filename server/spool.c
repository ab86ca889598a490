/*
 * spool.c - the on-disk record of every accepted job.
 *
 * Layout: <spool>/jobs/<id>/{input, target, request.json, state.json,
 * result.<ext>, metrics.json}. A job exists once state.json exists; every
 * file is written to a temporary name, fsync()ed when it must survive a
 * crash, and renamed into place, so after kill -9 a file is either absent
 * or complete. The directory entries themselves are made durable by
 * fsync()ing the directory. Nothing here knows about HTTP or JSON.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include "srv.h"

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
    char path[1400], tmp[1420], dir[1300];
    const char *p = data;
    size_t done = 0;
    int fd, rc = -1;

    if (srv_spool_path(path, sizeof path, spool, id, name) != 0 ||
        srv_spool_path(dir, sizeof dir, spool, id, "") != 0)
        return -1;
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
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

void srv_spool_remove(const char *spool, const char *id)
{
    char dir[1300], path[1700];
    DIR *d;
    struct dirent *e;

    if (srv_spool_path(dir, sizeof dir, spool, id, "") != 0)
        return;
    d = opendir(dir);
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
