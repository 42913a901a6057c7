// Exit codes of the `cellflow` CLI, for scripts. Listed in `cellflow --help`.
#pragma once

#include <grpcpp/support/status.h>

#include "cellflow/v1/service.pb.h"

namespace cellflow::client {

enum ExitCode : int {
  kExitOk = 0,               // done; for watch/--watch: the job SUCCEEDED
  kExitUsage = 1,            // bad command line
  kExitInvalidArgument = 2,  // the server refused the request (invalid spec, too large, wrong state)
  kExitFailed = 3,           // the job FAILED (or the server failed internally)
  kExitCancelled = 4,        // the job was CANCELLED
  kExitNotFound = 5,         // no such job or result
  kExitUnavailable = 6,      // the server could not be reached
  kExitDenied = 7,           // no valid token (UNAUTHENTICATED) or not allowed (PERMISSION_DENIED)
};

inline constexpr const char* kExitCodeHelp =
    "Exit codes: 0 succeeded, 1 usage, 2 invalid argument (spec refused), 3 job failed, 4 job cancelled, "
    "5 not found, 6 server unreachable, 7 not authenticated or not allowed.";

inline int exit_code_for(const grpc::Status& status) {
  switch (status.error_code()) {
    case grpc::StatusCode::OK:
      return kExitOk;
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::OUT_OF_RANGE:
      return kExitInvalidArgument;
    case grpc::StatusCode::NOT_FOUND:
      return kExitNotFound;
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return kExitUnavailable;
    case grpc::StatusCode::CANCELLED:
      return kExitCancelled;
    case grpc::StatusCode::UNAUTHENTICATED:
    case grpc::StatusCode::PERMISSION_DENIED:
      return kExitDenied;
    default:
      return kExitFailed;
  }
}

inline int exit_code_for(v1::Job::State state) {
  switch (state) {
    case v1::Job::SUCCEEDED:
      return kExitOk;
    case v1::Job::CANCELLED:
      return kExitCancelled;
    default:
      return kExitFailed;
  }
}

}  // namespace cellflow::client
