#include "worker/worker.h"

#include <signal.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

#include "io/xdmf.h"
#include "rpc/rpc.h"
#include "worker/checkpoints.h"
#include "worker/file_upload.h"
#include "worker/job_runner.h"
#include "worker/reporter.h"

namespace cellflow::worker {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

std::string host_name() {
  char buffer[256] = {0};
  if (::gethostname(buffer, sizeof buffer - 1) != 0) return "localhost";
  return buffer;
}

using rpc::seconds_to_ms;

}  // namespace

std::unique_ptr<v1::WorkerService::StubInterface> Worker::connect(const std::string& address,
                                                                  const rpc::ChannelOptions& channel) {
  // The channel reconnects quickly after a server restart (rpc::ChannelOptions).
  return v1::WorkerService::NewStub(rpc::make_channel(address, channel));
}

Worker::Worker(WorkerOptions options) : Worker(options, connect(options.server_address, options.channel)) {}

Worker::Worker(WorkerOptions options, std::unique_ptr<v1::WorkerService::StubInterface> stub)
    : options_(std::move(options)), stub_(std::move(stub)) {
  id_ = options_.name + "@" + host_name() + ":" + std::to_string(::getpid());
  if (options_.scratch_dir.empty()) {
    own_scratch_ = true;
    options_.scratch_dir =
        (fs::temp_directory_path() / ("cellflow-worker-" + std::to_string(::getpid()))).string();
  }
}

void Worker::stop() {
  std::lock_guard lock(lease_call_mutex_);
  stop_.store(true);
  if (lease_call_ != nullptr) lease_call_->TryCancel();
}

bool Worker::sleep_unless_stopped(std::chrono::milliseconds duration) {
  const auto end = Clock::now() + duration;
  while (Clock::now() < end) {
    if (stop_.load()) return false;
    std::this_thread::sleep_for(std::min<std::chrono::milliseconds>(50ms, duration));
  }
  return !stop_.load();
}

void Worker::remove_stale_scratch() {
  const fs::path parent = fs::path(options_.scratch_dir).parent_path();
  const std::string prefix = "cellflow-worker-";
  std::error_code error;
  for (fs::directory_iterator it(parent, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0 || name.size() == prefix.size() || name.size() > prefix.size() + 9)
      continue;
    const std::string digits = name.substr(prefix.size());
    if (digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(digits));
    if (pid <= 0 || pid == ::getpid()) continue;
    // Only a pid that no longer exists (ESRCH); another user's live worker gives EPERM.
    if (::kill(pid, 0) == 0 || errno != ESRCH) continue;
    std::error_code ignored;
    if (fs::remove_all(it->path(), ignored) > 0) spdlog::info("removed stale scratch directory {}", name);
  }
}

