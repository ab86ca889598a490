/* SPDX-License-Identifier: MIT */
/*
 * problem.h - the one table of client-visible errors of mcfd, shared by
 * the job service (service.h: a failure is a row of it) and both doors,
 * which map a row to their transport from its columns and nothing else.
 * Each row gives the symbolic name clients see (REST's problem+json
 * "code", gRPC's `mcf-code` trailer), the service code (svc_code: what
 * kind of failure, transport-neutral, persisted with a job's error), the
 * mcf_status it stands for (when it came from the core or the codecs),
 * the HTTP status and the gRPC status. Eight rows only a door raises
 * (AUTH, METHOD, URI_LIMIT, UPLOAD_TIMEOUT, FRAMING, NOT_IMPLEMENTED,
 * BUSY_ADDRESS, UNHEALTHY). Rows and codes are only ever appended: their
 * numbers and names are on the wire and in stored jobs.
 *
 * The columns are read through svc_problem_* (service/svc_error.c), at
 * any time from any thread.
 */
#ifndef SRV_PROBLEM_H
#define SRV_PROBLEM_H

#include "api.h"  /* mcf_status */

/* The kinds of failure (transport-neutral), persisted with a job's error
 * as its "kind". */
#define SVC_CODES(X)                                                   \
    X(OK,        "success")                                           \
    X(EPARAMS,   "invalid parameters")                                \
    X(EINPUT,    "the input mesh is refused")                         \
    X(EMESH,     "the mesh cannot be smoothed with these parameters") \
    X(ENOMEM,    "out of memory")                                     \
    X(EBUSY,     "the job queue is full")                             \
    X(EQUOTA,    "the spool is full")                                 \
    X(EDRAINING, "the service is shutting down")                      \
    X(ENOTFOUND, "no such job")                                       \
    X(ENOTREADY, "the job has not finished")                          \
    X(ENORESULT, "the job has no result")                             \
    X(ECANCELED, "the job was canceled")                              \
    X(ETIMEOUT,  "the job ran out of time")                           \
    X(ESTORAGE,  "the spool failed")                                  \
    X(EINTERNAL, "internal error")                                    \
    X(EAUTH,     "a valid token is required")                         \
    X(EMETHOD,   "the method is not allowed on this resource")        \
    X(EUNAVAILABLE, "the daemon cannot serve now")

typedef enum {
#define X(name, text) SVC_##name,
    SVC_CODES(X)
#undef X
} svc_code;

/* gRPC's status codes (grpc/status.h's numbers, fixed by the protocol),
 * for the table below; the gRPC door casts them to its StatusCode. */
typedef enum {
    SVC_GRPC_OK = 0, SVC_GRPC_CANCELLED = 1, SVC_GRPC_INVALID_ARGUMENT = 3,
    SVC_GRPC_DEADLINE_EXCEEDED = 4, SVC_GRPC_NOT_FOUND = 5,
    SVC_GRPC_RESOURCE_EXHAUSTED = 8, SVC_GRPC_FAILED_PRECONDITION = 9,
    SVC_GRPC_UNIMPLEMENTED = 12, SVC_GRPC_INTERNAL = 13,
    SVC_GRPC_UNAVAILABLE = 14, SVC_GRPC_UNAUTHENTICATED = 16
} svc_grpc_status;

/* Every client-visible error, one row each: its identifier, the name
 * clients see, the service code, the mcf status it stands for (OK: none),
 * the HTTP status, the gRPC status, and what it means. A failure of the
 * core or a codec at a stage is the row of (the stage's code, its status):
 * parameters EPARAMS, the bytes EINPUT, the run EMESH. Appended only. */
