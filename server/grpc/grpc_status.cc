/* SPDX-License-Identifier: MIT */
/*
 * grpc_status.cc - the gRPC door's helpers (grpc_internal.h): statuses
 * from the service's errors (service.h's table, with `mcf-code` and
 * `retry-after-ms` in trailing metadata), the bearer token check, and the
 * conversions between the proto's messages and the service's (Params as
 * REST's params object, the Job from the service's snapshot).
 */
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "grpc_internal.h"
#include "h2gate.h"

namespace mcfd_grpc {

namespace {

const char *code_name(StatusCode c)
{
    static const char *const names[] = {
        "OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT", "DEADLINE_EXCEEDED",
        "NOT_FOUND", "ALREADY_EXISTS", "PERMISSION_DENIED",
        "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION", "ABORTED",
        "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL", "UNAVAILABLE",
        "DATA_LOSS", "UNAUTHENTICATED"};
    unsigned i = (unsigned)c;
    return i < sizeof names / sizeof names[0] ? names[i] : "UNKNOWN";
}


} // namespace

/* The status of e (service.h's table: its gRPC column), with its name
 * and retry delay in trailing metadata. */
Status status_from(CallbackServerContext *ctx, const svc_error &e)
{
    ctx->AddTrailingMetadata("mcf-code", svc_problem_name(e.problem));
    if (e.retry_after > 0)
        ctx->AddTrailingMetadata(
            "retry-after-ms", std::to_string((long long)(e.retry_after * 1000 + 0.5)));
    return Status((StatusCode)svc_problem_grpc(e.problem), e.detail);
}

/* A door-made error: problem p with the detail. */
Status door_status(CallbackServerContext *ctx, svc_problem p, const std::string &detail)
{
    svc_error e;
    svc_error_set(&e, p, "%s", detail.c_str());
    return status_from(ctx, e);
}

/* Counts the call in /metrics and returns st. */
Status counted(const char *method, const Status &st)
{
    srv_metrics_grpc(method, code_name(st.error_code()));
    return st;
}

/* The bearer token check of REST (srv_bearer_ok: constant time). */
bool authorized(CallbackServerContext *ctx)
{
    if (g.cfg->token_len == 0)
        return true;
    const auto &md = ctx->client_metadata();
    auto it = md.find("authorization");
    if (it == md.end())
        return false;
    std::string v(it->second.data(), it->second.size());
    return srv_bearer_ok(g.cfg, v.c_str());
}

Status unauthenticated(CallbackServerContext *ctx)
{
    return door_status(ctx, SVC_P_AUTH,
                       "metadata 'authorization: Bearer <token>' is required");
}

Status draining_status(CallbackServerContext *ctx)
{
    return door_status(ctx, SVC_P_DRAINING,
                       "the daemon is shutting down: no new jobs (retry on "
                       "another instance or after the restart)");
}

/* An upload that missed a deadline of the door (not the client's own). */
Status late_status(CallbackServerContext *ctx, const char *what, const char *flag,
                   double limit)
{
    char d[200];
    snprintf(d, sizeof d, "%s did not arrive within %s %g s of the call's start", what,
             flag, limit);
    return door_status(ctx, SVC_P_UPLOAD_TIMEOUT, d);
}

/* The parameters as the JSON object REST's `params` field takes (a tree,
 * never text): every set field under its own name (they are the REST
 * names), NumberOrAuto as the number or "auto", 64-bit integers as text
 * (exact). Walks the descriptor, so a new proto field needs no code here.
 * NULL when out of memory. */
cJSON *params_object(const pb::Params &p, const std::string *out_format)
{
    using google::protobuf::FieldDescriptor;
    std::vector<const FieldDescriptor *> fields;
    const google::protobuf::Reflection *r = p.GetReflection();
    cJSON *o = cJSON_CreateObject();

    if (!o)
        return nullptr;
    r->ListFields(p, &fields);
    for (const FieldDescriptor *f : fields) {
        const char *key = f->name().c_str();
        cJSON *v = nullptr;
        if (f->is_repeated()) {
            v = cJSON_CreateArray();
            for (int i = 0; v && i < r->FieldSize(p, f); i++)
                cJSON_AddItemToArray(v, cJSON_CreateNumber(r->GetRepeatedUInt32(p, f, i)));
        } else {
            switch (f->cpp_type()) {
            case FieldDescriptor::CPPTYPE_DOUBLE: v = cJSON_CreateNumber(r->GetDouble(p, f)); break;
            case FieldDescriptor::CPPTYPE_INT32: v = cJSON_CreateNumber(r->GetInt32(p, f)); break;
            case FieldDescriptor::CPPTYPE_UINT32: v = cJSON_CreateNumber(r->GetUInt32(p, f)); break;
            case FieldDescriptor::CPPTYPE_INT64:
                v = cJSON_CreateString(std::to_string(r->GetInt64(p, f)).c_str()); break;
            case FieldDescriptor::CPPTYPE_UINT64:
                v = cJSON_CreateString(std::to_string(r->GetUInt64(p, f)).c_str()); break;
            case FieldDescriptor::CPPTYPE_BOOL: v = cJSON_CreateBool(r->GetBool(p, f)); break;
            case FieldDescriptor::CPPTYPE_STRING: v = cJSON_CreateString(r->GetString(p, f).c_str()); break;
            case FieldDescriptor::CPPTYPE_MESSAGE: {
                const auto &n = static_cast<const pb::NumberOrAuto &>(r->GetMessage(p, f));
                if (n.has_number())
                    v = cJSON_CreateNumber(n.number());
                else if (n.has_auto_())
                    /* false is refused by the same path ("... got \"false\"") */
                    v = n.auto_() ? cJSON_CreateString("auto") : cJSON_CreateFalse();
                else
                    continue; /* an empty NumberOrAuto: unset */
                break;
            }
            default: continue;
            }
        }
        if (v)
            cJSON_AddItemToObject(o, key, v);
    }
    if (out_format)
        cJSON_AddStringToObject(o, "format", out_format->c_str());
    return o;
}

/* The Job message from the service's document of the job (svc_job_document:
 * the same snapshot REST's job document is made of). */
bool fill_job(svc_job *j, pb::Job *out)
{
    char t[40];
    svc_snap s;
    if (svc_job_document(j, &s) != 0)
        return false;
    out->set_id(s.id);
    out->set_status((pb::Job::Status)(s.status + 1));
    pb::Job::JobProgress *g2 = out->mutable_progress();
    g2->set_step(s.step);
    if (s.steps_planned > 0)
        g2->set_steps(s.steps_planned);
    if (s.step > 0) {
        g2->set_t(s.t);
        g2->set_dt(s.dt);
        /* unset without the job's step log (REST null) */
        if (std::isfinite(s.energy))
            g2->set_energy(s.energy);
        if (std::isfinite(s.volume))
            g2->set_volume(s.volume);
    }
    g2->set_fraction(s.fraction);
    g2->set_phase(s.phase);
    const double times[3] = {s.created, s.started, s.finished};
    std::string *fields[3] = {out->mutable_created(), out->mutable_started(),
                              out->mutable_finished()};
    for (int i = 0; i < 3; i++)
        if (times[i] > 0) {
            srv_time_rfc3339(times[i], t, sizeof t);
            *fields[i] = t;
        }
    out->set_cancel_requested(s.cancel_requested != 0);
    if (s.params)
        out->set_params(s.params);
    out->set_input_format(s.in_format);
    if (s.metrics)
        out->set_metrics(s.metrics);
    if (s.status == SVC_JOB_FAILED || s.status == SVC_JOB_CANCELED) {
        pb::Job::Error *e = out->mutable_error();
        e->set_code(svc_problem_name(s.error.problem));
        e->set_detail(s.error.detail);
        e->set_grpc_code((int)svc_problem_grpc(s.error.problem));
    }
    svc_snap_free(&s);
    return true;
}

/* The client's address: gRPC knows each connection by the inner end of
 * the gate's socketpair ("fd:12"), the gate knows whose it is. */
std::string client_address(CallbackServerContext *ctx)
{
    std::string peer = ctx->peer();
    char ip[64];
    if (peer.compare(0, 3, "fd:") == 0 && h2gate_peer(atoi(peer.c_str() + 3), ip, sizeof ip) == 0)
        return ip;
    return peer;
}

} // namespace mcfd_grpc
