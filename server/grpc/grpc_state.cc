/* SPDX-License-Identifier: MIT */
/*
 * grpc_state.cc - the gRPC door's state, g (grpc_internal.h's Door: a
 * process singleton by design). Its own file so that every file of the
 * door reads it from a leaf: grpc.cc starts and stops the calls
 * (grpc_calls.cc, grpc_follow.cc), which read g and never call grpc.cc.
 */
#include "grpc_internal.h"

namespace mcfd_grpc {

Door g;

} // namespace mcfd_grpc
