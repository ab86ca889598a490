/* SPDX-License-Identifier: MIT */
/*
 * svc_table.c - the job service's table of jobs by ID and the workers'
 * wake-up, under the service lock. A leaf of the service: the files that
 * add, find or remove a job (service.c, recovery.c, svc_shared.c,
 * workers.c) and those that make work claimable (svc_job.c, workers.c)
 * call it; it calls nothing of theirs but the reference drop of a job it
 * removes (svc_ref.c).
 */
#include <stdint.h>
#include <string.h>

#include "svc_internal.h"

static unsigned bucket_of(const char *id)
{
    uint32_t h = 2166136261u;
    for (; *id; id++)
        h = (h ^ (unsigned char)*id) * 16777619u;
    return h % SVC_NBUCKETS;
}

svc_job *svc__find_locked(svc_t *s, const char *id)
{
    svc_job *j;
    for (j = s->buckets[bucket_of(id)]; j; j = j->hnext)
        if (strcmp(j->id, id) == 0)
            return j;
    return NULL;
}

void svc__table_insert(svc_t *s, svc_job *j)
{
    unsigned b = bucket_of(j->id);
    j->hnext = s->buckets[b];
    s->buckets[b] = j;
    j->in_table = 1;
    s->njobs++;
    s->disk_bytes += j->disk_bytes;
}

/* Removes j from the table and drops the table's reference. */
void svc__table_remove(svc_t *s, svc_job *j)
{
    svc_job **pp = &s->buckets[bucket_of(j->id)];
    while (*pp && *pp != j)
        pp = &(*pp)->hnext;
    if (*pp) {
        *pp = j->hnext;
        j->in_table = 0;
        s->njobs--;
        s->disk_bytes -= j->disk_bytes;
        svc__unref_locked(j);
    }
}

/* Wakes the workers. */
void svc__wake_locked(svc_t *s)
{
    s->wakes++;
    pthread_cond_broadcast(&s->work);
}
