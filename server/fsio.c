/* SPDX-License-Identifier: MIT */
/*
 * fsio.c - the two file primitives every durable write in mcfd is made of:
 * a whole buffer written through EINTR and short writes, and a directory
 * fsync()ed so a rename into it survives a crash. The spool, the Redis
 * store's blob files and the sandbox's pipe share them.
 */
#include <errno.h>
#include <fcntl.h>
#include <unistd.h>
#include "srv.h"

int srv_write_all(int fd, const void *data, size_t len)
{
    const char *p = data;

    while (len > 0) {
        ssize_t w = write(fd, p, len);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        p += w;
        len -= (size_t)w;
    }
    return 0;
}

int srv_sync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    int rc;

    if (fd < 0)
        return -1;
    rc = fsync(fd);
    close(fd);
    return rc;
}
