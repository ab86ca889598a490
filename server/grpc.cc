/*
 * grpc.cc - the gRPC door of mcfd: api/mcfd.proto's mcfd.v1.Smoother on
 * gRPC's C++ callback API, a bridge from the transport to the job service
 * (service.h) behind the plain C interface of grpc_door.h. The only C++
 * in server/, as api_draco.cc is in api/; everything it decides about jobs
 * it asks the service, everything about parameters, formats and metrics
 * it asks api/ through the service, so both doors give the same answers.
 *
 * Calls
 *   Smooth      ServerBidiReactor: reads the header and the chunks (limits
 *               enforced as bytes arrive, before any decode), submits on
 *               the client's half-close, then follows the job (Follow).
 *   SubmitJob   ServerReadReactor: the same upload; answers with the Job.
 *   WatchJob    ServerWriteReactor: follows an existing job (Follow).
 *   GetJob, CancelJob, ListSchemes   unary, answered at once.
 *
 * Threads. gRPC's own threads run the reactions (OnReadDone, OnWriteDone,
 * OnCancel, OnDone). The service calls a follower's notify function from
 * a worker with the service lock held; it may not call the service, so it
 * only marks the follower dirty and, when no write is in flight, posts it
 * to the door's one pump thread. The pump (on that thread, or right in
 * OnWriteDone) reads a snapshot and the new events and starts the next
 * write: one write in flight per stream, never more. Lock order: service
 * lock, then a follower's mu, then the pump queue's lock. A call may be
 * ended at once by a reaction, the pump and the main thread (expire): its
 * context's trailing metadata is only added under the call's mu and
 * before its Finish (finish_error, end_error), never after.
 *
 * Errors are the service's svc_error, mapped to status codes by the table
 * of service.h; the message is REST's detail; trailing metadata `mcf-code`
 * carries the symbolic name and `retry-after-ms` the delay of a transient
 * refusal (full queue, quota, drain).
 */
#include <atomic>
#include <cerrno>
#include <cstdarg>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include <grpc/compression.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/resource_quota.h>
#include <grpcpp/server_posix.h>

#include "mcfd.grpc.pb.h"

extern "C" {
#include "srv.h" /* plain C headers without extern "C" guards */
#include "service.h"
}
#include "grpc_door.h"
#include "h2gate.h"

/* ThreadSanitizer cannot see how gRPC orders the reactions of one call
 * (its completion queue hands them between its threads through absl's
 * futex mutexes and atomics in uninstrumented libraries), so every field a
 * reaction reads after an earlier one wrote it on another thread would be
 * reported. The door tells it the one rule gRPC guarantees: an operation
 * started (StartRead, StartWrite, Finish, the reactor's creation) happens
 * before the reactions that follow it, and OnDone after all of them
 * (Order below). Nothing else is annotated: the pump thread, the notify
 * callback and the main thread still synchronize only through our locks
 * and atomics, which TSan checks. */
#if defined(__SANITIZE_THREAD__)
#define MCF_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define MCF_TSAN 1
#endif
#endif
#ifdef MCF_TSAN
#include <sanitizer/tsan_interface.h>
#define HB_RELEASE(p) __tsan_release((void *)(p))
#define HB_ACQUIRE(p) __tsan_acquire((void *)(p))
#else
#define HB_RELEASE(p) ((void)(p))
#define HB_ACQUIRE(p) ((void)(p))
#endif

namespace pb = mcfd::v1;
using grpc::CallbackServerContext;
using grpc::Status;
using grpc::StatusCode;

namespace {

/* ----------------------------------------------------------------- state */

const char kService[] = "mcfd.v1.Smoother";
const size_t kChunk = 64 * 1024;   /* chunk size, both ways */

/* The gate's bounds on streams (h2gate.h; measured: README, reliability).
 * gRPC 1.51 holds about 12 KiB per stream it has accepted, so the door's
 * streams cost at most about kMaxStreams x 12 KiB. */
const int kStreamsPerConn = 100;   /* MAX_CONCURRENT_STREAMS, advertised */
const int kMaxStreams = 1024;      /* in the door at once */
const int kMaxStreamsPerIp = 256;  /* ... from one address */
/* gRPC 1.51 disposed of about 15,000 client-reset streams a second on one
 * core of the test machine; the gate assumes a fifteenth of that */
const double kResetsPerS = 1000;
/* a header block: twice gRPC's 8 KiB metadata limit, in at most 16
 * frames; gRPC's HPACK parser then copies at most 16 x 16 KiB per block */
const size_t kMaxHeaderBlock = 16 * 1024;
const int kMaxHeaderFrames = 16;
/* gRPC's resource quota, a backstop behind the gate: 1.51 charges each
 * call's arena and the transports' buffers to it and, past it, cancels
 * streams at random (chttp2_transport.cc, destructive_reclaimer_locked:
 * RESOURCE_EXHAUSTED "Buffers full"). The gate's bounds keep the door far
 * below it (about 15 MiB at its caps). Threads: those of gRPC's sync
 * server (the health service); the callback calls run on gRPC's executor. */
const size_t kQuotaBytes = 64 * 1024 * 1024;
const int kQuotaThreads = 16;

struct Door {
    std::unique_ptr<grpc::Server> server;
    const srv_config *cfg = nullptr;
    svc_t *svc = nullptr;
    std::atomic<bool> draining{false};
    std::atomic<int> active{0};
    /* streaming calls held now, in all and by client address (Slot) */
    std::mutex smu;
    int streams = 0;
    std::map<std::string, int> per_peer;
    /* uploads still being received (the door's expire) */
    std::mutex umu;
    std::set<std::shared_ptr<struct Deadline>> uploads;
    /* answers being streamed (the door's expire: stalled writes) */
    std::set<std::shared_ptr<struct Stall>> answers;
    /* the pump thread and its queue of followers to look at */
    std::mutex qmu;
    std::condition_variable qcv;
    std::deque<class Follow *> queue;
    bool quit = false;
    std::thread pump;
};
Door g;

/* --------------------------------------------------------------- helpers */

/* In a reaction (or a reactor's constructor): what gRPC ordered before it
 * is visible, and what it did is ordered before the next one (TSan only;
 * see HB_RELEASE above). */
struct Order {
    explicit Order(const void *call) : call_(call) { HB_ACQUIRE(call_); }
    ~Order() { HB_RELEASE(call_); }
    const void *call_;
};

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
        g2->set_energy(s.energy);
        g2->set_volume(s.volume);
    }
    g2->set_fraction(s.fraction);
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

/* ---------------------------------------------------------------- upload */

/* The bytes of Smooth and SubmitJob as they stream in: the header first,
 * then mesh and target chunks, every size checked before it is kept. */