int Worker::run() {
  std::error_code error;
  if (own_scratch_) remove_stale_scratch();
  fs::create_directories(options_.scratch_dir, error);
  if (error) {
    spdlog::error("cannot create scratch directory {}: {}", options_.scratch_dir, error.message());
    return 1;
  }
  spdlog::info("worker {} serving {} (scratch {})", id_, options_.server_address, options_.scratch_dir);
  int attempts = 0;
  auto idle_since = Clock::now();
  rpc::Backoff backoff(100ms, 5000ms);
  while (!stop_.load()) {
    if (options_.max_jobs > 0 && attempts >= options_.max_jobs) break;
    if (options_.idle_exit_s > 0 && Clock::now() - idle_since > seconds_to_ms(options_.idle_exit_s, 0ms)) {
      spdlog::info("idle for {} s; exiting", options_.idle_exit_s);
      break;
    }
    v1::LeaseJobRequest request;
    request.set_worker_id(id_);
    // Short polls so that a stop request is seen within a second.
    request.set_wait_s(std::min(options_.lease_wait_s, 1.0));
    v1::LeaseJobResponse response;
    grpc::ClientContext context;
    const auto asked = Clock::now();
    rpc::set_deadline(context, seconds_to_ms(request.wait_s() + 10.0, 10s));
    {
      // Registered under the lock that stop() takes: a stop either comes
      // before (seen here, no call) or cancels this call.
      std::lock_guard lock(lease_call_mutex_);
      if (stop_.load()) break;
      lease_call_ = &context;
    }
    const grpc::Status status = stub_->LeaseJob(&context, request, &response);
    {
      std::lock_guard lock(lease_call_mutex_);
      lease_call_ = nullptr;
    }
    if (stop_.load()) {
      // Stopped while polling: a lease that came anyway goes back unrun.
      if (status.ok() && response.found()) {
        spdlog::info("{}: leased as the worker stopped; handing it back unrun", response.lease().job_id());
        hand_back(response.lease());
      }
      break;
    }
    if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED ||
        status.error_code() == grpc::StatusCode::PERMISSION_DENIED) {
      // Retrying cannot help: the credential is missing, wrong or revoked.
      spdlog::error("LeaseJob refused: {} (set CELLFLOW_WORKER_TOKEN or --token-file to a worker token)",
                    status.error_message());
      return 2;
    }
    if (!status.ok()) {
      if (status.error_code() != grpc::StatusCode::UNAVAILABLE &&
          status.error_code() != grpc::StatusCode::DEADLINE_EXCEEDED) {
        spdlog::error("LeaseJob: {} ({})", status.error_message(), static_cast<int>(status.error_code()));
      }
      sleep_unless_stopped(backoff.next());
      continue;
    }
    backoff.reset();
    if (!response.found()) {
      // A server that answers at once (it is shutting down) is not polled in a tight loop.
      if (Clock::now() - asked < 100ms) sleep_unless_stopped(250ms);
      continue;
    }
    ++attempts;
    run_attempt(response);
    idle_since = Clock::now();
  }
  spdlog::info("worker {} stopped after {} attempt(s)", id_, attempts);
  std::error_code ignored;
  if (own_scratch_ && !options_.keep_results) {
    fs::remove_all(options_.scratch_dir, ignored);
  } else if (!options_.keep_results) {
    fs::remove(options_.scratch_dir, ignored);  // only if empty
  }
  return 0;
}

bool Worker::hand_back(const v1::Lease& lease) {
  v1::ReleaseJobRequest request;
  *request.mutable_lease() = lease;
  request.set_reason("worker " + id_ + " stopped");
  // Tried again while the server is UNAVAILABLE, for a few seconds (the worker is stopping).
  rpc::RetryOptions release_retry;
  release_retry.deadline = 2s;
  release_retry.max_attempts = 0;
  release_retry.give_up_after = 4s;
  release_retry.initial_backoff = 100ms;
  release_retry.max_backoff = 1000ms;
  const grpc::Status status = rpc::call_with_retry(release_retry, [&](grpc::ClientContext& context) {
    v1::FinishJobResponse response;
    return stub_->ReleaseJob(&context, request, &response);
  });
  if (status.ok()) {
    spdlog::info("{}: handed back", lease.job_id());
  } else {
    spdlog::warn(
        "{}: hand-back failed ({}); the server requeues the job when the lease expires or it restarts",
        lease.job_id(), status.error_message());
  }
  return status.ok();
}

Status Worker::fetch_mesh(v1::JobSpec& spec, const v1::Lease& lease) {
  // Every cell of the scene (a suspension has one per kind).
  for (const jobs::SceneCell& scene_cell : jobs::scene_cells(spec)) {
    if (Status s = fetch_cell_mesh(scene_cell.cell, scene_cell.field + ".", lease); !s.ok()) return s;
  }
  return {};
}

