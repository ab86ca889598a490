/* SPDX-License-Identifier: MIT */
/*
 * rds_pool.c - connections to one Redis server for many threads (rds.h):
 * n connections made up front (each connects at its first command), lent
 * one to a thread at a time; one that reaches the server ends the others'
 * backoff.
 */
#include <pthread.h>
#include <stdlib.h>

#include "rds.h"

struct rds_pool {
    pthread_mutex_t mu;
    pthread_cond_t freed;
    rds **all;                 /* n connections */
    rds **idle;                /* the ones not lent: a stack */
    int n, nidle;
};

rds_pool *rds_pool_new(const rds_config *cfg, int n)
{
    rds_pool *p = calloc(1, sizeof *p);
    int i;

    if (!p || n < 1 || !(p->all = calloc((size_t)n, sizeof *p->all)) ||
        !(p->idle = calloc((size_t)n, sizeof *p->idle))) {
        if (p)
            free(p->all);
        free(p);
        return NULL;
    }
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->freed, NULL);
    for (i = 0; i < n; i++) {
        if (!(p->all[i] = rds_new(cfg))) {
            rds_pool_free(p);
            return NULL;
        }
        p->idle[p->nidle++] = p->all[i];
        p->n = i + 1;
    }
    return p;
}

void rds_pool_free(rds_pool *p)
{
    int i;

    if (!p)
        return;
    for (i = 0; i < p->n; i++)
        rds_free(p->all[i]);
    free(p->all);
    free(p->idle);
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->freed);
    free(p);
}

rds *rds_pool_get(rds_pool *p)
{
    rds *c;

    pthread_mutex_lock(&p->mu);
    while (p->nidle == 0)
        pthread_cond_wait(&p->freed, &p->mu);
    c = p->idle[--p->nidle];
    pthread_mutex_unlock(&p->mu);
    return c;
}

void rds_pool_put(rds_pool *p, rds *c)
{
    int i;

    if (!c)
        return;
    pthread_mutex_lock(&p->mu);
    if (rds_connected(c))
        for (i = 0; i < p->nidle; i++)
            rds_retry_now(p->idle[i]);
    p->idle[p->nidle++] = c;
    pthread_cond_signal(&p->freed);
    pthread_mutex_unlock(&p->mu);
}