/* A streaming call's place in the door. REST bounds what clients hold by
 * connections (--max-connections, --max-connections-per-ip); over gRPC
 * one connection carries any number of calls, so the same two numbers
 * bound the streaming calls (Smooth, SubmitJob, WatchJob) open at once, in
 * all and from one address: each upload may buffer up to --max-upload,
 * each follower is woken on every step. Beyond them a call ends with
 * RESOURCE_EXHAUSTED (EBUSY) before it reads a message. */
class Slot {
  public:
    ~Slot()
    {
        if (!held_)
            return;
        std::lock_guard<std::mutex> l(g.smu);
        auto it = g.per_peer.find(peer_);
        if (it != g.per_peer.end() && --it->second <= 0)
            g.per_peer.erase(it);
        g.streams--;
    }

    /* true when taken; else false and st says why. */
    bool take(CallbackServerContext *ctx, Status *st)
    {
        const srv_config *cfg = g.cfg;
        std::string peer = client_address(ctx);
        std::lock_guard<std::mutex> l(g.smu);
        int here = g.per_peer.count(peer) ? g.per_peer[peer] : 0;
        char d[200];
        if (cfg->max_connections > 0 && g.streams >= cfg->max_connections)
            snprintf(d, sizeof d, "%d streaming calls are open, the most this daemon "
                     "keeps (--max-connections %d)", g.streams, cfg->max_connections);
        else if (cfg->max_connections_per_ip > 0 && here >= cfg->max_connections_per_ip)
            snprintf(d, sizeof d, "%d streaming calls are open from your address, the "
                     "most one address may hold (--max-connections-per-ip %d)", here,
                     cfg->max_connections_per_ip);
        else {
            g.per_peer[peer] = here + 1;
            g.streams++;
            peer_ = peer;
            held_ = true;
            return true;
        }
        *st = door_status(ctx, SVC_P_BUSY, d);
        return false;
    }

  private:
    bool held_ = false;
    std::string peer_;
};

/* Whether an upload (Smooth, SubmitJob) may start reading: the token, a
 * slot, and not draining, in that order. OK, or the status to end with. */
Status admit_upload(CallbackServerContext *ctx, Slot *slot)
{
    Status st;
    if (!authorized(ctx))
        return unauthenticated(ctx);
    if (!slot->take(ctx, &st))
        return st;
    if (g.draining || svc_draining(g.svc))
        return draining_status(ctx);
    return Status::OK;
}

/* An upload call (Smooth, SubmitJob) the main thread may end when its
 * upload is late. */
class Expirable {
  public:
    /* Ends the call with DEADLINE_EXCEEDED: what was late and its limit. */
    virtual void expire(const char *what, const char *flag, double limit) = 0;

  protected:
    ~Expirable() = default;
};

/* An upload's deadlines, shared by its call and the door's expire on
 * the main thread. The call may end, and be deleted, on a gRPC thread at
 * any time, so the main thread reaches it only through this record, under
 * mu and while alive; the call clears alive (disarm) at the latest in its
 * OnDone. mu is recursive: ending the call may run its reactions, which
 * disarm it, on the same thread. */
struct Deadline {
    std::recursive_mutex mu;
    Expirable *call = nullptr;     /* valid while alive */
    bool alive = true;
    std::atomic<bool> have_header{false};
    double started = 0;            /* srv_mono() at the call's start */
};

class Upload {
  public:
    ~Upload()
    {
        disarm();
        free(mesh_);
        free(target_);
        svc_upload_release(g.svc, &mem_held_);
        svc_request_free(&rq_);
    }

    /* One message as it came, parsed here: gRPC's own parse failure ends
     * a read as the client's half-close does (OnReadDone(false)), so a
     * corrupt message in the middle of an upload would pass for its end
     * and the bytes before it would be submitted as the mesh (a job was
     * made from a truncated mesh). Clears b. false and *e when the call
     * must end. */
    bool feed(grpc::ByteBuffer *b, svc_error *e)
    {
        nmsg_++;
        Status ps = grpc::SerializationTraits<pb::SmoothRequest>::Deserialize(b, &req_);
        if (!ps.ok())
            return fail(e, SVC_P_PARAM_INVALID, "message %ld of the upload is not a "
                        "SmoothRequest (its bytes do not parse as one): the upload is "
                        "refused, nothing is submitted", nmsg_);
        return feed(req_, e);
    }

    /* One parsed message; false and *e when the call must end. */
    bool feed(const pb::SmoothRequest &m, svc_error *e)
    {
        switch (m.part_case()) {
        case pb::SmoothRequest::kHeader:
            if (have_header_)
                return fail(e, SVC_P_PARAM_INVALID, "a second header: the header is sent once, first");
            have_header_ = true;
            if (dl_)
                dl_->have_header = true;
            return header(m.header(), e);
        case pb::SmoothRequest::kChunk:
        case pb::SmoothRequest::kTargetChunk: {
            bool t = m.part_case() == pb::SmoothRequest::kTargetChunk;
            const std::string &b = t ? m.target_chunk() : m.chunk();
            if (!have_header_)
                return fail(e, SVC_P_PARAM_INVALID, "the first message must be the header");
            if (b.size() > kChunk)
                return limit(e, "a %s of %zu bytes is over the %zu-byte chunk limit",
                             t ? "target_chunk" : "chunk", b.size(), kChunk);
            return append(t ? &target_ : &mesh_, t ? &target_len_ : &mesh_len_,
                          t ? target_size_ : total_size_, b, t ? "target mesh" : "mesh", e);
        }
        default:
            return fail(e, SVC_P_PARAM_INVALID, "an empty message (no part set)");
        }
    }

    /* After the client's half-close: the upload is whole. Submits it
     * (keep_result: the encoded result is kept for this call). */
    int submit(bool keep_result, svc_job **out, svc_error *e)
    {
        if (!have_header_)
            return fail(e, SVC_P_PARAM_INVALID, "no header: the first message must be the header") ? 0 : -1;
        if (mesh_len_ == 0)
            return fail(e, SVC_P_INPUT_DECODE, "no mesh: send its bytes in chunk messages") ? 0 : -1;
        if (total_size_ >= 0 && (long long)mesh_len_ != total_size_)
            return fail(e, SVC_P_INPUT_INVALID, "total_size is %lld but %zu bytes came",
                        total_size_, mesh_len_) ? 0 : -1;
        if (target_size_ >= 0 && (long long)target_len_ != target_size_)
            return fail(e, SVC_P_INPUT_INVALID, "target_size is %lld but %zu bytes came",
                        target_size_, target_len_) ? 0 : -1;
        if (in_format_ != API_FMT_UNKNOWN) {
            api_format got = api_format_detect(mesh_, mesh_len_);
            if (got != in_format_)
                return fail(e, SVC_P_INPUT_FORMAT, "format is %s but the bytes are %s",
                            api_format_name(in_format_),
                            got == API_FMT_UNKNOWN ? "of no known format" : api_format_name(got)) ? 0 : -1;
        }
        srv_metrics_upload(mesh_len_);
        rq_.input = mesh_;
        rq_.input_len = mesh_len_;
        rq_.target = target_;
        rq_.target_len = target_ ? target_len_ : 0;
        rq_.keep_result = keep_result;
        mesh_ = target_ = nullptr;
        int rc = svc_submit(g.svc, &rq_, out, e);
        svc_upload_release(g.svc, &mem_held_);   /* the bytes are in the store, or gone */
        return rc;
    }

