// Who is calling: the identity an authenticated call carries into the
// service logic (server/job_service.h). No gRPC here.
#pragma once

#include <string>

namespace cellflow::server {

struct Identity {
  std::string user;     // the owner of the jobs this identity submits
  bool admin = false;   // sees and manages every user's jobs
  bool worker = false;  // a worker credential (worker API only)

  // The single user of `--auth none` (loopback only) and of in-process
  // callers such as the unit tests: user "local", admin.
  static Identity local() { return {"local", true, false}; }
  // True when this identity may see a job owned by `owner`.
  bool sees(const std::string& owner) const { return admin || owner == user; }
};

}  // namespace cellflow::server
