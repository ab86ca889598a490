/* SPDX-License-Identifier: MIT */
/*
 * grpc_internal.h - what the gRPC door's files share (never included
 * outside them): the door's state, its status and message helpers, and
 * the classes of its streaming calls. The door is api/mcfd.proto's
 * mcfd.v1.Smoother on gRPC's C++ callback API, a bridge from the
 * transport to the job service (service.h) behind the plain C interface
 * of grpc_door.h; the only C++ in server/, as api/'s bridges to C++
 * libraries (api_draco*.cc, api_gltf.cc) are in api/.
 * Everything it decides about jobs it asks the service, everything about
 * parameters, formats and metrics it asks api/ through the service, so
 * both doors give the same answers.
 *
 * Files
 *   grpc.cc         the door: its state, start, drain, stop, expire,
 *                   health and gauges (grpc_door.h's mcfd_grpc_door)
 *   grpc_status.cc  statuses from the service's errors, the token check,
 *                   proto <-> service conversions (params, Job)
 *   grpc_upload.cc  Slot (a streaming call's place) and Upload (the
 *                   bytes of Smooth and SubmitJob as they stream in)
 *   grpc_follow.cc  Follow (a job followed to its end) and the pump thread
 *   grpc_calls.cc   the calls (SmoothCall, SubmitCall, WatchCall) and the
 *                   service that makes them
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
#ifndef MCFD_GRPC_INTERNAL_H
#define MCFD_GRPC_INTERNAL_H

#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "mcfd.grpc.pb.h"

extern "C" {
#include "srv.h" /* plain C headers without extern "C" guards */
#include "service.h"
}

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

namespace mcfd_grpc {

namespace pb = mcfd::v1;
using grpc::CallbackServerContext;
using grpc::Status;
using grpc::StatusCode;

const size_t kChunk = 64 * 1024;   /* chunk size, both ways */

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

class Follow;

/* The door's state: a process singleton by design (one daemon has one gRPC
 * door, started and stopped once by main.c through grpc_door.h;
 * grpc_state.cc's g). Its fields are set before the server starts and
 * read by the calls; the mutable ones name their lock. */
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
    std::set<std::shared_ptr<Deadline>> uploads;
    /* answers being streamed (the door's expire: stalled writes) */
    std::set<std::shared_ptr<Stall>> answers;
    /* the pump thread and its queue of followers to look at */
    std::mutex qmu;
    std::condition_variable qcv;
    std::deque<Follow *> queue;
    bool quit = false;
    std::thread pump;
};
extern Door g;

/* In a reaction (or a reactor's constructor): what gRPC ordered before it
 * is visible, and what it did is ordered before the next one (TSan only;
 * see HB_RELEASE above). */
struct Order {
    explicit Order(const void *call) : call_(call) { HB_ACQUIRE(call_); }
    ~Order() { HB_RELEASE(call_); }
    const void *call_;
};

/* ---------------------------------------------- grpc_status.cc: helpers */

/* The status of e (service.h's table: its gRPC column), with its name
 * and retry delay in trailing metadata. */
Status status_from(CallbackServerContext *ctx, const svc_error &e);
/* A door-made error: problem p with the detail. */
Status door_status(CallbackServerContext *ctx, svc_problem p, const std::string &detail);
/* Counts the call in /metrics and returns st. */
Status counted(const char *method, const Status &st);
/* The bearer token check of REST (srv_bearer_ok: constant time). */
bool authorized(CallbackServerContext *ctx);
Status unauthenticated(CallbackServerContext *ctx);
Status draining_status(CallbackServerContext *ctx);
/* An upload that missed a deadline of the door (not the client's own). */
Status late_status(CallbackServerContext *ctx, const char *what, const char *flag,
                   double limit);
/* The parameters as the JSON object REST's `params` field takes; NULL
 * when out of memory. */
cJSON *params_object(const pb::Params &p, const std::string *out_format);
/* The Job message from the service's document of the job. */
bool fill_job(svc_job *j, pb::Job *out);
/* The client's address (the gate knows whose each connection is). */
std::string client_address(CallbackServerContext *ctx);

/* ---------------------------------------------- grpc_upload.cc: uploads */

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
    ~Slot();
    /* true when taken; else false and st says why. */
    bool take(CallbackServerContext *ctx, Status *st);

  private:
    bool held_ = false;
    std::string peer_;
};

/* Whether an upload (Smooth, SubmitJob) may start reading: the token, a
 * slot, and not draining, in that order. OK, or the status to end with. */
Status admit_upload(CallbackServerContext *ctx, Slot *slot);

/* The bytes of Smooth and SubmitJob as they stream in: the header first,
 * then mesh and target chunks, every size checked before it is kept. */
