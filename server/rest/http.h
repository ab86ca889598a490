/* SPDX-License-Identifier: MIT */
/*
 * http.h - the REST door's router (http.c): the callbacks rest_door.c
 * gives libmicrohttpd, and the connection bookkeeping it runs from its
 * loop. Only rest_door.c and http.c include it: the door's other files
 * are called by the router and never call it back (rest_internal.h).
 */
#ifndef SRV_HTTP_H
#define SRV_HTTP_H

#include "rest_internal.h"

/* http.c's callbacks, which rest_door.c gives MHD (cls: the door). */
enum MHD_Result rest_http_handle(void *cls, struct MHD_Connection *c,
                                 const char *url, const char *method,
                                 const char *version, const char *upload_data,
                                 size_t *upload_data_size, void **con_cls);
void *rest_http_uri_log(void *cls, const char *uri, struct MHD_Connection *c);
void rest_http_completed(void *cls, struct MHD_Connection *c, void **con_cls,
                         enum MHD_RequestTerminationCode toe);
/* MHD_OPTION_NOTIFY_CONNECTION: tracks connections for the header
 * deadline and counts them per client address: one opened past
 * --max-connections-per-ip has its request answered 503 EBUSY with
 * Retry-After and closed, or is closed after 2 s without one. Releases a
 * request MHD never completed. */
void rest_http_connection(void *cls, struct MHD_Connection *c,
                          void **socket_context,
                          enum MHD_ConnectionNotificationCode code);
/* Closes the connections that have waited longer than timeout seconds
 * for a complete request head (request line and headers), since they
 * opened or since their last answer, and uploads older than timeout that
 * averaged under 4 KiB/s since their head: slowloris clients. With nine
 * tenths of max_connections open the timeout is 2 s at most (timeout 0:
 * none). Also uploads whose body is still arriving body_timeout seconds
 * after their head (--body-timeout; 0: none). And, whatever the timeouts,
 * connections past --max-connections-per-ip with no request head after
 * 2 s. Returns how many. */
int rest_http_expire_heads(rest_t *d, double timeout, int max_connections,
                           double body_timeout);
/* libmicrohttpd's own per-address limit (MHD_OPTION_PER_IP_CONNECTION_LIMIT),
 * a backstop a quarter above --max-connections-per-ip (0: none): the
 * connections between the two are the ones answered 503; past it MHD
 * closes a connection at accept, before any request, without a word. */
unsigned rest_http_ip_backstop(const srv_config *cfg);

#endif /* SRV_HTTP_H */
