/* SPDX-License-Identifier: MIT */
/*
 * waiter.c - connections of the REST door that wait on a job: the
 * service's subscription callback resumes them, and the main thread's
 * poll finds the ones whose client hung up.
 *
 * A waiting request or stream suspends its MHD connection; the service
 * calls on_notify (under its lock) when the job moves, which resumes it.
 * wait_mu, the door's lock, guards every waiter's flags and the list of all
 * of them; it is taken inside the service's lock (the callback), so the
 * door never calls the service while holding it. A suspended connection
 * is left alone by MHD until it is resumed, which needs wait_mu: under it
 * a suspended waiter's socket is valid, and may be peeked at.
 *
 * No notification is lost: rest_waiter_arm clears `pending` before the
 * caller reads its snapshot, the callback sets it, and rest_waiter_sleep
 * suspends only while it is still clear (else the caller looks again).
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "rest_internal.h"

/* The service's callback: service lock held. */
static void on_notify(void *ctx, unsigned what)
{
    rest_waiter *w = ctx;

    (void)what;
    pthread_mutex_lock(&w->door->wait_mu);
    w->pending = 1;
    if (w->suspended) {
        w->suspended = 0;
        MHD_resume_connection(w->conn);
    }
    pthread_mutex_unlock(&w->door->wait_mu);
}

int rest_waiter_start(rest_waiter *w, rest_t *d, svc_job *j,
                      struct MHD_Connection *c, int want_events,
                      int cancel_on_hangup)
{
    memset(w, 0, sizeof *w);
    w->door = d;
    w->conn = c;
    snprintf(w->id, sizeof w->id, "%s", svc_job_id(j));
    w->want_events = want_events;
    w->cancel_on_hangup = cancel_on_hangup;
    pthread_mutex_lock(&d->wait_mu);
    w->next = d->waiters;
    if (d->waiters)
        d->waiters->prev = w;
    d->waiters = w;
    w->linked = 1;
    d->followers += want_events != 0;
    pthread_mutex_unlock(&d->wait_mu);
    if (svc_subscribe(j, want_events ? SVC_NOTIFY_PROGRESS : SVC_NOTIFY_STATE,
                      on_notify, w, &w->sub) != 0) {
        rest_waiter_stop(w);
        return -1;
    }
    return 0;
}

void rest_waiter_stop(rest_waiter *w)
{
    rest_t *d = w->door;

    /* First the subscription: on_notify is not running on return. */
    svc_unsubscribe(w->sub);
    w->sub = NULL;
    if (!d)
        return; /* never started */
    pthread_mutex_lock(&d->wait_mu);
    if (w->linked) {
        if (w->prev)
            w->prev->next = w->next;
        else
            d->waiters = w->next;
        if (w->next)
            w->next->prev = w->prev;
        w->prev = w->next = NULL;
        w->linked = 0;
        d->followers -= w->want_events != 0;
    }
    pthread_mutex_unlock(&d->wait_mu);
}

void rest_waiter_arm(rest_waiter *w)
{
    pthread_mutex_lock(&w->door->wait_mu);
    w->pending = 0;
    pthread_mutex_unlock(&w->door->wait_mu);
}

int rest_waiter_sleep(rest_waiter *w)
{
    int slept = 0;

    pthread_mutex_lock(&w->door->wait_mu);
    if (!w->pending && !w->gone) {
        w->suspended = 1;
        MHD_suspend_connection(w->conn);
        slept = 1;
    }
    pthread_mutex_unlock(&w->door->wait_mu);
    return slept;
}

void rest_waiter_retry(rest_waiter *w)
{
    pthread_mutex_lock(&w->door->wait_mu);
    w->retry = 1;
    pthread_mutex_unlock(&w->door->wait_mu);
}

int rest_waiter_gone(rest_waiter *w)
{
    int gone;
    pthread_mutex_lock(&w->door->wait_mu);
    gone = w->gone;
    pthread_mutex_unlock(&w->door->wait_mu);
    return gone;
}

int rest_waiter_followers(rest_t *d)
{
    int n;
    pthread_mutex_lock(&d->wait_mu);
    n = d->followers;
    pthread_mutex_unlock(&d->wait_mu);
    return n;
}

/* Whether the peer of a suspended connection has closed it: a peek finds
 * the end of the stream or an error. A pipelined request (bytes waiting)
 * is a client still there. A client that half-closes its side after the
 * request counts as gone, as in most servers. */
static int client_gone(struct MHD_Connection *c)
{
    const union MHD_ConnectionInfo *ci =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
    char b;
    ssize_t n;

    if (!ci || ci->connect_fd == MHD_INVALID_SOCKET)
        return 0;
    n = recv(ci->connect_fd, &b, 1, MSG_PEEK | MSG_DONTWAIT);
    return n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK &&
                      errno != EINTR);
}

int rest_http_check_clients(rest_t *d)
{
    char (*ids)[SVC_ID_LEN + 1] = NULL;
    int n = 0, cap = 0, i, canceled = 0;
    rest_waiter *w;

    pthread_mutex_lock(&d->wait_mu);
    for (w = d->waiters; w; w = w->next) {
        if (!w->suspended)
            continue;
        if (w->want_events) {
            /* An event stream whose client left: resumed to end
             * (stream.c), which frees its connection now, not when the
             * job moves. */
            if (!w->gone && client_gone(w->conn))
                w->gone = 1;
            /* or one to read the store again (rest_waiter_retry) */
            if (w->gone || w->retry) {
                w->retry = 0;
                w->suspended = 0;
                MHD_resume_connection(w->conn);
            }
            continue;
        }
        if (!w->cancel_on_hangup || !client_gone(w->conn))
            continue;
        if (n == cap) {
            int ncap = cap ? 2 * cap : 16;
            void *p = realloc(ids, (size_t)ncap * sizeof *ids);
            if (!p)
                break; /* the next check tries again */
            ids = p;
            cap = ncap;
        }
        memcpy(ids[n++], w->id, sizeof *ids);
    }
    pthread_mutex_unlock(&d->wait_mu);
    /* Outside wait_mu: the service calls back into it. A job already
     * canceled or finished is left as it is. */
    for (i = 0; i < n; i++) {
        svc_job *j = svc_job_get(d->svc, ids[i]);
        if (j && svc_cancel(j, SVC_CANCEL_CLIENT) != 0)
            canceled++;
        svc_job_unref(j);
    }
    free(ids);
    return canceled;
}