    /* The upload's deadlines start now: --header-timeout for the header,
     * --body-timeout for the whole upload (the door's expire). */
    void arm(Expirable *call)
    {
        dl_ = std::make_shared<Deadline>();
        dl_->call = call;
        dl_->started = srv_mono();
        std::lock_guard<std::mutex> l(g.umu);
        g.uploads.insert(dl_);
    }

    /* The upload is whole, or the call ends: no deadline from now on.
     * Never with a lock held that expire() takes. */
    void disarm()
    {
        if (!dl_)
            return;
        {
            std::lock_guard<std::mutex> l(g.umu);
            g.uploads.erase(dl_);
        }
        {
            std::lock_guard<std::recursive_mutex> l(dl_->mu);
            dl_->alive = false;
        }
        dl_.reset();
    }

  private:
    static svc_request request_init()
    {
        svc_request rq;
        svc_request_init(&rq);
        return rq;
    }

    bool header(const pb::SmoothHeader &h, svc_error *e)
    {
        const api_limits *lim = &g.cfg->lim;
        std::string of;
        cJSON *po;
        if (h.has_format()) {
            in_format_ = api_format_from_name(h.format().c_str());
            if (in_format_ == API_FMT_UNKNOWN || h.format().find('.') != std::string::npos)
                return fail(e, SVC_P_PARAM_INVALID, "format must be one of obj, draco, ply, stl, off, got \"%.64s\"",
                            h.format().c_str());
        }
        if (h.has_total_size()) {
            if (h.total_size() > lim->max_input_bytes)
                return limit(e, "total_size %llu is over the upload limit of %zu bytes (--max-upload)",
                             (unsigned long long)h.total_size(), lim->max_input_bytes);
            total_size_ = (long long)h.total_size();
        }
        if (h.has_target_size()) {
            if (h.target_size() > lim->max_input_bytes)
                return limit(e, "target_size %llu is over the upload limit of %zu bytes (--max-upload)",
                             (unsigned long long)h.target_size(), lim->max_input_bytes);
            target_size_ = (long long)h.target_size();
        }
        /* REST's early 503: no room now, so no reason to take the bytes */
        if (!svc_can_accept(g.svc)) {
            svc_gauges gg = svc_get_gauges(g.svc);
            if (gg.draining)
                svc_error_set(e, SVC_P_DRAINING, "the daemon is shutting down and accepts no new jobs");
            else
                svc_error_set(e, SVC_P_BUSY, "the job queue is full (%d queued, %d workers busy, --queue %d)",
                              gg.queue_depth, gg.workers_busy, gg.queue_capacity);
            return false;
        }
        /* the memory the upload will take, reserved by its declared sizes
         * (without them, as the bytes come: append) */
        size_t declared = (size_t)(total_size_ > 0 ? total_size_ : 0) +
                          (size_t)(target_size_ > 0 ? target_size_ : 0);
        if (declared > 0 && svc_upload_reserve(g.svc, &mem_held_, declared, e) != 0)
            return false;
        if (h.has_output_format())
            of = h.output_format();
        if (!(po = params_object(h.params(), h.has_output_format() ? &of : nullptr)))
            return fail(e, SVC_P_NOMEM, "out of memory");
        if (h.has_filename())
            snprintf(rq_.filename, sizeof rq_.filename, "%s", basename_of(h.filename()).c_str());
        /* The parameters now, before any byte of the mesh, parsed once into
         * the job's: the path REST's params field takes, so the same
         * message names the field. */
        mcf_error err;
        mcf_status rc = api_params_set_json(&rq_.params, po, lim, &err);
        cJSON_Delete(po);
        if (rc != MCF_OK) {
            svc_error_from_mcf(e, rc, API_JOB_PARAMS, NULL, &err);
            return false;
        }
        return true;
    }

    static std::string basename_of(const std::string &n)
    {
        size_t k = n.find_last_of("/\\");
        std::string b = k == std::string::npos ? n : n.substr(k + 1);
        std::string s;
        for (char c : b)
            if ((unsigned char)c >= 0x20 && c != 0x7f && c != '"')
                s += c;
        return s.empty() ? "mesh" : s;
    }

    bool append(char **buf, size_t *len, long long declared, const std::string &b,
                const char *what, svc_error *e)
    {
        size_t max = g.cfg->lim.max_input_bytes;
        if (b.size() > max - *len)
            return limit(e, "the %s is over the upload limit of %zu bytes (--max-upload)", what, max);
        if (declared >= 0 && (long long)(*len + b.size()) > declared)
            return fail(e, SVC_P_INPUT_INVALID, "more bytes of the %s than its declared size %lld",
                        what, declared);
        if (svc_upload_reserve(g.svc, &mem_held_, mesh_len_ + target_len_ + b.size(), e) != 0)
            return false;
        if (*len + b.size() > alloc_of(buf)) {
            /* geometric growth as bytes arrive, never ahead of them: a
             * declared size is only checked, so a header alone cannot
             * make the daemon reserve --max-upload bytes */
            size_t want = alloc_of(buf) ? alloc_of(buf) * 2 : 256 * 1024;
            while (want < *len + b.size())
                want *= 2;
            if (want > max)
                want = max;
            char *nb = (char *)realloc(*buf, want);
            if (!nb)
                return fail(e, SVC_P_NOMEM, "out of memory for the %s", what);
            *buf = nb;
            alloc_of(buf) = want;
        }
        memcpy(*buf + *len, b.data(), b.size());
        *len += b.size();
        return true;
    }

    size_t &alloc_of(char **buf) { return buf == &mesh_ ? mesh_alloc_ : target_alloc_; }

    static bool fail(svc_error *e, svc_problem p, const char *fmt, ...)
#if defined(__GNUC__)
        __attribute__((format(printf, 3, 4)))
#endif
    {
        va_list ap;
        char d[sizeof e->detail];
        va_start(ap, fmt);
        vsnprintf(d, sizeof d, fmt, ap);
        va_end(ap);
        svc_error_set(e, p, "%s", d);
        return false;
    }