class Upload {
  public:
    ~Upload();
    bool feed(grpc::ByteBuffer *b, svc_error *e);
    bool feed(const pb::SmoothRequest &m, svc_error *e);
    int submit(bool keep_result, svc_job **out, svc_error *e);
    bool phases() const { return phases_; }  /* SmoothHeader.phases */
    void arm(Expirable *call);
    void disarm();

  private:
    static svc_request request_init()
    {
        svc_request rq;
        svc_request_init(&rq);
        return rq;
    }
    bool header(const pb::SmoothHeader &h, svc_error *e);
    static std::string basename_of(const std::string &n);
    bool append(char **buf, size_t *len, long long declared, const std::string &b,
                const char *what, svc_error *e);
    size_t &alloc_of(char **buf) { return buf == &mesh_ ? mesh_alloc_ : target_alloc_; }
    static bool fail(svc_error *e, svc_problem p, const char *fmt, ...)
#if defined(__GNUC__)
        __attribute__((format(printf, 3, 4)))
#endif
        ;
    /* A limit: EINPUT with mcf ELIMIT, RESOURCE_EXHAUSTED. */
    static bool limit(svc_error *e, const char *fmt, ...)
#if defined(__GNUC__)
        __attribute__((format(printf, 2, 3)))
#endif
        ;


    bool have_header_ = false;
    long nmsg_ = 0;                 /* messages received */
    pb::SmoothRequest req_;
    svc_request rq_ = request_init();
    api_format in_format_ = API_FMT_UNKNOWN;
    long long total_size_ = -1, target_size_ = -1;
    bool phases_ = false;
    char *mesh_ = nullptr, *target_ = nullptr;
    size_t mesh_len_ = 0, target_len_ = 0, mesh_alloc_ = 0, target_alloc_ = 0;
    size_t mem_held_ = 0;           /* svc_upload_reserve */
    std::shared_ptr<Deadline> dl_;
};

/* ---------------------------------------- grpc_follow.cc: answers streamed */

/* What Smooth and WatchJob share: a job followed to its end, written one
 * message at a time. Subclasses give the transport's StartWrite and
 * Finish. Reference counted: gRPC's reference (dropped in OnDone) and one
 * per post to the pump queue. */
class Follow {
  public:
    virtual ~Follow();
    void ref() { refs_++; }
    void dequeued();
    void unref()
    {
        if (--refs_ == 0)
            delete this;
    }
    static void notify(void *ctx, unsigned what);
    void pump();

  protected:
    Follow(CallbackServerContext *ctx, const char *method);
    void follow(svc_job *j, bool keep, int from_step, bool skip_result, bool no_wait,
                bool phases);
    void write_done(bool ok);
    void cancelled();
    void done();
    void finish(const Status &st);
    void finish_error(const svc_error &e);
    void finish_locked(const Status &st);

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
    int next(Status *st);
    void set_end(const svc_error &e);
    void parse_events(const char *data, size_t len);
    void queue_phases();
    bool work_news(const svc_snap &s);
    static double num(const cJSON *o, const char *k);

    enum { P_STEPS, P_METRICS, P_HEADER, P_CHUNKS, P_END };

    const char *method_;
    std::atomic<int> refs_{1};
    svc_job *job_ = nullptr;
    svc_sub *sub_ = nullptr;
    bool keep_ = false, taken_ = false, skip_result_ = false, no_wait_ = false;
    bool phases_ = false;          /* the core's milestones too (work_news) */
    int from_step_ = 0;
    /* under mu_ */
    std::shared_ptr<Stall> stall_;  /* the write in flight, for the door's expire */
    bool writing_ = false, busy_ = false, dirty_ = false, gone_ = false;
    bool queued_ = false;           /* in the pump queue */
    /* touched only by the one pump() running (busy_) */
    int phase_ = P_STEPS;
    int next_event_ = 0;
    std::deque<pb::Progress> pending_;
    /* the milestones sent (queue_phases, work_news): the run's phase
     * changes, the last share, and the events sent by then */
    int work_phases_ = 0;
    double work_told_ = 0;
    int work_event_ = 0;
    pb::SmoothResponse out_;
    char *result_ = nullptr;
    size_t result_len_ = 0, result_off_ = 0;
    char result_name_[32] = "", out_format_[16] = "";
    std::unique_ptr<svc_error> end_err_;   /* next()'s error, once */
};

/* Queues f for the pump thread (a reference for the queue). */
void post(Follow *f);
/* The pump thread: pumps the followers posted to it until g.quit. */
void pump_thread();

/* ------------------------------------------------ grpc_calls.cc: service */

/* The Smoother service: the calls above behind api/mcfd.proto's methods. */
grpc::Service *smoother_service();

} // namespace mcfd_grpc

#endif
