/* SPDX-License-Identifier: MIT */
/*
 * grpc_upload.cc - the uploads of the gRPC door's Smooth and SubmitJob
 * (grpc_internal.h): a streaming call's place among the door's (Slot:
 * --max-connections and --max-connections-per-ip bound streaming calls),
 * and the bytes as they stream in (Upload: the header parsed into the
 * job's parameters, every size checked before a byte is kept, the
 * upload's deadlines armed for the door's expire).
 */
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "grpc_internal.h"

namespace mcfd_grpc {

Slot::~Slot()
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
bool Slot::take(CallbackServerContext *ctx, Status *st)
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

Upload::~Upload()
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
bool Upload::feed(grpc::ByteBuffer *b, svc_error *e)
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
bool Upload::feed(const pb::SmoothRequest &m, svc_error *e)
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
int Upload::submit(bool keep_result, svc_job **out, svc_error *e)
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
    rq_.measures = keep_result; /* Smooth's reply carries the metrics */
    mesh_ = target_ = nullptr;
    int rc = svc_submit(g.svc, &rq_, out, e);
    svc_upload_release(g.svc, &mem_held_);   /* the bytes are in the store, or gone */
    return rc;
}

/* The upload's deadlines start now: --header-timeout for the header,
 * --body-timeout for the whole upload (the door's expire). */
void Upload::arm(Expirable *call)
{
    dl_ = std::make_shared<Deadline>();
    dl_->call = call;
    dl_->started = srv_mono();
    std::lock_guard<std::mutex> l(g.umu);
    g.uploads.insert(dl_);
}

/* The upload is whole, or the call ends: no deadline from now on.
 * Never with a lock held that expire() takes. */
void Upload::disarm()
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

bool Upload::header(const pb::SmoothHeader &h, svc_error *e)
{
    const api_limits *lim = &g.cfg->svc.lim;
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
        /* the mesh and the target share --max-upload, as on REST */
        if (h.target_size() > lim->max_input_bytes - (size_t)(total_size_ > 0 ? total_size_ : 0))
            return limit(e, "target_size %llu and total_size %lld together are over the upload "
                         "limit of %zu bytes (--max-upload: the mesh and the target together)",
                         (unsigned long long)h.target_size(), total_size_ > 0 ? total_size_ : 0,
                         lim->max_input_bytes);
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
    phases_ = h.phases();
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

std::string Upload::basename_of(const std::string &n)
{
    size_t k = n.find_last_of("/\\");
    std::string b = k == std::string::npos ? n : n.substr(k + 1);
    std::string s;
    for (char c : b)
        if ((unsigned char)c >= 0x20 && c != 0x7f && c != '"')
            s += c;
    return s.empty() ? "mesh" : s;
}

bool Upload::append(char **buf, size_t *len, long long declared, const std::string &b,
                    const char *what, svc_error *e)
{
    size_t max = g.cfg->svc.lim.max_input_bytes;
    if (b.size() > max - *len)
        return limit(e, "the %s is over the upload limit of %zu bytes (--max-upload)", what, max);
    if (b.size() > max - (mesh_len_ + target_len_))
        return limit(e, "the mesh and the target together are over the upload limit of %zu "
                     "bytes (--max-upload)", max);
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

bool Upload::fail(svc_error *e, svc_problem p, const char *fmt, ...)
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
bool Upload::limit(svc_error *e, const char *fmt, ...)
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

} // namespace mcfd_grpc