#define SVC_PROBLEMS(X)                                                              \
    X(OK,             "OK",         OK,        OK,         200, OK,                  \
      "success")                                                                    \
    /* the parameters: the request's fault */                                      \
    X(PARAM_INVALID,  "EINVAL",     EPARAMS,   EINVAL,     400, INVALID_ARGUMENT,    \
      "a parameter is invalid (named in the detail)")                               \
    X(PARAM_LIMIT,    "ELIMIT",     EPARAMS,   ELIMIT,     400, INVALID_ARGUMENT,    \
      "the parameters alone exceed a limit")                                        \
    X(PARAM_DECODE,   "EDECODE",    EPARAMS,   EDECODE,    400, INVALID_ARGUMENT,    \
      "the parameters do not parse")                                                \
    /* the request's bytes */                                                       \
    X(INPUT_INVALID,  "EINVAL",     EINPUT,    EINVAL,     400, INVALID_ARGUMENT,    \
      "the request's body is not what it must be")                                  \
    X(INPUT_DECODE,   "EDECODE",    EINPUT,    EDECODE,    400, INVALID_ARGUMENT,    \
      "the bytes do not parse")                                                     \
    X(INPUT_FORMAT,   "EFORMAT",    EINPUT,    EFORMAT,    415, INVALID_ARGUMENT,    \
      "not a format the service reads")                                             \
    X(INPUT_LIMIT,    "ELIMIT",     EINPUT,    ELIMIT,     413, RESOURCE_EXHAUSTED,  \
      "the input is over a size limit")                                             \
    X(INPUT_MESH,     "EMESH",      EINPUT,    EMESH,      422, INVALID_ARGUMENT,    \
      "the bytes hold a malformed mesh")                                            \
    /* this mesh with these parameters */                                           \
    X(MESH_INVALID,   "EINVAL",     EMESH,     EINVAL,     422, INVALID_ARGUMENT,    \
      "these parameters do not suit this mesh")                                     \
    X(MESH_LIMIT,     "ELIMIT",     EMESH,     ELIMIT,     422, RESOURCE_EXHAUSTED,  \
      "the job exceeds a budget (steps, work, memory, decode)")                     \
    X(MESH,           "EMESH",      EMESH,     EMESH,      422, INVALID_ARGUMENT,    \
      "the mesh is malformed")                                                      \
    X(MESH_NOTPOSDEF, "ENOTPOSDEF", EMESH,     ENOTPOSDEF, 422, INVALID_ARGUMENT,    \
      "the system matrix is not positive definite")                                 \
    X(MESH_NUMERIC,   "ENUMERIC",   EMESH,     ENUMERIC,   422, INVALID_ARGUMENT,    \
      "the flow failed numerically")                                                \
    X(MESH_NOCONV,    "ENOCONV",    EMESH,     ENOCONV,    422, INVALID_ARGUMENT,    \
      "an iteration did not converge")                                              \
    X(MESH_DECODE,    "EDECODE",    EMESH,     EDECODE,    400, INVALID_ARGUMENT,    \
      "the bytes do not parse")                                                     \
    X(MESH_FORMAT,    "EFORMAT",    EMESH,     EFORMAT,    415, INVALID_ARGUMENT,    \
      "not a format the service writes")                                            \
    /* the service */                                                               \
    X(NOMEM,          "ENOMEM",     ENOMEM,    ENOMEM,     503, RESOURCE_EXHAUSTED,  \
      "out of memory: retry after the delay")                                       \
    X(BUSY,           "EBUSY",      EBUSY,     OK,         503, RESOURCE_EXHAUSTED,  \
      "no room now (queue, memory, streams): retry after the delay")                \
    X(SPOOL_FULL,     "ESPOOLFULL", EQUOTA,    OK,         503, RESOURCE_EXHAUSTED,  \
      "the spool's quota or disk is full: retry after the delay")                   \
    X(DRAINING,       "EDRAINING",  EDRAINING, OK,         503, UNAVAILABLE,         \
      "shutting down; a job it interrupted runs again after the restart")           \
    X(NOT_FOUND,      "ENOTFOUND",  ENOTFOUND, OK,         404, NOT_FOUND,           \
      "no such job or resource")                                                    \
    X(NOT_READY,      "ENOTREADY",  ENOTREADY, OK,         409, FAILED_PRECONDITION, \
      "the job is queued or running: no result yet")                                \
    X(NO_RESULT,      "ENORESULT",  ENORESULT, OK,         409, FAILED_PRECONDITION, \
      "the job failed or was canceled: no result")                                  \
    X(CANCELED,       "ECANCELED",  ECANCELED, OK,         409, CANCELLED,           \
      "canceled by a user, or because its only client left")                        \
    X(TIMEOUT,        "ELIMIT",     ETIMEOUT,  OK,         422, DEADLINE_EXCEEDED,   \
      "the job ran longer than --job-timeout")                                      \
    X(STORAGE,        "EIO",        ESTORAGE,  OK,         500, INTERNAL,            \
      "the spool could not be read or written")                                     \
    X(INTERNAL_IO,    "EIO",        EINTERNAL, EIO,        500, INTERNAL,            \
      "an input/output error")                                                      \
    X(INTERNAL,       "EINTERNAL",  EINTERNAL, OK,         500, INTERNAL,            \
      "internal error")                                                             \
    /* the doors' own */                                                            \
    X(AUTH,           "EAUTH",      EAUTH,     OK,         401, UNAUTHENTICATED,     \
      "a valid bearer token is required")                                           \
    X(METHOD,         "EMETHOD",    EMETHOD,   OK,         405, UNIMPLEMENTED,       \
      "the method is not allowed on this resource")                                 \
    X(URI_LIMIT,      "ELIMIT",     EPARAMS,   OK,         414, INVALID_ARGUMENT,    \
      "the query string is too long")                                               \
    X(UPLOAD_TIMEOUT, "ETIMEOUT",   ETIMEOUT,  OK,         408, DEADLINE_EXCEEDED,   \
      "the upload did not arrive in time")                                          \
    X(UNHEALTHY,      "EUNHEALTHY", EUNAVAILABLE, OK,      503, UNAVAILABLE,         \
      "a door cannot take connections")                                             \
    X(SPOOL_UNREADY,  "ESPOOL",     EUNAVAILABLE, OK,      503, UNAVAILABLE,         \
      "the spool cannot be written")                                                \
    X(FRAMING,        "EFRAMING",   EPARAMS,   OK,         400, INVALID_ARGUMENT,    \
      "the request's body cannot be framed without doubt")                          \
    X(NOT_IMPLEMENTED, "ENOTIMPLEMENTED", EPARAMS, OK,     501, UNIMPLEMENTED,       \
      "the request uses a feature the daemon does not implement")                   \
    X(BUSY_ADDRESS,   "EBUSY",      EBUSY,     OK,         503, RESOURCE_EXHAUSTED,  \
      "this address has too many connections open")

typedef enum {
#define X(id, name, code, mcf, http, grpc, text) SVC_P_##id,
    SVC_PROBLEMS(X)
#undef X
    SVC_P_COUNT
} svc_problem;

/* A row's columns (an unknown row reads as INTERNAL's). */
const char *svc_problem_name(svc_problem p);     /* "EINVAL", "EBUSY" */
svc_code svc_problem_code(svc_problem p);
mcf_status svc_problem_mcf(svc_problem p);
unsigned svc_problem_http(svc_problem p);
svc_grpc_status svc_problem_grpc(svc_problem p);
const char *svc_problem_text(svc_problem p);

/* "EPARAMS" for SVC_EPARAMS, "" when unknown. */
const char *svc_code_name(svc_code c);

#endif /* SRV_PROBLEM_H */