    /* A limit: EINPUT with mcf ELIMIT, RESOURCE_EXHAUSTED. */
    static bool limit(svc_error *e, const char *fmt, ...)
#if defined(__GNUC__)
        __attribute__((format(printf, 2, 3)))
#endif
    {
        va_list ap;
        mcf_error err;
        va_start(ap, fmt);
        vsnprintf(err.msg, sizeof err.msg, fmt, ap);
        va_end(ap);
        err.status = MCF_ELIMIT;
        svc_error_from_mcf(e, MCF_ELIMIT, API_JOB_DECODE, NULL, &err);
        return false;
    }

    bool have_header_ = false;
    long nmsg_ = 0;                 /* messages received */
    pb::SmoothRequest req_;
    svc_request rq_ = request_init();
    api_format in_format_ = API_FMT_UNKNOWN;
    long long total_size_ = -1, target_size_ = -1;
    char *mesh_ = nullptr, *target_ = nullptr;
    size_t mesh_len_ = 0, target_len_ = 0, mesh_alloc_ = 0, target_alloc_ = 0;
    size_t mem_held_ = 0;           /* svc_upload_reserve */
    std::shared_ptr<Deadline> dl_;
};

/* ---------------------------------------------------------------- follow */

void post(Follow *f);

/* A streamed answer's write in flight, shared by its call and the door's expire
 * on the main thread, as Deadline is: reached under mu while alive (the
 * call clears it in OnDone); mu is recursive because cancelling may run the
 * call's reactions on the same thread. */
struct Stall {
    std::recursive_mutex mu;
    CallbackServerContext *ctx = nullptr;   /* valid while alive */
    bool alive = true;
    std::atomic<double> since{0};  /* srv_mono() when the write started, 0: none */
};

/* What Smooth and WatchJob share: a job followed to its end, written one
 * message at a time. Subclasses give the transport's StartWrite and
 * Finish. Reference counted: gRPC's reference (dropped in OnDone) and one
 * per post to the pump queue. */
class Follow {
  public:
    virtual ~Follow()
    {
        if (job_) {
            if (keep_ && !taken_)
                svc_job_release_result(job_);
            svc_job_unref(job_);
        }
        free(result_);
        g.active--;
    }

    void ref() { refs_++; }
    /* Taken off the pump queue (a later notify may post it again). */
    void dequeued()
    {
        std::lock_guard<std::mutex> l(mu_);
        queued_ = false;
    }
    void unref()
    {
        if (--refs_ == 0)
            delete this;
    }

    /* The service's notify function (service lock held: no service call). */
    static void notify(void *ctx, unsigned what)
    {
        (void)what;
        Follow *f = static_cast<Follow *>(ctx);
        bool p = false;
        {
            std::lock_guard<std::mutex> l(f->mu_);
            f->dirty_ = true;
            if (!f->writing_ && !f->busy_ && !f->queued_ && !f->finished_) {
                f->queued_ = true;
                p = true;
            }
        }
        if (p)
            post(f);
    }

    /* Writes the next message, or finishes, or waits for a notify. Never
     * with the service lock held (it calls the service). */
    void pump()
    {
        {
            std::lock_guard<std::mutex> l(mu_);
            if (writing_ || busy_ || finished_ || !job_)
                return;
            busy_ = true;
            dirty_ = false;
        }
        for (;;) {
            Status st;
            int r = next(&st);
            std::lock_guard<std::mutex> l(mu_);
            if (r > 0) {            /* out_ is ready */
                writing_ = true;
                busy_ = false;
                if (finished_)      /* cancelled meanwhile */
                    return;
                /* Under mu_, so that no Finish can slip between the check
                 * and the write. Safe: gRPC 1.51 never runs a reaction
                 * inline from StartWrite or Finish (their tags dispatch
                 * OnWriteDone and OnDone to its executor). */
                stall_->since = srv_mono();
                start_write(&out_);
                return;
            }
            if (r < 0) {            /* the end */
                busy_ = false;
                if (!finished_)
                    finish_locked(end_err_ ? status_from(ctx_, *end_err_) : st);
                return;
            }
            if (!dirty_) {          /* nothing new: wait for a notify */
                busy_ = false;
                return;
            }
            dirty_ = false;
        }
    }

  protected:
    Follow(CallbackServerContext *ctx, const char *method) : ctx_(ctx), method_(method)
    {
        g.active++;
        stall_ = std::make_shared<Stall>();
        stall_->ctx = ctx;
        std::lock_guard<std::mutex> l(g.umu);
        g.answers.insert(stall_);
    }

    /* Starts following j (a reference the follower now owns). */
    void follow(svc_job *j, bool keep, int from_step, bool skip_result, bool no_wait)
    {
        bool gone;
        {
            std::lock_guard<std::mutex> l(mu_);
            job_ = j;
            keep_ = keep;
            from_step_ = from_step;
            skip_result_ = skip_result;
            no_wait_ = no_wait;
            gone = gone_;
        }
        if (gone) {     /* cancelled between the submission and now */
            if (owns_job_)
                svc_cancel(j, SVC_CANCEL_CLIENT);
            return;
        }
        if (svc_subscribe(j, SVC_NOTIFY_STATE | SVC_NOTIFY_PROGRESS, notify, this, &sub_) != 0) {
            svc_error e;
            svc_error_set(&e, SVC_P_NOMEM, "out of memory");
            finish_error(e);
            return;
        }
        pump();
    }

    void write_done(bool ok)
    {
        {
            std::lock_guard<std::mutex> l(mu_);
            writing_ = false;
            stall_->since = 0;
            if (!ok) {              /* the stream broke: the client left */
                finish_locked(Status(StatusCode::CANCELLED, "the client left"));
                return;
            }
        }
        pump();
    }

    /* The call was cancelled by the client or its deadline; a job the
     * call owns (Smooth's) is cancelled with it. */
    void cancelled()
    {
        svc_job *j;
        {
            std::lock_guard<std::mutex> l(mu_);
            j = job_;
            gone_ = true;
        }
        if (j && owns_job_) {
            svc_snap s;
            svc_job_snapshot(j, &s);
            if (!svc_job_status_terminal(s.status))
                svc_cancel(j, SVC_CANCEL_CLIENT);
        }
        finish(ctx_->deadline() <= std::chrono::system_clock::now()
                   ? Status(StatusCode::DEADLINE_EXCEEDED, "deadline exceeded")
                   : Status(StatusCode::CANCELLED, "cancelled by the client"));
    }

    /* From OnDone: no notify after this, then gRPC's reference goes. */
    void done()
    {
        {
            std::lock_guard<std::mutex> l(g.umu);
            g.answers.erase(stall_);
        }
        {
            std::lock_guard<std::recursive_mutex> l(stall_->mu);
            stall_->alive = false;
        }
        svc_unsubscribe(sub_);
        sub_ = nullptr;
        unref();
    }

    void finish(const Status &st)
    {
        std::lock_guard<std::mutex> l(mu_);
        finish_locked(st);
    }

