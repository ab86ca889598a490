/* SPDX-License-Identifier: MIT */
/*
 * grpc.cc - the gRPC door of mcfd behind grpc_door.h: start (gRPC's
 * server without a listening port, fed by the gate, h2gate.c), drain,
 * stop, the expiry of late uploads and stalled answers, health and
 * gauges. The calls and what they share: grpc_internal.h; the door's
 * state, g: grpc_state.cc.
 */
#include <chrono>
#include <cstdio>
#include <cstring>
#include <vector>

#include <unistd.h>

#include <grpc/compression.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/resource_quota.h>
#include <grpcpp/server_posix.h>

#include "grpc_internal.h"
#include "grpc_door.h"
#include "h2gate.h"

using namespace mcfd_grpc;

namespace {

const char kService[] = "mcfd.v1.Smoother";

/* The gate's bounds on streams (h2gate_limits.h; measured: README, reliability).
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
        b.RegisterService(smoother_service());
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
        b.SetMaxReceiveMessageSize((int)(kChunk + cfg->svc.lim.max_json_bytes + 4096));
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

extern "C" const srv_door_ops mcfd_grpc_door = {
    "gRPC", grpc_start, grpc_drain, grpc_stop, grpc_expire, grpc_active,
    grpc_health, grpc_gauges,
};
