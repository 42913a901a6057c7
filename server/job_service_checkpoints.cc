// Checkpoints of running flow jobs: upload (fenced, bounded, atomic
// replacement of checkpoints/job-N.ckpt), the announcement in LeaseJob, the
// fetch by a re-leased attempt, and removal when the job ends or is deleted.
// The bytes are opaque here: the scene validates them when it resumes.
#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <vector>

#include "server/job_service.h"

namespace cellflow::server {

namespace fs = std::filesystem;

namespace {

Status sync_directory_of(const fs::path& file) {
  const int fd = ::open(file.parent_path().c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return {StatusCode::kInternal, "cannot open directory " + file.parent_path().string()};
  ::fsync(fd);
  ::close(fd);
  return {};
}

}  // namespace

fs::path JobService::checkpoint_path(std::int64_t job_id) const {
  return options_.data_dir / "checkpoints" / (job_name(job_id) + ".ckpt");
}

fs::path JobService::checkpoint_upload_path(const v1::Lease& lease) const {
  auto id = parse_job_name(lease.job_id());
  // The token keeps two attempts (or a stale worker) from sharing a file.
  return options_.data_dir / "checkpoints" /
         (job_name(id.value_or(0)) + ".attempt-" + std::to_string(lease.attempt()) + "." +
          lease.lease_token().substr(0, 32) + ".ckpt.part");
}

StatusOr<std::unique_ptr<ResultUpload>> JobService::begin_checkpoint_upload(const v1::Lease& lease) {
  auto id = parse_job_name(lease.job_id());
  if (!id) return invalid_argument("lease.job_id: \"" + lease.job_id() + "\" is not a job id (job-<n>)");
  auto check = store_.check_lease(*id, lease.lease_token());
  if (!check.ok()) return check.status();
  if (*check != LeaseCheck::kValid)
    return Status(StatusCode::kFailedPrecondition, "lease lost: checkpoint refused");
  auto job = store_.get(*id);
  if (!job.ok()) return job.status();
  double limit = static_cast<double>(options_.max_checkpoint_bytes);
  if (!(limit > 0.0)) {
    limit = options_.upload_memory_factor * static_cast<double>(job->estimated_memory_bytes()) +
            static_cast<double>(options_.upload_slack_bytes);
  }
  const fs::path path = checkpoint_upload_path(lease);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status(StatusCode::kInternal, "cannot create the checkpoint upload file");
  return std::make_unique<ResultUpload>(path, fd, static_cast<std::int64_t>(std::min(limit, 9e18)));
}

StatusOr<std::int64_t> JobService::commit_checkpoint(const v1::Lease& lease, const v1::CheckpointInfo& info,
                                                     ResultUpload& upload) {
  auto id = parse_job_name(lease.job_id());
  if (!id) return invalid_argument("lease.job_id: not a job id");
  const fs::path part = checkpoint_upload_path(lease);
  std::error_code error;
  auto drop = [&] { fs::remove(part, error); };
  auto size = upload.complete();
  if (!size.ok()) {
    drop();
    return size.status();
  }
  if (*size <= 0) {
    drop();
    return invalid_argument("checkpoint: empty upload");
  }
  if (info.time_step() <= 0 || info.last_sample_index() < 0) {
    drop();
    return invalid_argument("info: time_step must be > 0 and last_sample_index >= 0");
  }
  const std::int64_t bound = max_sample_index(*id);
  if (bound >= 0 && info.last_sample_index() > bound) {
    drop();
    return invalid_argument("info.last_sample_index: " + std::to_string(info.last_sample_index()) +
                            " outside the job's range [0, " + std::to_string(bound) + "]");
  }
  CheckpointRecord record;
  record.attempt = lease.attempt();
  record.time_step = info.time_step();
  record.last_sample_index = info.last_sample_index();
  record.size_bytes = *size;
  record.time_ms = now();
  const fs::path target = checkpoint_path(*id);
  Status saved = store_.save_checkpoint(*id, lease.lease_token(), record, [&]() -> Status {
    std::error_code moved;
    fs::rename(part, target, moved);  // replaces the previous checkpoint atomically
    if (moved)
      return Status(StatusCode::kInternal, "cannot move the checkpoint into place: " + moved.message());
    return sync_directory_of(target);
  });
  if (!saved.ok()) {
    drop();
    return saved;
  }
  spdlog::info("{}: checkpoint of attempt {} after step {} (sample {}, {} bytes)", job_name(*id),
               lease.attempt(), info.time_step(), info.last_sample_index(), *size);
  return *size;
}

void JobService::describe_checkpoint(std::int64_t job_id, v1::LeaseJobResponse& response) {
  auto record = store_.checkpoint(job_id);
  if (!record.ok() || !record->has_value()) return;
  std::error_code error;
  const fs::path path = checkpoint_path(job_id);
  const auto size = fs::file_size(path, error);
  if (error || static_cast<std::int64_t>(size) != (*record)->size_bytes) {
    spdlog::warn("{}: checkpoint record without its file; dropped", job_name(job_id));
    (void)store_.delete_checkpoint(job_id);
    return;
  }
  v1::CheckpointInfo* info = response.mutable_checkpoint();
  info->set_size_bytes((*record)->size_bytes);
  info->set_attempt((*record)->attempt);
  info->set_time_step((*record)->time_step);
  info->set_last_sample_index((*record)->last_sample_index);
}

Status JobService::fetch_checkpoint(const v1::FetchCheckpointRequest& request,
                                    const std::function<bool(const v1::CheckpointChunk&)>& send) {
  auto id = parse_job_name(request.lease().job_id());
  if (!id) return invalid_argument("lease.job_id: not a job id");
  auto check = store_.check_lease(*id, request.lease().lease_token());
  if (!check.ok()) return check.status();
  if (*check != LeaseCheck::kValid)
    return Status(StatusCode::kFailedPrecondition, "lease lost: fetch refused");
  auto record = store_.checkpoint(*id);
  if (!record.ok()) return record.status();
  if (!record->has_value()) return Status(StatusCode::kNotFound, job_name(*id) + " has no checkpoint");
  std::ifstream in(checkpoint_path(*id), std::ios::binary);
  if (!in) return Status(StatusCode::kNotFound, job_name(*id) + " has no checkpoint file");
  std::vector<char> buffer(options_.download_chunk_bytes);
  std::int64_t offset = 0;
  bool first = true;
  while (offset < (*record)->size_bytes) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in.gcount();
    if (n <= 0) break;
    v1::CheckpointChunk chunk;
    if (first) {
      v1::CheckpointInfo* info = chunk.mutable_info();
      info->set_size_bytes((*record)->size_bytes);
      info->set_attempt((*record)->attempt);
      info->set_time_step((*record)->time_step);
      info->set_last_sample_index((*record)->last_sample_index);
    }
    first = false;
    chunk.set_offset(offset);
    chunk.set_data(buffer.data(), static_cast<std::size_t>(n));
    if (!send(chunk)) return {StatusCode::kCancelled, "the worker went away"};
    offset += n;
  }
  return {};
}

void JobService::remove_checkpoint(std::int64_t job_id) {
  std::error_code error;
  const bool had_file = fs::remove(checkpoint_path(job_id), error);
  (void)store_.delete_checkpoint(job_id);
  const std::string prefix = job_name(job_id) + ".attempt-";
  for (fs::directory_iterator it(options_.data_dir / "checkpoints", error), end; !error && it != end;
       it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) == 0 && name.ends_with(".ckpt.part")) {
      std::error_code ignored;
      fs::remove(it->path(), ignored);
    }
  }
  if (had_file) spdlog::info("{}: checkpoint removed", job_name(job_id));
}

}  // namespace cellflow::server