    /* Ends with e's status. Its trailing metadata is added under mu_ and
     * only while not finished: after Finish the context is gRPC's (it
     * sends the trailers), and a reaction, the pump and the main thread
     * (expire) may end the call at once. */
    void finish_error(const svc_error &e)
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!finished_)
            finish_locked(status_from(ctx_, e));
    }

    void finish_locked(const Status &st)
    {
        if (finished_)
            return;
        finished_ = true;
        /* a call that is gone is counted as it ended for its client */
        counted(method_, st);
        finish_call(st);
    }

    /* Plain writes: gRPC's buffer hint would hold a write's OnWriteDone
     * until something flushes it (measured: a finished job's WatchJob took
     * 209 ms instead of 1.9). */
    virtual void start_write(const pb::SmoothResponse *m) = 0;
    virtual void finish_call(const Status &st) = 0;

    CallbackServerContext *ctx_;
    bool owns_job_ = false;         /* Smooth: the job is this call's alone */
    Slot slot_;                     /* its place among the streaming calls */
    bool finished_ = false;         /* under mu_ */
    std::mutex mu_;

  private:
    /* The next message into out_: 1; nothing to send now: 0; the end:
     * -1 and *st, or -1 and an error in end_err_ (its status is made
     * under mu_, pump). */
    int next(Status *st)
    {
        if (!pending_.empty()) {
            out_.Clear();
            *out_.mutable_progress() = pending_.front();
            pending_.pop_front();
            return 1;
        }
        if (phase_ == P_STEPS) {
            svc_snap s;
            for (;;) {
                char *data = nullptr;
                size_t len = 0;
                int n = 0;
                /* the snapshot before the events: when it says finished,
                 * every event is in what follows; 64 KiB of them at a time */
                svc_job_snapshot(job_, &s);
                if (svc_job_events(job_, next_event_, 64 * 1024, &data, &len, &n) != 0) {
                    svc_error e;
                    if (errno == ENOMEM)
                        svc_error_set(&e, SVC_P_NOMEM, "out of memory reading the job's events");
                    else /* a finished job's, in the store */
                        svc_error_set(&e, SVC_P_STORAGE, "cannot read the job's events from "
                                      "the spool: %s", strerror(errno));
                    set_end(e);
                    return -1;
                }
                if (n == 0)
                    break;
                next_event_ += n;
                parse_events(data, len);
                free(data);
                if (!pending_.empty())
                    return next(st);
                /* every one before from_step: the next batch */
            }
            if (!svc_job_status_terminal(s.status)) {
                if (s.closing || (s.draining && s.status == SVC_JOB_QUEUED)) {
                    svc_error e = s.error;
                    if (svc_error_code(&e) != SVC_EDRAINING)
                        svc_error_set(&e, SVC_P_DRAINING,
                                      "the daemon is shutting down; job %s runs again after the restart", s.id);
                    set_end(e);
                    return -1;
                }
                if (no_wait_) {
                    svc_error e;
                    svc_error_set(&e, SVC_P_NOT_READY, "job %s is %s: no result yet", s.id,
                                  svc_job_status_name(s.status));
                    set_end(e);
                    return -1;
                }
                return 0;
            }
            if (s.status != SVC_JOB_SUCCEEDED) {
                set_end(s.error);
                return -1;
            }
            snprintf(result_name_, sizeof result_name_, "%s", s.result_name);
            snprintf(out_format_, sizeof out_format_, "%s", s.out_format);
            phase_ = P_METRICS;
        }
        svc_error e;
        switch (phase_) {
        case P_METRICS: {
            char *m = nullptr;
            size_t ml = 0;
            if (svc_job_metrics(job_, &m, &ml, &e) != 0) {
                set_end(e);
                return -1;
            }
            out_.Clear();
            out_.set_metrics(m, ml);
            free(m);
            phase_ = skip_result_ ? P_END : P_HEADER;
            return 1;
        }
        case P_HEADER: {
            if (svc_job_result(job_, keep_ ? SVC_RESULT_TAKE : 0, &result_, &result_len_, &e) != 0) {
                set_end(e);
                return -1;
            }
            taken_ = true;
            out_.Clear();
            pb::ResultHeader *h = out_.mutable_result_header();
            h->set_format(out_format_);
            h->set_size(result_len_);
            h->set_file_name(result_name_);
            h->set_job_id(svc_job_id(job_));
            phase_ = P_CHUNKS;
            return 1;
        }
        case P_CHUNKS:
            if (result_off_ < result_len_) {
                size_t n = result_len_ - result_off_ < kChunk ? result_len_ - result_off_ : kChunk;
                out_.Clear();
                out_.set_result_chunk(result_ + result_off_, n);
                result_off_ += n;
                return 1;
            }
            phase_ = P_END;
            /* fall through */
        default:
            *st = Status::OK;
            return -1;
        }
    }

    void set_end(const svc_error &e)
    {
        end_err_.reset(new svc_error(e));
    }

    void parse_events(const char *data, size_t len)
    {
        const char *p = data, *end = data + len;
        while (p < end) {
            const char *nl = (const char *)memchr(p, '\n', (size_t)(end - p));
            size_t n = nl ? (size_t)(nl - p) : (size_t)(end - p);
            cJSON *o = cJSON_ParseWithLength(p, n);
            if (o) {
                cJSON *s = cJSON_GetObjectItemCaseSensitive(o, "step");
                int step = cJSON_IsNumber(s) ? s->valueint : 0;
                if (step >= from_step_) {
                    pb::Progress pr;
                    pr.set_step(step);
                    pr.set_t(num(o, "t"));
                    pr.set_dt(num(o, "dt"));
                    pr.set_energy(num(o, "energy"));
                    pr.set_volume(num(o, "volume"));
                    pending_.push_back(pr);
                }
                cJSON_Delete(o);
            }
            p += n + 1;
        }
    }

    static double num(const cJSON *o, const char *k)
    {
        const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, k);
        return cJSON_IsNumber(x) ? x->valuedouble : 0;
    }

    enum { P_STEPS, P_METRICS, P_HEADER, P_CHUNKS, P_END };

    const char *method_;
    std::atomic<int> refs_{1};
    svc_job *job_ = nullptr;
    svc_sub *sub_ = nullptr;
    bool keep_ = false, taken_ = false, skip_result_ = false, no_wait_ = false;
    int from_step_ = 0;
    /* under mu_ */
    std::shared_ptr<Stall> stall_;  /* the write in flight, for the door's expire */
    bool writing_ = false, busy_ = false, dirty_ = false, gone_ = false;
    bool queued_ = false;           /* in the pump queue */
    /* touched only by the one pump() running (busy_) */
    int phase_ = P_STEPS;
    int next_event_ = 0;
    std::deque<pb::Progress> pending_;
    pb::SmoothResponse out_;
    char *result_ = nullptr;
    size_t result_len_ = 0, result_off_ = 0;
    char result_name_[32] = "", out_format_[16] = "";
    std::unique_ptr<svc_error> end_err_;   /* next()'s error, once */
};

