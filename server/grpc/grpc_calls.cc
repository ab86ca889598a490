/* SPDX-License-Identifier: MIT */
/*
 * grpc_calls.cc - the gRPC door's calls (grpc_internal.h): Smooth
 * (upload, then follow its job), SubmitJob (upload, answer the Job),
 * WatchJob (follow an existing job), and the Smoother service that makes
 * them and answers the unary GetJob, CancelJob and ListSchemes.
 */
#include <cerrno>
#include <cstring>

#include "grpc_internal.h"

namespace mcfd_grpc {

namespace {

/* ------------------------------------------------------------- uploads */

/* The upload half of Smooth and SubmitJob, whose reactor bases differ
 * (bidi and client-streaming): admitted, then read one message at a time
 * into Upload until the client half-closes, then submitted; the door's
 * expire ends it while it is late. Call (CRTP, a friend) gives its
 * reactor's StartRead, ctx_, and under mu_ its end: finished_,
 * finish_locked(st); finish(st) and finish_error(e) take mu_. */
template <class Call>
class Uploading : public Expirable {
  public:
    void expire(const char *what, const char *flag, double limit) override
    {
        std::lock_guard<std::mutex> l(self().mu_);
        if (!self().finished_)
            self().finish_locked(late_status(self().ctx_, what, flag, limit));
    }

  protected:
    /* In the call's constructor: reading, or ended. */
    void begin(CallbackServerContext *ctx, Slot *slot)
    {
        Status st = admit_upload(ctx, slot);
        if (st.ok()) {
            up_.arm(this);
            read();
        } else {
            self().finish(st);
        }
    }

    /* OnReadDone's part: the next message read, or at the end of the
     * upload its job submitted (a reference). nullptr when there is no
     * job (reading on, or the call ended). */
    svc_job *read_done(bool ok, bool keep_result)
    {
        svc_error e;
        if (ok) {
            if (up_.feed(&req_, &e))
                read();
            else
                self().finish_error(e);
            return nullptr;
        }
        up_.disarm();           /* whole: no expiry from now on */
        {
            std::lock_guard<std::mutex> l(self().mu_);
            if (self().finished_)   /* cancelled or expired while reading */
                return nullptr;
        }
        svc_job *j = nullptr;
        if (up_.submit(keep_result, &j, &e) != 0) {
            self().finish_error(e);
            return nullptr;
        }
        return j;
    }

    Upload up_;

  private:
    Call &self() { return static_cast<Call &>(*this); }
    void read()
    {
        HB_RELEASE(self().ctx_);
        self().StartRead(&req_);
    }

    grpc::ByteBuffer req_;          /* parsed by Upload::feed */
};

/* ------------------------------------------------------------------ Smooth */

class SmoothCall : public Follow,
                   public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>,
                   public Uploading<SmoothCall> {
    friend class Uploading<SmoothCall>;

  public:
    explicit SmoothCall(CallbackServerContext *ctx) : Follow(ctx, "Smooth")
    {
        Order o(ctx);
        owns_job_ = true;
        begin(ctx, &slot_);
    }

    void OnReadDone(bool ok) override
    {
        Order o(ctx_);
        svc_job *j = read_done(ok, true);
        if (!j)
            return;
        ctx_->AddInitialMetadata("mcf-job-id", svc_job_id(j));
        follow(j, true, 0, false, false, up_.phases());
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

  private:
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

    grpc::ByteBuffer wbuf_;         /* serialized here */
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
        svc_error e;
        int here;
        if (!authorized(ctx)) {
            finish(unauthenticated(ctx));
        } else if (!slot_.take(ctx, &st)) {
            finish(st);
        } else if (!(j = svc_job_find(g.svc, req->id().c_str(), &e))) {
            finish(status_from(ctx, e));
        } else if ((here = svc_followers(j)) >= SVC_FOLLOWERS_PER_JOB) {
            finish(door_status(ctx, SVC_P_BUSY,
                               "job " + std::string(svc_job_id(j)) + " already has " +
                                   std::to_string(here) + " followers, the most one job "
                                   "may have; poll GetJob instead"));
            svc_job_unref(j);
        } else {
            ctx->AddInitialMetadata("mcf-job-id", svc_job_id(j));
            follow(j, false, req->from_step(), req->skip_result(), req->no_wait(),
                   req->phases());
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

class SubmitCall : public grpc::ServerReadReactor<grpc::ByteBuffer>,
                   public Uploading<SubmitCall> {
    friend class Uploading<SubmitCall>;

  public:
    SubmitCall(CallbackServerContext *ctx, grpc::ByteBuffer *resp) : ctx_(ctx), resp_(resp)
    {
        Order o(ctx);
        g.active++;
        begin(ctx, &slot_);
    }

    void OnReadDone(bool ok) override
    {
        Order o(ctx_);
        svc_job *j = read_done(ok, false);
        if (!j)
            return;
        pb::Job job;
        bool own, ok2 = fill_job(j, &job) &&
                        grpc::SerializationTraits<pb::Job>::Serialize(job, resp_, &own).ok();
        svc_job_unref(j);
        finish(ok2 ? Status::OK : door_status(ctx_, SVC_P_NOMEM, "out of memory"));
    }

    void OnCancel() override
    {
        Order o(ctx_);
        finish(Status(StatusCode::CANCELLED, "cancelled by the client"));
    }
    void OnDone() override
    {
        HB_ACQUIRE(ctx_);
        up_.disarm();
        g.active--;
        delete this;
    }

  private:
    void finish(const Status &st)
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!finished_)
            finish_locked(st);
    }

    /* Trailing metadata is added under mu_ and only before Finish: the
     * main thread (expire) and a reaction may end the call at once. */
    void finish_error(const svc_error &e)
    {
        std::lock_guard<std::mutex> l(mu_);
        if (!finished_)
            finish_locked(status_from(ctx_, e));
    }

    void finish_locked(const Status &st)
    {
        finished_ = true;
        HB_RELEASE(ctx_);
        Finish(counted("SubmitJob", st));
    }

    CallbackServerContext *ctx_;
    grpc::ByteBuffer *resp_;        /* the Job, serialized here */
    Slot slot_;
    std::mutex mu_;
    bool finished_ = false;
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
            svc_error e;
            svc_job *j = svc_job_find(g.svc, req->id().c_str(), &e);
            if (!j)
                return status_from(ctx, e);
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
            svc_error e;
            svc_job *j = svc_job_find(g.svc, req->id().c_str(), &e);
            if (!j)
                return status_from(ctx, e);
            if (svc_cancel(j, SVC_CANCEL_USER) < 0) {
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
};


Smoother g_service;

} // namespace

grpc::Service *smoother_service()
{
    return &g_service;
}

} // namespace mcfd_grpc
