/* SPDX-License-Identifier: MIT */
/*
 * grpc_follow.cc - the gRPC door's answers (grpc_internal.h): Follow, a
 * job followed to its end and written one message at a time (progress,
 * metrics, the result's header and chunks), woken by the service's notify
 * and pumped on the door's one pump thread (or in OnWriteDone).
 */
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "grpc_internal.h"

namespace mcfd_grpc {

Follow::~Follow()
{
    if (job_) {
        if (keep_ && !taken_)
            svc_job_release_result(job_);
        svc_job_unref(job_);
    }
    free(result_);
    g.active--;
}

void Follow::dequeued()
{
    std::lock_guard<std::mutex> l(mu_);
    queued_ = false;
}
void Follow::notify(void *ctx, unsigned what)
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
void Follow::pump()
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

Follow::Follow(CallbackServerContext *ctx, const char *method) : ctx_(ctx), method_(method)
{
    g.active++;
    stall_ = std::make_shared<Stall>();
    stall_->ctx = ctx;
    std::lock_guard<std::mutex> l(g.umu);
    g.answers.insert(stall_);
}

/* Starts following j (a reference the follower now owns). */
void Follow::follow(svc_job *j, bool keep, int from_step, bool skip_result, bool no_wait,
                    bool phases)
{
    bool gone;
    {
        std::lock_guard<std::mutex> l(mu_);
        job_ = j;
        keep_ = keep;
        from_step_ = from_step;
        skip_result_ = skip_result;
        no_wait_ = no_wait;
        phases_ = phases;
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

void Follow::write_done(bool ok)
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
void Follow::cancelled()
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
void Follow::done()
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

void Follow::finish(const Status &st)
{
    std::lock_guard<std::mutex> l(mu_);
    finish_locked(st);
}

/* Ends with e's status. Its trailing metadata is added under mu_ and
 * only while not finished: after Finish the context is gRPC's (it
 * sends the trailers), and a reaction, the pump and the main thread
 * (expire) may end the call at once. */
void Follow::finish_error(const svc_error &e)
{
    std::lock_guard<std::mutex> l(mu_);
    if (!finished_)
        finish_locked(status_from(ctx_, e));
}

void Follow::finish_locked(const Status &st)
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
/* The next message into out_: 1; nothing to send now: 0; the end:
 * -1 and *st, or -1 and an error in end_err_ (its status is made
 * under mu_, pump). */
int Follow::next(Status *st)
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
            if (n == 0) {
                queue_phases();
                if (!pending_.empty())
                    return next(st);
                break;
            }
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
            if (work_news(s))
                return 1;
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

void Follow::set_end(const svc_error &e)
{
    end_err_.reset(new svc_error(e));
}

/* For a call that asked for them (phases_): the run's phase changes not
 * sent yet into pending_ (kept with the job: none is missed). */
void Follow::queue_phases()
{
    svc_phase ph[SVC_PHASES_MAX];
    int n, k;

    if (!phases_)
        return;
    n = svc_job_phases(job_, work_phases_, ph, SVC_PHASES_MAX);
    for (k = 0; work_phases_ < n && k < SVC_PHASES_MAX; k++, work_phases_++) {
        if (ph[k].step < from_step_)
            continue;
        pb::Progress pr;
        pr.set_step(ph[k].step);
        pr.set_phase(ph[k].phase);
        pr.set_fraction(ph[k].fraction);
        pending_.push_back(pr);
        work_told_ = ph[k].fraction;
        work_event_ = next_event_;
    }
}

/* While the job runs, its share into out_ when it moved by a percent with
 * no step or milestone sent since the last one (a phase without steps:
 * the default request's passes, say). */
bool Follow::work_news(const svc_snap &s)
{
    if (!phases_ || s.status != SVC_JOB_RUNNING || !s.phase[0] || s.step < from_step_ ||
        !(s.fraction >= work_told_ + SVC_WORK_STEP && next_event_ == work_event_))
        return false;
    work_told_ = s.fraction;
    out_.Clear();
    pb::Progress *pr = out_.mutable_progress();
    pr->set_step(s.step);
    pr->set_phase(s.phase);
    pr->set_fraction(s.fraction);
    return true;
}

void Follow::parse_events(const char *data, size_t len)
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

double Follow::num(const cJSON *o, const char *k)
{
    const cJSON *x = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(x) ? x->valuedouble : 0;
}

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

} // namespace mcfd_grpc