void post(Follow *f)
{
    f->ref();
    {
        std::lock_guard<std::mutex> l(g.qmu);
        g.queue.push_back(f);
    }
    g.qcv.notify_one();
}

void pump_thread()
{
    std::unique_lock<std::mutex> l(g.qmu);
    for (;;) {
        g.qcv.wait(l, [] { return g.quit || !g.queue.empty(); });
        if (g.queue.empty())
            return;
        Follow *f = g.queue.front();
        g.queue.pop_front();
        l.unlock();
        f->dequeued();
        f->pump();
        f->unref();
        l.lock();
    }
}

/* ------------------------------------------------------------------ Smooth */

class SmoothCall : public Follow,
                   public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>,
                   public Expirable {
  public:
    explicit SmoothCall(CallbackServerContext *ctx) : Follow(ctx, "Smooth")
    {
        Order o(ctx);
        owns_job_ = true;
        Status st = admit_upload(ctx, &slot_);
        if (st.ok()) {
            up_.arm(this);
            read();
        } else {
            finish(st);
        }
    }

    void OnReadDone(bool ok) override
    {
        Order o(ctx_);
        svc_error e;
        if (ok) {
            if (up_.feed(&req_, &e))
                read();
            else
                finish_error(e);
            return;
        }
        up_.disarm();           /* whole: no expiry from now on */
        {
            std::lock_guard<std::mutex> l(mu_);
            if (finished_)      /* cancelled or expired while reading */
                return;
        }
        svc_job *j = nullptr;
        if (up_.submit(true, &j, &e) != 0) {
            finish_error(e);
            return;
        }
        ctx_->AddInitialMetadata("mcf-job-id", svc_job_id(j));
        follow(j, true, 0, false, false);
    }

    void OnWriteDone(bool ok) override
    {
        Order o(ctx_);
        write_done(ok);
    }
    /* The call's end (client cancel, deadline, broken stream): the job is
     * this call's alone, so it is cancelled and its worker freed. */
    void OnCancel() override
    {
        Order o(ctx_);
        cancelled();
    }
    void OnDone() override
    {
        HB_ACQUIRE(ctx_);
        up_.disarm();
        done();
    }
    void expire(const char *what, const char *flag, double limit) override
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!finished_)
            finish_locked(late_status(ctx_, what, flag, limit));
    }

  private:
    void read()
    {
        HB_RELEASE(ctx_);
        StartRead(&req_);
    }
    /* Under mu_ (Follow::pump); one write in flight, so one buffer. */
    void start_write(const pb::SmoothResponse *m) override
    {
        bool own;
        wbuf_.Clear();              /* the last write is done: its bytes go */
        HB_RELEASE(ctx_);
        if (!grpc::SerializationTraits<pb::SmoothResponse>::Serialize(*m, &wbuf_, &own).ok()) {
            finished_ = true;
            Finish(counted("Smooth", door_status(ctx_, SVC_P_INTERNAL, "cannot serialize a response")));
            return;
        }
        StartWrite(&wbuf_);
    }
    void finish_call(const Status &st) override
    {
        HB_RELEASE(ctx_);
        Finish(st);
    }

    grpc::ByteBuffer req_, wbuf_;   /* parsed and serialized here (Upload::feed) */
    Upload up_;
};

/* --------------------------------------------------------------- WatchJob */

class WatchCall : public Follow, public grpc::ServerWriteReactor<pb::SmoothResponse> {
  public:
    WatchCall(CallbackServerContext *ctx, const pb::WatchJobRequest *req)
        : Follow(ctx, "WatchJob")
    {
        Order o(ctx);
        svc_job *j;
        Status st;
        int here;
        if (!authorized(ctx)) {
            finish(unauthenticated(ctx));
        } else if (!slot_.take(ctx, &st)) {
            finish(st);
        } else if (!(j = svc_job_get(g.svc, req->id().c_str()))) {
            finish(door_status(ctx, SVC_P_NOT_FOUND,
                               "no job '" + req->id().substr(0, 64) + "' (or it expired)"));
        } else if ((here = svc_followers(j)) >= SVC_FOLLOWERS_PER_JOB) {
            finish(door_status(ctx, SVC_P_BUSY,
                               "job " + std::string(svc_job_id(j)) + " already has " +
                                   std::to_string(here) + " followers, the most one job "
                                   "may have; poll GetJob instead"));
            svc_job_unref(j);
        } else {
            ctx->AddInitialMetadata("mcf-job-id", svc_job_id(j));
            follow(j, false, req->from_step(), req->skip_result(), req->no_wait());
        }
    }

    void OnWriteDone(bool ok) override
    {
        Order o(ctx_);
        write_done(ok);
    }
    /* A watcher leaving does not cancel the job. */
    void OnCancel() override
    {
        Order o(ctx_);
        cancelled();
    }
    void OnDone() override
    {
        HB_ACQUIRE(ctx_);
        done();
    }

  private:
    void start_write(const pb::SmoothResponse *m) override
    {
        HB_RELEASE(ctx_);
        StartWrite(m);
    }
    void finish_call(const Status &st) override
    {
        HB_RELEASE(ctx_);
        Finish(st);
    }
};

/* -------------------------------------------------------------- SubmitJob */

class SubmitCall : public grpc::ServerReadReactor<grpc::ByteBuffer>, public Expirable {
  public:
    SubmitCall(CallbackServerContext *ctx, grpc::ByteBuffer *resp) : ctx_(ctx), resp_(resp)
    {
        Order o(ctx);
        g.active++;
        Status st = admit_upload(ctx, &slot_);
        if (st.ok()) {
            up_.arm(this);
            read();
        } else {
            end(st);
        }
    }

    void OnReadDone(bool ok) override
    {
        Order o(ctx_);
        svc_error e;
        if (ok) {
            if (up_.feed(&req_, &e))
                read();
            else
                end_error(e);
            return;
        }
        up_.disarm();       /* whole: no expiry from now on */
        {
            std::lock_guard<std::mutex> l(mu_);
            if (ended_)     /* cancelled or expired while reading */
                return;
        }
        svc_job *j = nullptr;
        if (up_.submit(false, &j, &e) != 0) {
            end_error(e);
            return;
        }
        pb::Job job;
        bool own, ok2 = fill_job(j, &job) &&
                        grpc::SerializationTraits<pb::Job>::Serialize(job, resp_, &own).ok();
        svc_job_unref(j);
        end(ok2 ? Status::OK : door_status(ctx_, SVC_P_NOMEM, "out of memory"));
    }