Status Worker::fetch_cell_mesh(v1::CellSpec* cell, const std::string& field, const v1::Lease& lease) {
  if (!cell->mesh_file().empty()) {
    return invalid_argument(field +
                            "mesh_file: a worker reads no file a job names; upload the mesh and set " +
                            field + "mesh_sha256");
  }
  cell->clear_mesh_bytes();
  if (cell->mesh_sha256().empty()) return {};
  constexpr std::size_t kMaxMeshBytes = std::size_t{1} << 30;  // the server's limit is far lower
  std::string bytes;
  rpc::RetryOptions retry;
  retry.deadline = 60s;
  retry.max_attempts = 5;
  const grpc::Status status = rpc::call_with_retry(retry, [&](grpc::ClientContext& context) {
    bytes.clear();
    v1::FetchMeshRequest request;
    *request.mutable_lease() = lease;
    request.set_sha256(cell->mesh_sha256());
    auto reader = stub_->FetchMesh(&context, request);
    v1::MeshChunk chunk;
    while (reader->Read(&chunk)) {
      if (bytes.size() + chunk.data().size() > kMaxMeshBytes) {
        context.TryCancel();
        break;
      }
      bytes += chunk.data();
    }
    return reader->Finish();
  });
  if (!status.ok()) {
    return Status(StatusCode::kFailedPrecondition,
                  field + "mesh_sha256: cannot fetch the uploaded mesh: " + status.error_message());
  }
  cell->set_mesh_bytes(std::move(bytes));
  return {};
}