    void OnCancel() override
    {
        Order o(ctx_);
        end(Status(StatusCode::CANCELLED, "cancelled by the client"));
    }
    void OnDone() override
    {
        HB_ACQUIRE(ctx_);
        up_.disarm();
        g.active--;
        delete this;
    }
    void expire(const char *what, const char *flag, double limit) override
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!ended_)
            end_locked(late_status(ctx_, what, flag, limit));
    }

  private:
    void read()
    {
        HB_RELEASE(ctx_);
        StartRead(&req_);
    }

    void end(const Status &st)
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!ended_)
            end_locked(st);
    }

    /* Trailing metadata is added under mu_ and only before Finish: the
     * main thread (expire) and a reaction may end the call at once. */
    void end_error(const svc_error &e)
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!ended_)
            end_locked(status_from(ctx_, e));
    }

    void end_locked(const Status &st)
    {
        ended_ = true;
        HB_RELEASE(ctx_);
        Finish(counted("SubmitJob", st));
    }

    CallbackServerContext *ctx_;
    grpc::ByteBuffer *resp_;        /* the Job, serialized here */
    grpc::ByteBuffer req_;          /* parsed by Upload::feed */
    Upload up_;
    Slot slot_;
    std::mutex mu_;
    bool ended_ = false;
};

/* ---------------------------------------------------------------- service */

/* Smooth and SubmitJob are raw methods: their requests come as bytes and
 * are parsed by the door (Upload::feed), the only way to tell a corrupt
 * message from the end of the upload. Reflection still describes them
 * from the proto. */
using SmootherBase = pb::Smoother::WithRawCallbackMethod_Smooth<
    pb::Smoother::WithRawCallbackMethod_SubmitJob<pb::Smoother::WithCallbackMethod_GetJob<
        pb::Smoother::WithCallbackMethod_CancelJob<pb::Smoother::WithCallbackMethod_WatchJob<
            pb::Smoother::WithCallbackMethod_ListSchemes<pb::Smoother::Service>>>>>>;

class Smoother final : public SmootherBase {
    grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> *
    Smooth(CallbackServerContext *ctx) override
    {
        return new SmoothCall(ctx);
    }

    grpc::ServerReadReactor<grpc::ByteBuffer> *SubmitJob(CallbackServerContext *ctx,
                                                         grpc::ByteBuffer *resp) override
    {
        return new SubmitCall(ctx, resp);
    }

    grpc::ServerWriteReactor<pb::SmoothResponse> *
    WatchJob(CallbackServerContext *ctx, const pb::WatchJobRequest *req) override
    {
        return new WatchCall(ctx, req);
    }

    grpc::ServerUnaryReactor *GetJob(CallbackServerContext *ctx, const pb::GetJobRequest *req,
                                     pb::Job *resp) override
    {
        return unary(ctx, "GetJob", [&]() -> Status {
            svc_job *j = svc_job_get(g.svc, req->id().c_str());
            if (!j)
                return not_found(ctx, req->id());
            bool ok = fill_job(j, resp);
            svc_job_unref(j);
            return ok ? Status::OK : door_status(ctx, SVC_P_NOMEM, "out of memory");
        });
    }

    grpc::ServerUnaryReactor *CancelJob(CallbackServerContext *ctx,
                                        const pb::CancelJobRequest *req,
                                        pb::Job *resp) override
    {
        return unary(ctx, "CancelJob", [&]() -> Status {
            svc_job *j = svc_job_get(g.svc, req->id().c_str());
            if (!j)
                return not_found(ctx, req->id());
            if (svc_cancel(j, SVC_CANCEL_USER) < 0) {
                svc_error e;
                svc_error_set(&e, SVC_P_STORAGE,
                              "the spool could not record the cancellation of job %s "
                              "(not canceled; retry): %s", svc_job_id(j), strerror(errno));
                svc_job_unref(j);
                return status_from(ctx, e);
            }
            bool ok = fill_job(j, resp);
            svc_job_unref(j);
            return ok ? Status::OK : door_status(ctx, SVC_P_NOMEM, "out of memory");
        });
    }

    grpc::ServerUnaryReactor *ListSchemes(CallbackServerContext *ctx,
                                          const pb::ListSchemesRequest *,
                                          pb::ListSchemesResponse *resp) override
    {
        return unary(ctx, "ListSchemes", [&]() -> Status {
            for (int s = 0; s < MCF_NSCHEMES; s++) {
                const mcf_scheme_info *si = mcf_scheme_get((mcf_scheme)s);
                if (!si)
                    continue;
                pb::Scheme *o = resp->add_schemes();
                o->set_name(si->name);
                o->set_title(si->title ? si->title : "");
                o->set_order(si->order);
                o->set_is_explicit(si->is_explicit != 0);
                o->set_stability(si->stability);
                o->set_solves_per_step(si->solves_per_step);
                o->set_factorizations_per_step(si->factorizations_per_step);
                o->set_has_estimate(si->has_estimate != 0);
                o->set_estimate(si->estimate ? si->estimate : "");
                o->set_best_use(si->best_use ? si->best_use : "");
            }
            return Status::OK;
        });
    }

    template <class F>
    grpc::ServerUnaryReactor *unary(CallbackServerContext *ctx, const char *method, F body)
    {
        grpc::ServerUnaryReactor *r = ctx->DefaultReactor();
        r->Finish(counted(method, authorized(ctx) ? body() : unauthenticated(ctx)));
        return r;
    }

    static Status not_found(CallbackServerContext *ctx, const std::string &id)
    {
        return door_status(ctx, SVC_P_NOT_FOUND,
                           "no job '" + id.substr(0, 64) + "' (or it expired)");
    }
};

Smoother g_service;

void set_serving(bool on)
{
    grpc::HealthCheckServiceInterface *h = g.server ? g.server->GetHealthCheckService() : nullptr;
    if (!h)
        return;
    h->SetServingStatus("", on);
    h->SetServingStatus(kService, on);
}

/* The gate hands each admitted connection's inner end to gRPC (on the
 * gate's thread). */
void adopt(int fd, void *)
{
    try {
        grpc::AddInsecureChannelFromFd(g.server.get(), fd);
    } catch (...) {
        close(fd);
    }
}

} // namespace

/* ------------------------------------------------------------ C interface */