void Worker::run_attempt(const v1::LeaseJobResponse& leased) {
  const v1::Lease& lease = leased.lease();
  const std::string& job = lease.job_id();
  spdlog::info("{}: attempt {}{}", job, lease.attempt(),
               leased.spec().name().empty() ? "" : " \"" + leased.spec().name() + "\"");
  const auto ttl = seconds_to_ms(leased.lease_ttl_s(), 10s);
  Reporter reporter(*stub_, lease, seconds_to_ms(leased.heartbeat_interval_s(), 250ms), ttl);
  reporter.start();

  const auto started = Clock::now();
  auto last_progress = Clock::now() - 1h;
  double last_fraction = -1.0;
  JobEvents events;
  events.force_sample = [&](const v1::ForceSample& sample) {
    v1::WorkerReport report;
    *report.mutable_force_sample() = sample;
    reporter.send(std::move(report));
  };
  events.deformation_sample = [&](const v1::DeformationSample& sample) {
    v1::WorkerReport report;
    *report.mutable_deformation_sample() = sample;
    reporter.send(std::move(report));
  };
  events.suspension_sample = [&](const v1::SuspensionSample& sample) {
    v1::WorkerReport report;
    *report.mutable_suspension_sample() = sample;
    reporter.send(std::move(report));
  };
  events.progress = [&](double fraction, const std::string& stage) {
    // At most five progress reports a second; the first and the last always.
    const auto now = Clock::now();
    if (fraction == last_fraction) return;
    if (now - last_progress < 200ms && fraction < 1.0 && fraction > 0.0) return;
    last_progress = now;
    last_fraction = fraction;
    const double elapsed = std::chrono::duration<double>(now - started).count();
    v1::WorkerReport report;
    auto* progress = report.mutable_progress();
    progress->set_fraction_done(fraction);
    progress->set_elapsed_s(elapsed);
    // Remaining time from the rate so far; unknown (-1) before the first progress.
    progress->set_estimated_remaining_s(fraction > 0.0 ? elapsed * (1.0 - fraction) / fraction : -1.0);
    progress->set_stage(stage);
    reporter.send(std::move(report));
  };
  events.should_stop = [&] { return reporter.should_stop() || stop_.load(); };
  // Stopping to hand the job back: a flow job first checkpoints at its next sample.
  events.checkpoint_before_stop = [&] { return stop_.load() && !reporter.should_stop(); };

  const std::string stem = job + ".attempt-" + std::to_string(lease.attempt());
  const fs::path temporary = fs::path(options_.scratch_dir) / (stem + ".h5.tmp");
  const fs::path result = fs::path(options_.scratch_dir) / (stem + ".h5");
  const fs::path sidecar = fs::path(options_.scratch_dir) / (stem + ".xdmf");
  RunOptions run_options;
  run_options.result_path = temporary.string();
  run_options.threads = options_.threads;
  run_options.debug_delay_per_point_ms = options_.debug_delay_per_point_ms;
  run_options.library_dir = options_.library_dir;
  // Checkpoint and restart (flow jobs; other scenes ignore it).
  const fs::path checkpoint = fs::path(options_.scratch_dir) / (stem + ".ckpt");
  const fs::path resume = fs::path(options_.scratch_dir) / (stem + ".resume.ckpt");
  if (options_.checkpoint_interval_s > 0.0) {
    run_options.checkpoint_interval_s = options_.checkpoint_interval_s;
    run_options.checkpoint_path = checkpoint.string();
  }
  if (leased.has_checkpoint()) {
    const v1::CheckpointInfo& info = leased.checkpoint();
    const auto fetch_started = Clock::now();
    if (Status fetched = fetch_checkpoint(*stub_, lease, info, resume.string()); fetched.ok()) {
      run_options.resume_path = resume.string();
      spdlog::info(
          "{}: resuming from the checkpoint of attempt {} after step {} (sample {}, {} bytes, "
          "fetched in {:.2f} s)",
          job, info.attempt(), info.time_step(), info.last_sample_index(), info.size_bytes(),
          std::chrono::duration<double>(Clock::now() - fetch_started).count());
    } else {
      spdlog::warn("{}: checkpoint not fetched ({}); running from the start", job, fetched.to_string());
    }
  }
  events.checkpoint_written = [&](const jobs::CheckpointWritten& written) {
    if (!written.error.empty()) {
      spdlog::warn("{}: checkpoint not written: {}", job, written.error);
      return;
    }
    const auto upload_started = Clock::now();
    const Status uploaded = upload_checkpoint(*stub_, lease, written);
    const double upload_s = std::chrono::duration<double>(Clock::now() - upload_started).count();
    if (uploaded.ok()) {
      spdlog::info(
          "{}: checkpoint after step {} (sample {}): {} bytes, written in {:.3f} s, uploaded in {:.3f} s",
          job, written.time_step, written.last_sample_index, written.bytes, written.seconds, upload_s);
    } else {
      spdlog::warn("{}: checkpoint after step {} not uploaded: {}", job, written.time_step,
                   uploaded.to_string());
    }
  };
  // The spec runs with its uploaded mesh's bytes; the result records the spec as leased.
  v1::JobSpec spec = leased.spec();
  RunOutcome outcome;
  if (Status fetched = fetch_mesh(spec, lease); fetched.ok()) {
    outcome = run_job(registry_, spec, leased.spec(), run_options, events);
  } else {
    outcome.status = fetched;
  }
  if (outcome.resumed_from_step >= 0) {
    spdlog::info("{}: resumed after step {}", job, outcome.resumed_from_step);
  } else if (!outcome.resume_refused.empty()) {
    spdlog::warn("{}: {}; ran from the start", job, outcome.resume_refused);
  }

  // Every sample reaches the server before the attempt ends.
  reporter.close(ttl);
  std::error_code ignored;
  auto cleanup = [&] {
    fs::remove(checkpoint, ignored);
    fs::remove(checkpoint.string() + ".tmp", ignored);
    fs::remove(resume, ignored);
    fs::remove(temporary, ignored);
    if (!options_.keep_results) fs::remove(result, ignored);
    if (!options_.keep_results) fs::remove(sidecar, ignored);
  };
  if (reporter.cancelled()) {
    spdlog::info("{}: cancelled; stopped after {} sample(s)", job, outcome.samples);
    cleanup();
    return;
  }
  if (reporter.lease_lost()) {
    spdlog::warn("{}: lease lost; abandoning attempt {}", job, lease.attempt());
    cleanup();
    return;
  }
  if (stop_.load() && outcome.status.code() == StatusCode::kCancelled) {
    hand_back(lease);
    cleanup();
    return;
  }

  // Upload the result (also the partial one of a failed run), then end the attempt.
  const bool have_file = outcome.result_written || (!outcome.status.ok() && fs::exists(temporary, ignored));
  if (have_file) fs::rename(temporary, result, ignored);
  // The XDMF sidecar for ParaView, naming the file as the server serves it
  // (job-<n>.h5); a result without cell frames or fields has none.
  bool have_sidecar = false;
  if (have_file) {
    if (auto xml = io::xdmf_for(result.string(), "cell", "./" + job + ".h5"); xml.ok()) {
      std::ofstream out(sidecar, std::ios::binary | std::ios::trunc);
      out << *xml;
      have_sidecar = static_cast<bool>(out);
    }
  }
  // The upload and the terminal calls are tried again while the server is
  // UNAVAILABLE, for at most the lease time (waits of 0.1, 0.2, ... 2 s).
  rpc::RetryOptions retry;
  retry.max_attempts = 0;
  retry.give_up_after = ttl;
  retry.initial_backoff = 100ms;
  retry.max_backoff = 2000ms;
  rpc::RetryOptions upload_retry = retry;
  upload_retry.deadline = 10min;
  rpc::RetryOptions end_retry = retry;
  end_retry.deadline = 30s;

  auto upload_part = [&](grpc::ClientContext& context, const fs::path& path,
                         v1::ResultPart part) -> grpc::Status {
    v1::UploadResultResponse response;
    return upload_file_chunks<v1::UploadChunk>(stub_->UploadResult(&context, &response), path, "result file",
                                               [&](v1::UploadChunk& chunk) {
                                                 *chunk.mutable_lease() = lease;
                                                 chunk.set_part(part);
                                               });
  };
  // The sidecar first: the HDF5 upload is what FinishJob waits for, and the
  // server adopts the sidecar with it. A lost sidecar only costs the download.
  auto upload_with_retry = [&] {
    if (have_sidecar) {
      const grpc::Status sent = rpc::call_with_retry(upload_retry, [&](grpc::ClientContext& context) {
        return upload_part(context, sidecar, v1::RESULT_PART_XDMF);
      });
      if (!sent.ok()) spdlog::warn("{}: XDMF sidecar upload failed: {}", job, sent.error_message());
    }
    return rpc::call_with_retry(upload_retry, [&](grpc::ClientContext& context) {
      return upload_part(context, result, v1::RESULT_PART_HDF5);
    });
  };
  auto finish = [&](const v1::FinishJobRequest& request) {
    return rpc::call_with_retry(end_retry, [&](grpc::ClientContext& context) {
      v1::FinishJobResponse response;
      return stub_->FinishJob(&context, request, &response);
    });
  };
  auto fail = [&](const v1::FailJobRequest& request) {
    return rpc::call_with_retry(end_retry, [&](grpc::ClientContext& context) {
      v1::FinishJobResponse response;
      return stub_->FailJob(&context, request, &response);
    });
  };

  grpc::Status uploaded =
      have_file ? upload_with_retry() : grpc::Status(grpc::StatusCode::NOT_FOUND, "no result");
  if (outcome.status.ok()) {
    if (!uploaded.ok()) spdlog::error("{}: upload failed: {}", job, uploaded.error_message());
    v1::FinishJobRequest request;
    *request.mutable_lease() = lease;
    grpc::Status finished = finish(request);
    if (finished.error_code() == grpc::StatusCode::FAILED_PRECONDITION &&
        finished.error_message().find("no result uploaded") != std::string::npos) {
      // The upload was lost (e.g. across a server restart): once more.
      if (upload_with_retry().ok()) finished = finish(request);
    }
    spdlog::info("{}: finished {} ({} sample(s), {:.2f} s)", job,
                 finished.ok() ? "ok" : finished.error_message(), outcome.samples,
                 std::chrono::duration<double>(Clock::now() - started).count());
  } else {
    v1::FailJobRequest request;
    *request.mutable_lease() = lease;
    request.set_reason(outcome.status.to_string());
    const grpc::Status failed = fail(request);
    spdlog::warn("{}: failed: {} (reported: {})", job, outcome.status.to_string(),
                 failed.ok() ? "ok" : failed.error_message());
  }
  cleanup();
}

}  // namespace cellflow::worker