namespace {

int grpc_start(const srv_config *cfg, svc_t *svc, const srv_daemon *dm, void **door,
               char *where, size_t wsize, char *msg, size_t msgsize)
{
    (void)dm;
    *door = nullptr;
    try {
        grpc::EnableDefaultHealthCheckService(true);
        grpc::reflection::InitProtoReflectionServerBuilderPlugin();
        grpc::ServerBuilder b;
        /* No listening port: the gate (h2gate.c) owns the socket and hands
         * gRPC each admitted connection; h2gate.c says why. */
        b.RegisterService(&g_service);
        /* The streams one connection may hold (the gate enforces it even
         * for a client that never acknowledges the setting). */
        b.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, kStreamsPerConn);
        /* A connection without a call for --send-timeout is closed (REST's
         * keep-alive connections are held as long) */
        if (cfg->send_timeout > 0)
            b.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS,
                                 (int)(cfg->send_timeout * 1000));
        /* Requests are not compressed: gRPC 1.51 inflates a whole message
         * before any size limit (message_decompress_filter.cc: 132 KiB of
         * gzip became 128 MiB), so only identity is enabled and a
         * compressed message is refused (UNIMPLEMENTED) unread. Answers
         * are not compressed either. */
        b.AddChannelArgument(GRPC_COMPRESSION_CHANNEL_ENABLED_ALGORITHMS_BITSET,
                             1 << GRPC_COMPRESS_NONE);
        grpc::ResourceQuota quota("mcfd-grpc");
        quota.Resize(kQuotaBytes);
        quota.SetMaxThreads(kQuotaThreads);
        b.SetResourceQuota(quota);
        /* one chunk or one header (its params at most --max-json), and a
         * little for the framing: anything larger is refused by gRPC with
         * RESOURCE_EXHAUSTED before it is buffered */
        b.SetMaxReceiveMessageSize((int)(kChunk + cfg->lim.max_json_bytes + 4096));
        b.SetMaxSendMessageSize((int)(kChunk + 4096 + 16 * 1024 * 1024));
        g.cfg = cfg;
        g.svc = svc;
        g.quit = false;
        g.server = b.BuildAndStart();
        if (!g.server) {
            snprintf(msg, msgsize, "gRPC: the server did not start");
            return -1;
        }
        h2gate_config gc = {};
        gc.bind = cfg->bind;
        gc.port = cfg->grpc_port;
        gc.max_conns = cfg->grpc_max_connections;
        gc.max_conns_per_ip = cfg->max_connections_per_ip;
        gc.fd_reserve = cfg->fd_reserve;
        gc.streams_per_conn = kStreamsPerConn;
        gc.max_streams = kMaxStreams;
        gc.max_streams_per_ip = kMaxStreamsPerIp;
        gc.resets_per_s = kResetsPerS;
        gc.max_header_block = kMaxHeaderBlock;
        gc.max_header_frames = kMaxHeaderFrames;
        gc.header_timeout = cfg->header_timeout;
        /* a second more than the door's own upload deadline (expire):
         * an upload gets its DEADLINE_EXCEEDED from the door first */
        gc.message_timeout = cfg->header_timeout > 0 ? cfg->header_timeout + 1 : 0;
        gc.unhealthy_after = SRV_FDS_DEAD;
        gc.adopt = adopt;
        int port = 0;
        if (h2gate_start(&gc, &port, msg, msgsize) != 0) {
            g.server->Shutdown();
            g.server->Wait();
            g.server.reset();
            return -1;
        }
        set_serving(true);
        g.pump = std::thread(pump_thread);
        snprintf(where, wsize, strchr(cfg->bind, ':') ? "[%s]:%d" : "%s:%d", cfg->bind, port);
        *door = &g;
        return 0;
    } catch (const std::exception &ex) {
        snprintf(msg, msgsize, "gRPC: %s", ex.what());
    } catch (...) {
        snprintf(msg, msgsize, "gRPC: start-up failed");
    }
    return -1;
}

void grpc_drain(void *door)
{
    if (!door)
        return;
    g.draining = true;
    set_serving(false);
}

void grpc_stop(void *door)
{
    if (!door || !g.server)
        return;
    h2gate_stop_accepting();
    try {
        g.server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
        g.server->Wait();
    } catch (...) {
    }
    h2gate_stop();
    {
        std::lock_guard<std::mutex> l(g.qmu);
        g.quit = true;
    }
    g.qcv.notify_all();
    if (g.pump.joinable())
        g.pump.join();
    g.server.reset();
}

int expire(double header_timeout, double body_timeout, double send_timeout)
{
    std::vector<std::shared_ptr<Deadline>> late;
    std::vector<std::shared_ptr<Stall>> stalled;
    double now = srv_mono();
    {
        std::lock_guard<std::mutex> l(g.umu);
        for (const auto &d : g.uploads) {
            double age = now - d->started;
            if ((header_timeout > 0 && !d->have_header && age > header_timeout) ||
                (body_timeout > 0 && age > body_timeout))
                late.push_back(d);
        }
        for (const auto &w : g.answers) {
            double since = w->since;
            if (send_timeout > 0 && since > 0 && now - since > send_timeout)
                stalled.push_back(w);
        }
    }
    int n = 0;
    /* A write the client's flow control has held for send_timeout: the
     * call is cancelled, its write then fails and the call ends (a Smooth
     * cancels its job), releasing the result it held. */
    for (const auto &w : stalled) {
        std::lock_guard<std::recursive_mutex> l(w->mu);
        if (!w->alive || w->since == 0)
            continue;
        w->since = 0;
        srv_logf(SRV_LOG_INFO, "gRPC call cancelled: its client read nothing for "
                 "--send-timeout %g s", send_timeout);
        w->ctx->TryCancel();
        n++;
    }
    for (const auto &d : late) {
        std::lock_guard<std::recursive_mutex> l(d->mu);
        if (!d->alive)
            continue;
        d->alive = false;
        if (!d->have_header)
            d->call->expire("the header", "--header-timeout", header_timeout);
        else
            d->call->expire("the whole upload", "--body-timeout", body_timeout);
        n++;
    }
    return n;
}

int grpc_expire(void *door, const srv_config *cfg)
{
    int n = door ? expire(cfg->header_timeout, cfg->body_timeout, cfg->send_timeout) : 0;
    if (n > 0)
        srv_logf(SRV_LOG_WARN, "ended %d gRPC call%s that sent no header within "
                 "--header-timeout %g s, no whole upload within --body-timeout %g s, "
                 "or read nothing for --send-timeout %g s", n, n == 1 ? "" : "s",
                 cfg->header_timeout, cfg->body_timeout, cfg->send_timeout);
    return n;
}

int grpc_active(void *door)
{
    return door ? g.active.load() : 0;
}

int grpc_health(void *door, char *why, size_t size)
{
    return door && g.server ? h2gate_health(why, size) : 0;
}

void grpc_gauges(void *door, srv_gauges *out)
{
    h2gate_stats st;
    if (!door)
        return;
    h2gate_get_stats(&st);
    out->grpc_connections = st.conns;
    out->grpc_streams = st.streams;
    out->grpc_waiting = st.waiting;
    out->grpc_refused = (double)st.refused;
    out->grpc_closed = (double)st.closed;
    out->grpc_reset = (double)st.streams_reset;
    out->grpc_accept_errors = (double)st.accept_errors;
}

} // namespace

extern "C" const srv_door_ops srv_grpc_door = {
    "gRPC", grpc_start, grpc_drain, grpc_stop, grpc_expire, grpc_active,
    grpc_health, grpc_gauges,
};
