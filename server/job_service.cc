#include "server/job_service.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <system_error>
#include <vector>

#include "jobs/fit/fit_library.h"
#include "jobs/fit/fit_spec.h"
#include "jobs/registry.h"
#include "jobs/study/study.h"
#include "server/encoding.h"

namespace cellflow::server {

namespace fs = std::filesystem;

namespace {

std::int64_t system_now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

StatusOr<std::int64_t> parse_id(const std::string& job_id, const char* field) {
  auto id = parse_job_name(job_id);
  if (!id) return invalid_argument(std::string(field) + ": \"" + job_id + "\" is not a job id (job-<n>)");
  return *id;
}

// HDF5's format signature, at offset 0 or a power of two from 512 (a user block).
bool has_hdf5_signature(const fs::path& path) {
  static constexpr std::array<unsigned char, 8> kSignature = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  std::ifstream in(path, std::ios::binary);
  for (std::int64_t offset : {0LL, 512LL, 1024LL, 2048LL, 4096LL}) {
    std::array<unsigned char, 8> head{};
    in.clear();
    in.seekg(offset);
    if (!in.read(reinterpret_cast<char*>(head.data()), head.size())) return false;
    if (head == kSignature) return true;
  }
  return false;
}

Status sync_directory(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return {StatusCode::kInternal, "cannot open directory " + dir.string()};
  ::fsync(fd);
  ::close(fd);
  return {};
}

}  // namespace

std::string sanitize_text(const std::string& text, std::size_t max_bytes) {
  static const std::string kReplacement = "\xEF\xBF\xBD";  // U+FFFD
  std::string out;
  out.reserve(std::min(text.size(), max_bytes));
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  std::size_t i = 0;
  bool cut = false;
  while (i < n) {
    const unsigned char c = p[i];
    std::size_t length = 0;
    std::uint32_t code = 0;
    if (c < 0x80) {
      length = 1;
      code = c;
    } else if ((c & 0xE0) == 0xC0) {
      length = 2;
      code = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      length = 3;
      code = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      length = 4;
      code = c & 0x07;
    }
    bool valid = length > 0 && i + length <= n;
    for (std::size_t k = 1; valid && k < length; ++k) {
      valid = (p[i + k] & 0xC0) == 0x80;
      code = (code << 6) | (p[i + k] & 0x3F);
    }
    // Overlong forms, surrogates and code points past U+10FFFF are invalid too.
    if (valid) {
      static constexpr std::uint32_t kMin[] = {0, 0, 0x80, 0x800, 0x10000};
      valid = code >= kMin[length] && code <= 0x10FFFF && !(code >= 0xD800 && code <= 0xDFFF);
    }
    // Control characters other than tab and newline become spaces.
    const std::string piece = !valid ? kReplacement
                              : (code < 0x20 && code != '\t' && code != '\n') || code == 0x7F
                                  ? std::string(" ")
                                  : text.substr(i, length);
    if (out.size() + piece.size() > max_bytes) {
      cut = true;
      break;
    }
    out += piece;
    i += valid ? length : 1;
  }
  if (cut) {
    while (!out.empty() && out.size() + 3 > max_bytes) {
      // Drop whole characters: continuation bytes and then their lead byte.
      while (!out.empty() && (static_cast<unsigned char>(out.back()) & 0xC0) == 0x80) out.pop_back();
      if (!out.empty()) out.pop_back();
    }
    if (max_bytes >= 3) out += "...";
  }
  return out;
}

std::string encode_page_token(std::int64_t after_id, v1::Job::State state, std::int64_t parent_id) {
  std::string text = "v1:" + std::to_string(after_id) + ":" + std::to_string(static_cast<int>(state));
  if (parent_id > 0) text += ":" + std::to_string(parent_id);
  return base64url(text);
}

StatusOr<std::int64_t> decode_page_token(const std::string& token, v1::Job::State state,
                                         std::int64_t parent_id) {
  auto text = unbase64url(token);
  long long after = 0;
  int token_state = 0;
  long long token_parent = 0;
  const int fields =
      text ? std::sscanf(text->c_str(), "v1:%lld:%d:%lld", &after, &token_state, &token_parent) : 0;
  if (fields < 2 || after < 0) {
    return invalid_argument("page_token: not a token this server issued");
  }
  if (token_state != static_cast<int>(state)) {
    return invalid_argument("page_token: belongs to a listing with another state filter");
  }
  if ((fields == 3 ? token_parent : 0) != parent_id) {
    return invalid_argument("page_token: belongs to a listing with another parent_job_id filter");
  }
  return static_cast<std::int64_t>(after);
}

ResultUpload::~ResultUpload() {
  if (fd_ >= 0) ::close(fd_);
  if (!completed_) {
    std::error_code error;
    fs::remove(path_, error);
  }
}

Status ResultUpload::write(std::int64_t offset, const std::string& data) {
  if (offset != size_) {
    return invalid_argument("offset: expected " + std::to_string(size_) + ", got " + std::to_string(offset));
  }
  if (max_bytes_ > 0 && size_ + static_cast<std::int64_t>(data.size()) > max_bytes_) {
    return {StatusCode::kResourceExhausted, "upload: over this job's limit of " + std::to_string(max_bytes_) +
                                                " bytes (a multiple of its memory estimate)"};
  }
  std::size_t written = 0;
  while (written < data.size()) {
    const ssize_t n = ::pwrite(fd_, data.data() + written, data.size() - written, size_ + written);
    if (n < 0) return {StatusCode::kInternal, "cannot write " + path_.string()};
    written += static_cast<std::size_t>(n);
  }
  size_ += static_cast<std::int64_t>(data.size());
  return {};
}

StatusOr<std::int64_t> ResultUpload::complete() {
  if (::fsync(fd_) != 0 || ::close(fd_) != 0) {
    fd_ = -1;
    return Status(StatusCode::kInternal, "cannot sync " + path_.string());
  }
  fd_ = -1;
  completed_ = true;
  return size_;
}

JobService::JobService(Store& store, Notifier& notifier, JobServiceOptions options)
    : store_(store),
      notifier_(notifier),
      options_(std::move(options)),
      meshes_(options_.data_dir / "meshes", options_.max_mesh_bytes) {
  if (!options_.now_ms) options_.now_ms = system_now_ms;
  std::error_code error;
  fs::create_directories(options_.data_dir / "results", error);
  fs::create_directories(options_.data_dir / "checkpoints", error);
}

namespace {

const char* part_extension(v1::ResultPart part) {
  return part == v1::RESULT_PART_XDMF ? ".xdmf" : ".h5";
}

}  // namespace

fs::path JobService::result_path(std::int64_t job_id, v1::ResultPart part) const {
  return options_.data_dir / "results" / (job_name(job_id) + part_extension(part));
}

fs::path JobService::upload_path(const v1::Lease& lease, v1::ResultPart part) const {
  auto id = parse_job_name(lease.job_id());
  // The token keeps two attempts (or a stale worker) from sharing a file.
  return options_.data_dir / "results" /
         (job_name(id.value_or(0)) + ".attempt-" + std::to_string(lease.attempt()) + "." +
          lease.lease_token().substr(0, 32) + part_extension(part) + ".part");
}

void JobService::published(const v1::Job& job) {
  auto id = parse_job_name(job.id());
  if (!id) return;
  notifier_.publish(*id, job.last_sequence());
  if (is_terminal(job.state())) remove_checkpoint(*id);  // no attempt can resume any more
  // A child's change appended a ChildUpdate to its study: wake the study's watchers.
  if (job.parent_job_id().empty()) return;
  if (auto parent = parse_job_name(job.parent_job_id())) {
    if (auto sequence = store_.last_sequence(*parent); sequence.ok()) notifier_.publish(*parent, *sequence);
  }
}

Status JobService::check_visible(std::int64_t id, const Identity& caller) {
  if (caller.admin) return {};
  auto owner = store_.job_owner(id);
  if (!owner.ok()) return owner.status();
  // Another user's job reads as missing: ids of other users' jobs do not leak.
  if (!caller.sees(*owner)) return {StatusCode::kNotFound, "job " + job_name(id) + " not found"};
  return {};
}

StatusOr<std::unique_ptr<jobs::PreparedJob>> JobService::prepare_submitted(const v1::JobSpec& spec) {
  if (spec.name().size() > options_.max_name_bytes) {
    return invalid_argument("name: " + std::to_string(spec.name().size()) + " bytes; at most " +
                            std::to_string(options_.max_name_bytes));
  }
  if (spec.author().size() > options_.max_name_bytes) {
    return invalid_argument("author: " + std::to_string(spec.author().size()) + " bytes; at most " +
                            std::to_string(options_.max_name_bytes));
  }
  if (spec.has_fit() && spec.fit().has_server_library()) {
    return invalid_argument("fit.server_library: set by the server when it leases the fit; not accepted");
  }
  v1::JobSpec resolved = spec;
  // Every cell of the scene (a suspension has one per kind).
  for (const jobs::SceneCell& scene_cell : jobs::scene_cells(resolved)) {
    v1::CellSpec* cell = scene_cell.cell;
    const std::string field = scene_cell.field + ".";
    // A request names no file of the server's or a worker's machine: no
    // stat, no open, nothing about the path in the answer.
    if (!cell->mesh_file().empty()) {
      return invalid_argument(field +
                              "mesh_file: a job of the service cannot name a file; upload the mesh "
                              "(UploadMesh; `cellflow submit --mesh-file` uploads it) and set " +
                              field + "mesh_sha256");
    }
    if (!cell->mesh_bytes().empty()) {
      return invalid_argument(field +
                              "mesh_bytes: not accepted in a submitted spec; upload the mesh "
                              "(UploadMesh) and set " +
                              field + "mesh_sha256");
    }
    if (!cell->mesh_sha256().empty()) {
      if (!is_sha256_hex(cell->mesh_sha256())) {
        return invalid_argument(field + "mesh_sha256: must be 64 lowercase hex digits (MeshRef.sha256)");
      }
      auto bytes = meshes_.get(cell->mesh_sha256());
      if (!bytes.ok()) {
        return invalid_argument(field +
                                "mesh_sha256: no uploaded mesh has this hash; upload it first "
                                "(UploadMesh)");
      }
      cell->set_mesh_bytes(std::move(*bytes));
    }
  }
  return registry_.prepare(resolved);
}

std::int64_t JobService::max_sample_index(std::int64_t job_id) {
  {
    std::lock_guard lock(sample_bounds_mutex_);
    if (auto it = sample_bounds_.find(job_id); it != sample_bounds_.end()) return it->second;
  }
  // A job submitted before this server started: converted once more.
  auto job = store_.get(job_id);
  if (!job.ok()) return -1;
  auto prepared = prepare_submitted(job->spec());
  const std::int64_t bound = prepared.ok() ? (*prepared)->max_sample_index() : -1;
  std::lock_guard lock(sample_bounds_mutex_);
  sample_bounds_[job_id] = bound;
  return bound;
}

void JobService::remove_uploads(std::int64_t job_id) {
  const std::string prefix = job_name(job_id) + ".attempt-";
  std::error_code error;
  for (fs::directory_iterator it(options_.data_dir / "results", error), end; !error && it != end;
       it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) == 0 && name.size() > 5 && name.ends_with(".part")) {
      std::error_code ignored;
      fs::remove(it->path(), ignored);
    }
  }
}

int JobService::remove_all_uploads() {
  int removed = 0;
  for (const fs::path& dir :
       {options_.data_dir / "results", options_.data_dir / "meshes", options_.data_dir / "checkpoints"}) {
    std::error_code error;
    for (fs::directory_iterator it(dir, error), end; !error && it != end; it.increment(error)) {
      if (it->path().filename().string().ends_with(".part")) {
        std::error_code ignored;
        if (fs::remove(it->path(), ignored)) ++removed;
      }
    }
  }
  return removed;
}

StatusOr<v1::MeshRef> JobService::upload_mesh(const std::string& bytes, const std::string& name) {
  auto ref = meshes_.put(bytes, name.empty() ? "mesh" : sanitize_text(name, 200));
  if (ref.ok()) {
    spdlog::info("mesh {} stored ({} bytes, {} vertices, {} tets)", ref->sha256(), ref->size_bytes(),
                 ref->vertex_count(), ref->tet_count());
  }
  return ref;
}

Status JobService::delete_job(const std::string& job_id, const Identity& caller) {
  auto id = parse_id(job_id, "job_id");
  if (!id.ok()) return id.status();
  if (Status s = check_visible(*id, caller); !s.ok()) return s;
  std::vector<std::int64_t> children;
  if (Status s = store_.delete_job(*id, &children); !s.ok()) return s;
  children.push_back(*id);
  for (std::int64_t removed : children) {
    std::error_code error;
    fs::remove(result_path(removed), error);
    fs::remove(result_path(removed, v1::RESULT_PART_XDMF), error);
    remove_uploads(removed);
    remove_checkpoint(removed);
    std::lock_guard lock(sample_bounds_mutex_);
    sample_bounds_.erase(removed);
  }
  spdlog::info("{} deleted{}", job_name(*id),
               children.size() > 1 ? " with its " + std::to_string(children.size() - 1) + " children" : "");
  return {};
}

Status JobService::fetch_mesh(const v1::FetchMeshRequest& request,
                              const std::function<bool(const v1::MeshChunk&)>& send) {
  auto id = parse_id(request.lease().job_id(), "lease.job_id");
  if (!id.ok()) return id.status();
  auto check = store_.check_lease(*id, request.lease().lease_token());
  if (!check.ok()) return check.status();
  if (*check != LeaseCheck::kValid) return {StatusCode::kFailedPrecondition, "lease lost: fetch refused"};
  auto job = store_.get(*id);
  if (!job.ok()) return job.status();
  v1::JobSpec spec = job->spec();
  const std::vector<jobs::SceneCell> cells = jobs::scene_cells(spec);
  const bool named = std::any_of(cells.begin(), cells.end(), [&](const jobs::SceneCell& c) {
    return !c.cell->mesh_sha256().empty() && c.cell->mesh_sha256() == request.sha256();
  });
  if (!named) return invalid_argument("sha256: not the mesh of the leased job's spec");
  auto bytes = meshes_.get(request.sha256());
  if (!bytes.ok()) return bytes.status();
  std::size_t offset = 0;
  do {
    v1::MeshChunk chunk;
    const std::size_t n = std::min(options_.download_chunk_bytes, bytes->size() - offset);
    chunk.set_data(bytes->substr(offset, n));
    if (!send(chunk)) return {StatusCode::kCancelled, "the worker went away"};
    offset += n;
  } while (offset < bytes->size());
  return {};
}

StatusOr<v1::SubmitJobResponse> JobService::submit(const v1::SubmitJobRequest& request,
                                                   const Identity& caller) {
  if (draining()) return Status(StatusCode::kFailedPrecondition, "the server is shutting down");
  if (static_cast<int>(request.request_id().size()) > options_.max_request_id_length) {
    return invalid_argument("request_id: at most " + std::to_string(options_.max_request_id_length) +
                            " characters");
  }
  if (request.spec().has_study()) return submit_study(request, caller);
  // One conversion: validation and the memory estimate read the same parameters.
  auto prepared = prepare_submitted(request.spec());
  if (!prepared.ok()) return prepared.status();
  const std::int64_t memory = (*prepared)->memory_bytes();
  if (options_.memory_limit_bytes > 0 && memory > options_.memory_limit_bytes) {
    return Status(
        StatusCode::kResourceExhausted,
        "the job needs an estimated " + std::to_string(memory >> 20) + " MiB, over this server's limit of " +
            std::to_string(options_.memory_limit_bytes >> 20) +
            " MiB (--memory-limit-bytes); lower cell.target_vertex_count or the lattice resolution");
  }
  // The result names an author: the client's, else the submitting user.
  v1::JobSpec spec = request.spec();
  if (spec.author().empty()) spec.set_author(caller.user);
  // A fit that reads library curves: the curves the server lacks become its child jobs.
  std::vector<Store::LibraryChild> library;
  if (spec.has_fit()) {
    auto needs = library_children(spec);
    if (!needs.ok()) return needs.status();
    library = std::move(*needs);
  }
  auto submitted = spec.has_fit() && !library.empty()
                       ? store_.submit_fit(spec, memory, library, request.request_id(), now(), caller.user)
                       : store_.submit(spec, request.request_id(), memory, now(), caller.user);
  if (!submitted.ok()) return submitted.status();
  if (!submitted->existed) {
    if (auto id = parse_job_name(submitted->job.id())) {
      std::lock_guard lock(sample_bounds_mutex_);
      sample_bounds_[*id] = (*prepared)->max_sample_index();
    }
    published(submitted->job);
    notifier_.queue_changed();
    if (submitted->job.child_count() > 0) {
      spdlog::info("{}: {} of its {} library curves queued as child jobs", submitted->job.id(),
                   submitted->job.child_count(), library.size());
    }
    spdlog::info("{} queued{}{}", submitted->job.id(),
                 request.spec().name().empty() ? "" : " \"" + sanitize_text(request.spec().name(), 80) + "\"",
                 request.request_id().empty() ? "" : " (request " + request.request_id() + ")");
  }
  v1::SubmitJobResponse response;
  *response.mutable_job() = std::move(submitted->job);
  response.set_already_existed(submitted->existed);
  return response;
}

StatusOr<std::vector<Store::LibraryChild>> JobService::library_children(const v1::JobSpec& spec) {
  std::vector<Store::LibraryChild> out;
  auto plan = jobs::to_fit_plan(spec.fit());
  if (!plan.ok()) return plan.status();
  auto children = jobs::fit_library_children(*plan, sanitize_text(spec.name(), 200));
  if (!children.ok()) return children.status();
  if (children->size() > static_cast<std::size_t>(options_.max_fit_library_children)) {
    return Status(StatusCode::kResourceExhausted,
                  "fit: " + std::to_string(children->size()) +
                      " library curves (distinct probe-to-cell radius ratios x the w grid); at most " +
                      std::to_string(options_.max_fit_library_children) +
                      " per fit: fit cells of similar radius together or fix w");
  }
  for (jobs::FitLibraryChild& c : *children) {
    // Checked like any submitted job; one the scenes refuse (a key at the edge
    // of their ranges) is left to the fit, which simulates it itself.
    auto prepared = prepare_submitted(c.spec);
    if (!prepared.ok()) continue;
    out.push_back({std::move(c.key), std::move(c.base), c.mooney_rivlin_w, c.needed_deformation,
                   std::move(c.spec), (*prepared)->memory_bytes()});
  }
  return out;
}

StatusOr<v1::SubmitJobResponse> JobService::submit_study(const v1::SubmitJobRequest& request,
                                                         const Identity& caller) {
  v1::JobSpec spec = request.spec();
  if (spec.name().size() > options_.max_name_bytes) {
    return invalid_argument("name: " + std::to_string(spec.name().size()) + " bytes; at most " +
                            std::to_string(options_.max_name_bytes));
  }
  if (spec.author().size() > options_.max_name_bytes) {
    return invalid_argument("author: " + std::to_string(spec.author().size()) + " bytes; at most " +
                            std::to_string(options_.max_name_bytes));
  }
  // Every child's result names an author: the base's, else the study's (the
  // client's), else the submitting user.
  if (spec.author().empty()) spec.set_author(caller.user);
  const std::string author =
      spec.study().base().author().empty() ? spec.author() : spec.study().base().author();
  // A repeated request returns its study before anything is expanded.
  if (!request.request_id().empty()) {
    auto existing = store_.submit_study(spec, {}, request.request_id(), now(), caller.user);
    if (existing.ok() && existing->existed) {
      v1::SubmitJobResponse response;
      *response.mutable_job() = std::move(existing->job);
      response.set_already_existed(true);
      return response;
    }
  }
  auto points = jobs::expand_study(spec.study(), options_.max_study_points);
  if (!points.ok()) return points.status();
  // Every child validated and memory-checked before anything is queued.
  std::vector<Store::StudyChild> children;
  std::vector<std::int64_t> bounds;
  std::set<std::string> library_keys;  // of every fit point
  children.reserve(points->size());
  const std::string base_name = spec.study().base().name().empty() ? spec.name() : spec.study().base().name();
  for (std::size_t i = 0; i < points->size(); ++i) {
    jobs::StudyPoint& point = (*points)[i];
    std::string where;
    for (int a = 0; a < spec.study().axes_size(); ++a) {
      where += (a == 0 ? "" : ", ") + std::string("study.axes[") + std::to_string(a) + "].values[" +
               std::to_string(point.value_index[static_cast<std::size_t>(a)]) + "]";
    }
    where += " (" + point.label + ")";
    point.spec.set_name(sanitize_text((base_name.empty() ? "" : base_name + " ") + "[" + point.label + "]",
                                      options_.max_name_bytes));
    point.spec.set_author(author);
    auto prepared = prepare_submitted(point.spec);
    if (!prepared.ok()) return Status(prepared.status().code(), where + ": " + prepared.status().message());
    const std::int64_t memory = (*prepared)->memory_bytes();
    if (options_.memory_limit_bytes > 0 && memory > options_.memory_limit_bytes) {
      return Status(StatusCode::kResourceExhausted,
                    where + ": the job needs an estimated " + std::to_string(memory >> 20) +
                        " MiB, over this server's limit of " +
                        std::to_string(options_.memory_limit_bytes >> 20) + " MiB (--memory-limit-bytes)");
    }
    bounds.push_back((*prepared)->max_sample_index());
    // A fit point reads library curves like a submitted fit: what the server
    // lacks is simulated by child jobs of that point, each curve once.
    std::vector<Store::LibraryChild> library;
    if (point.spec.has_fit()) {
      auto needs = library_children(point.spec);
      if (!needs.ok()) return Status(needs.status().code(), where + ": " + needs.status().message());
      library = std::move(*needs);
      // Bounded over the whole study, as for one fit: points of distinct
      // probe ratios or numerics would otherwise multiply the child rows.
      for (const Store::LibraryChild& c : library) library_keys.insert(c.key);
      if (library_keys.size() > static_cast<std::size_t>(options_.max_fit_library_children)) {
        return Status(StatusCode::kResourceExhausted,
                      where + ": the study's fit points read more than " +
                          std::to_string(options_.max_fit_library_children) +
                          " distinct library curves; sweep fewer probe ratios or numerics, or fix w");
      }
    }
    children.push_back({std::move(point.spec), memory, std::move(library)});
  }
  auto submitted = store_.submit_study(spec, children, request.request_id(), now(), caller.user);
  if (!submitted.ok()) return submitted.status();
  if (!submitted->existed) {
    if (auto id = parse_job_name(submitted->job.id())) {
      // Children have the ids after the study's, in point order (one transaction).
      std::lock_guard lock(sample_bounds_mutex_);
      for (std::size_t i = 0; i < bounds.size(); ++i)
        sample_bounds_[*id + 1 + static_cast<std::int64_t>(i)] = bounds[i];
    }
    published(submitted->job);
    notifier_.queue_changed();
    spdlog::info("{} queued: a study of {} children{}", submitted->job.id(), children.size(),
                 request.request_id().empty() ? "" : " (request " + request.request_id() + ")");
  }
  v1::SubmitJobResponse response;
  *response.mutable_job() = std::move(submitted->job);
  response.set_already_existed(submitted->existed);
  return response;
}

StatusOr<v1::Job> JobService::get(const std::string& job_id, const Identity& caller) {
  auto id = parse_id(job_id, "job_id");
  if (!id.ok()) return id.status();
  if (Status s = check_visible(*id, caller); !s.ok()) return s;
  return store_.get(*id);
}

StatusOr<v1::ListJobsResponse> JobService::list(const v1::ListJobsRequest& request, const Identity& caller) {
  if (request.page_size() < 0) return invalid_argument("page_size: must be >= 0");
  if (!v1::Job::State_IsValid(request.state())) return invalid_argument("state: unknown job state");
  const int page_size = request.page_size() == 0 ? options_.default_page_size
                                                 : std::min(request.page_size(), options_.max_page_size);
  std::int64_t after = 0;
  std::int64_t parent = 0;
  if (!request.parent_job_id().empty()) {
    auto id = parse_id(request.parent_job_id(), "parent_job_id");
    if (!id.ok()) return id.status();
    if (Status s = check_visible(*id, caller); !s.ok()) return s;
    parent = *id;
  }
  if (!request.page_token().empty()) {
    auto decoded = decode_page_token(request.page_token(), request.state(), parent);
    if (!decoded.ok()) return decoded.status();
    after = *decoded;
  }
  auto jobs =
      store_.list(after, page_size + 1, request.state(), caller.admin ? nullptr : &caller.user, parent);
  if (!jobs.ok()) return jobs.status();
  v1::ListJobsResponse response;
  const bool more = static_cast<int>(jobs->size()) > page_size;
  if (more) jobs->pop_back();
  for (auto& job : *jobs) *response.add_jobs() = std::move(job);
  if (more) {
    const auto last = parse_job_name(response.jobs(response.jobs_size() - 1).id());
    response.set_next_page_token(encode_page_token(last.value_or(0), request.state(), parent));
  }
  return response;
}

StatusOr<v1::Job> JobService::cancel(const std::string& job_id, const Identity& caller) {
  auto id = parse_id(job_id, "job_id");
  if (!id.ok()) return id.status();
  if (Status s = check_visible(*id, caller); !s.ok()) return s;
  std::vector<Store::CancelledChild> children;
  auto job = store_.cancel(*id, "cancelled by the client", now(), &children);
  if (job.ok()) {
    for (const Store::CancelledChild& child : children) {
      if (child.was_running) remove_uploads(child.id);  // a queued child has no upload
      notifier_.publish(child.id, child.last_sequence);
    }
    remove_uploads(*id);
    published(*job);
    notifier_.queue_changed();  // a fit waiting for this job may be leasable now
    spdlog::info("{} cancelled{}", job->id(),
                 children.empty() ? "" : " with " + std::to_string(children.size()) + " children");
  }
  return job;
}

Status JobService::watch(const v1::WatchJobRequest& request,
                         const std::function<bool(const v1::JobEvent&)>& send,
                         const std::function<bool()>& client_gone, const Identity& caller) {
  auto id = parse_id(request.job_id(), "job_id");
  if (!id.ok()) return id.status();
  if (Status s = check_visible(*id, caller); !s.ok()) return s;
  if (request.after_sequence() < 0) return invalid_argument("after_sequence: must be >= 0");
  // Subscribe before the first read: a commit after the read wakes the wait.
  auto subscription = notifier_.subscribe(*id);
  if (auto job = store_.get(*id); !job.ok()) return job.status();
  constexpr int kBatch = 256;
  std::int64_t after = request.after_sequence();
  while (true) {
    if (client_gone()) return {StatusCode::kCancelled, "the watcher went away"};
    auto events = store_.events_after(*id, after, kBatch);
    if (!events.ok()) return events.status();
    for (const v1::JobEvent& event : *events) {
      if (!send(event)) return {StatusCode::kCancelled, "the watcher went away"};
      after = event.sequence();
      if (event.has_state_change() && is_terminal(event.state_change().state())) return {};
    }
    if (static_cast<int>(events->size()) == kBatch) continue;
    if (events->empty()) {
      // Resumed after the terminal event: nothing will follow.
      auto job = store_.get(*id);
      if (!job.ok()) return job.status();
      if (is_terminal(job->state()) && after >= job->last_sequence()) return {};
      if (notifier_.shutting_down()) return {StatusCode::kCancelled, "the server is shutting down"};
    }
    // Woken by the next commit; the timeout only bounds how long a vanished
    // client keeps this thread.
    subscription->wait(after, std::chrono::milliseconds(500));
  }
}

Status JobService::download(const std::string& job_id,
                            const std::function<bool(const v1::ResultChunk&)>& send, const Identity& caller,
                            v1::ResultPart part) {
  auto id = parse_id(job_id, "job_id");
  if (!id.ok()) return id.status();
  if (part != v1::RESULT_PART_HDF5 && part != v1::RESULT_PART_XDMF) return invalid_argument("part: unknown");
  if (Status s = check_visible(*id, caller); !s.ok()) return s;
  auto job = store_.get(*id);
  if (!job.ok()) return job.status();
  const fs::path path = result_path(*id, part);
  std::ifstream in(path, std::ios::binary);
  if (!in && job->child_count() > 0) {
    return {StatusCode::kNotFound, job->id() + " is a study: each of its " +
                                       std::to_string(job->child_count()) +
                                       " children has a result (cellflow list --parent " + job->id() +
                                       "; cellflow plot " + job->id() + ")"};
  }
  if (!in) {
    return {StatusCode::kNotFound, job->id() + " has no result " +
                                       (part == v1::RESULT_PART_XDMF ? "XDMF sidecar" : "file") + " (state " +
                                       v1::Job::State_Name(job->state()) + ")"};
  }
  std::error_code error;
  const auto total = static_cast<std::int64_t>(fs::file_size(path, error));
  std::vector<char> buffer(options_.download_chunk_bytes);
  std::int64_t offset = 0;
  bool first = true;
  do {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in.gcount();
    v1::ResultChunk chunk;
    chunk.set_offset(offset);
    chunk.set_data(buffer.data(), static_cast<std::size_t>(n));
    chunk.set_total_size_bytes(total);
    if (first) chunk.set_file_name(job->id() + part_extension(part));
    first = false;
    if (!send(chunk)) return {StatusCode::kCancelled, "the client went away"};
    offset += n;
  } while (in && offset < total);
  return {};
}

void JobService::attach_library(const v1::Job& job, v1::FitSpec& fit) {
  auto id = parse_job_name(job.id());
  if (!id) return;
  // Under the 4 MiB message limit with the fit's own data (at most 3.2 MB of
  // samples): what does not fit, the fit simulates.
  const std::int64_t room = std::max<std::int64_t>(
      0, (std::int64_t{4} << 20) - static_cast<std::int64_t>(fit.ByteSizeLong()) - (std::int64_t{64} << 10));
  auto library = store_.library_curves_for(*id, room);
  if (!library.ok()) {
    spdlog::warn("{}: library curves not read: {}", job.id(), library.status().to_string());
    return;
  }
  if (library->refused > 0) {
    spdlog::warn("{}: {} stored library curves refused (checks or size)", job.id(), library->refused);
  }
  v1::FitServerLibrary* out = fit.mutable_server_library();
  for (v1::FitLibraryCurve& c : library->curves) *out->add_curves() = std::move(c);
  out->set_child_simulations(library->children_run);
}

StatusOr<v1::LeaseJobResponse> JobService::lease(const v1::LeaseJobRequest& request,
                                                 const std::function<bool()>& client_gone) {
  if (request.worker_id().empty()) return invalid_argument("worker_id: must not be empty");
  if (request.worker_id().size() > 256) return invalid_argument("worker_id: at most 256 bytes");
  const double wait_s = std::clamp(request.wait_s(), 0.0, 30.0);
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(static_cast<int>(wait_s * 1000));
  v1::LeaseJobResponse response;
  response.set_lease_ttl_s(options_.lease_ttl_s);
  response.set_heartbeat_interval_s(options_.heartbeat_interval_s);
  waiting_workers_.fetch_add(1);
  struct Waiting {
    std::atomic<int>& count;
    ~Waiting() { count.fetch_sub(1); }
  } waiting{waiting_workers_};
  while (!notifier_.shutting_down()) {
    const std::uint64_t generation = notifier_.queue_generation();
    // A worker that cancelled its poll (it is stopping: SIGTERM) gets no job:
    // a lease it never sees would only expire and cost the job an attempt.
    if (client_gone()) break;
    // While draining nothing is handed out; the poll still waits its time so
    // that workers do not spin against a draining server.
    if (!draining()) {
      auto claim = store_.claim(request.worker_id(), now(), ttl_ms());
      if (!claim.ok()) return claim.status();
      if (claim->has_value()) {
        Claim& c = **claim;
        if (client_gone()) {
          // The caller left while the claim was written: hand it back at once
          // (not charged), rather than let the lease expire.
          auto released =
              store_.release(parse_job_name(c.job.id()).value_or(0), c.lease_token,
                             "worker " + request.worker_id() + " left before the lease reached it", now());
          if (released.ok()) published(*released);
          notifier_.queue_changed();
          break;
        }
        published(c.job);
        spdlog::info("{} leased by {} (attempt {})", c.job.id(), request.worker_id(), c.job.attempt());
        response.set_found(true);
        response.mutable_lease()->set_job_id(c.job.id());
        response.mutable_lease()->set_lease_token(c.lease_token);
        response.mutable_lease()->set_attempt(c.job.attempt());
        *response.mutable_spec() = c.job.spec();
        if (response.spec().has_fit()) attach_library(c.job, *response.mutable_spec()->mutable_fit());
        response.set_last_delivered_sample_index(c.last_delivered_sample_index);
        if (auto id = parse_job_name(c.job.id())) describe_checkpoint(*id, response);
        return response;
      }
    }
    const auto now_steady = std::chrono::steady_clock::now();
    if (now_steady >= deadline || client_gone()) break;
    notifier_.wait_queue(generation, std::min(deadline, now_steady + std::chrono::seconds(1)));
  }
  response.set_found(false);
  return response;
}

namespace {

// Why a suspension sample cannot be stored ("" when it can): a worker's report
// is bounded like a request, so a hostile one cannot grow the event log by
// repeating cells (the result file, not the event, holds every cell).
std::string suspension_sample_refusal(const v1::SuspensionSample& s) {
  if (s.cell_count() < 0) return "suspension_sample.cell_count: must be >= 0";
  if (s.cells_size() > jobs::kMaxStreamedSuspensionCells) {
    return "suspension_sample.cells: " + std::to_string(s.cells_size()) + " cells, at most " +
           std::to_string(jobs::kMaxStreamedSuspensionCells) + " are streamed";
  }
  if (s.cells_size() > s.cell_count()) return "suspension_sample.cells: more cells than cell_count";
  for (int i = 0; i < s.cells_size(); ++i) {
    const v1::SuspendedCellState& cell = s.cells(i);
    const std::string field = "suspension_sample.cells[" + std::to_string(i) + "]";
    if (cell.cell() < 0 || cell.cell() >= s.cell_count()) return field + ".cell: outside [0, cell_count)";
    if (cell.centroid_m_size() != 3) return field + ".centroid_m: must hold 3 values";
  }
  return "";
}

// A report for a job that no longer exists (cancelled, then deleted while its
// worker still ran) is not an error of the stream: the ack tells the worker
// that its attempt is over, so it stops instead of reconnecting until its
// lease would have expired.
StatusOr<LeaseCheck> lease_or_deleted(StatusOr<LeaseCheck> check) {
  if (!check.ok() && check.status().code() == StatusCode::kNotFound) return LeaseCheck::kLost;
  return check;
}

}  // namespace

StatusOr<v1::ReportAck> JobService::report(const v1::WorkerReport& report) {
  auto id = parse_id(report.lease().job_id(), "lease.job_id");
  if (!id.ok()) return id.status();
  const std::string& token = report.lease().lease_token();
  LeaseCheck check = LeaseCheck::kLost;
  std::int64_t sequence = 0;
  v1::JobEvent event;
  std::optional<int> sample_index;
  std::string refused;  // a report the server cannot trust: an error to it, the job unaffected
  switch (report.kind_case()) {
    case v1::WorkerReport::kHeartbeat: {
      auto beat = lease_or_deleted(store_.heartbeat(*id, token, now(), ttl_ms()));
      if (!beat.ok()) return beat.status();
      check = *beat;
      break;
    }
    case v1::WorkerReport::kProgress: {
      const v1::Progress& p = report.progress();
      // NaN fails both comparisons; rounding just outside [0, 1] is clamped below.
      if (!(p.fraction_done() >= -1e-6 && p.fraction_done() <= 1.0 + 1e-6)) {
        refused = "progress.fraction_done: must lie in [0, 1]";
      } else if (!std::isfinite(p.elapsed_s()) || p.elapsed_s() < 0.0) {
        refused = "progress.elapsed_s: must be finite and >= 0";
      }
      *event.mutable_progress() = p;
      event.mutable_progress()->set_fraction_done(std::clamp(p.fraction_done(), 0.0, 1.0));
      if (!std::isfinite(p.estimated_remaining_s()) || p.estimated_remaining_s() < 0.0) {
        event.mutable_progress()->set_estimated_remaining_s(-1.0);  // unknown
      }
      event.mutable_progress()->set_stage(sanitize_text(p.stage(), 200));
      break;
    }
    case v1::WorkerReport::kForceSample:
      *event.mutable_force_sample() = report.force_sample();
      sample_index = report.force_sample().index();
      break;
    case v1::WorkerReport::kDeformationSample:
      *event.mutable_deformation_sample() = report.deformation_sample();
      sample_index = report.deformation_sample().index();
      break;
    case v1::WorkerReport::kSuspensionSample:
      refused = suspension_sample_refusal(report.suspension_sample());
      *event.mutable_suspension_sample() = report.suspension_sample();
      sample_index = report.suspension_sample().index();
      break;
    case v1::WorkerReport::KIND_NOT_SET:
      return invalid_argument("kind: a report needs a heartbeat, progress or sample");
  }
  if (sample_index && refused.empty()) {
    const std::int64_t bound = max_sample_index(*id);
    if (*sample_index < 0 || (bound >= 0 && *sample_index > bound)) {
      refused = "index: " + std::to_string(*sample_index) + " outside the job's range [0, " +
                (bound >= 0 ? std::to_string(bound) : std::string("...")) + "]";
    }
  }
  if (!refused.empty()) {
    // Refused: nothing is appended; the report still renews the lease, as a heartbeat.
    auto beat = lease_or_deleted(store_.heartbeat(*id, token, now(), ttl_ms()));
    if (!beat.ok()) return beat.status();
    check = *beat;
    if (check == LeaseCheck::kValid) spdlog::warn("{}: report refused: {}", job_name(*id), refused);
  } else if (!report.has_heartbeat()) {
    auto outcome = store_.append_event(*id, token, std::move(event), sample_index, now(), ttl_ms());
    if (!outcome.ok() && outcome.status().code() == StatusCode::kNotFound) {
      outcome = ReportOutcome{};  // a deleted job (cancelled, then deleted): the attempt is over
    }
    if (!outcome.ok()) return outcome.status();
    check = outcome->lease;
    sequence = outcome->sequence;
    refused = outcome->refused;
    if (sequence > 0) notifier_.publish(*id, sequence);
    if (!refused.empty()) spdlog::warn("{}: report refused: {}", job_name(*id), refused);
  }
  v1::ReportAck ack;
  if (check == LeaseCheck::kValid) ack.set_error(refused);
  ack.set_report_id(report.report_id());
  ack.set_lease_valid(check == LeaseCheck::kValid);
  ack.set_cancelled(check == LeaseCheck::kCancelled);
  return ack;
}

StatusOr<std::unique_ptr<ResultUpload>> JobService::begin_upload(const v1::Lease& lease,
                                                                 v1::ResultPart part) {
  if (part != v1::RESULT_PART_HDF5 && part != v1::RESULT_PART_XDMF) return invalid_argument("part: unknown");
  auto id = parse_id(lease.job_id(), "lease.job_id");
  if (!id.ok()) return id.status();
  auto check = store_.check_lease(*id, lease.lease_token());
  if (!check.ok()) return check.status();
  if (*check != LeaseCheck::kValid)
    return Status(StatusCode::kFailedPrecondition, "lease lost: upload refused");
  auto job = store_.get(*id);
  if (!job.ok()) return job.status();
  // A result holds part of what the run keeps in memory: the job's own estimate bounds it.
  const double limit =
      part == v1::RESULT_PART_XDMF
          ? static_cast<double>(kMaxXdmfBytes)
          : options_.upload_memory_factor * static_cast<double>(job->estimated_memory_bytes()) +
                static_cast<double>(options_.upload_slack_bytes);
  const fs::path path = upload_path(lease, part);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status(StatusCode::kInternal, "cannot create the upload file");
  return std::make_unique<ResultUpload>(path, fd, static_cast<std::int64_t>(std::min(limit, 9e18)));
}

StatusOr<std::int64_t> JobService::adopt_upload(const v1::Lease& lease, std::int64_t job_id) {
  const fs::path from = upload_path(lease);
  std::error_code error;
  if (!fs::exists(from, error)) return static_cast<std::int64_t>(-1);
  const auto size = static_cast<std::int64_t>(fs::file_size(from, error));
  fs::rename(from, result_path(job_id), error);
  if (error) return Status(StatusCode::kInternal, "cannot move the result into place: " + error.message());
  // The sidecar goes with it (none uploaded: none kept from an earlier attempt).
  const fs::path xdmf = upload_path(lease, v1::RESULT_PART_XDMF);
  std::error_code ignored;
  if (fs::exists(xdmf, ignored)) {
    fs::rename(xdmf, result_path(job_id, v1::RESULT_PART_XDMF), ignored);
  } else {
    fs::remove(result_path(job_id, v1::RESULT_PART_XDMF), ignored);
  }
  if (Status s = sync_directory(result_path(job_id).parent_path()); !s.ok()) return s;
  return size;
}

StatusOr<v1::FinishJobResponse> JobService::finish(const v1::FinishJobRequest& request) {
  auto id = parse_id(request.lease().job_id(), "lease.job_id");
  if (!id.ok()) return id.status();
  std::error_code error;
  const fs::path upload = upload_path(request.lease());
  if (!fs::exists(upload, error)) {
    return Status(StatusCode::kFailedPrecondition,
                  "no result uploaded for this lease; upload it, then finish");
  }
  // A result is an HDF5 file; anything else never becomes a SUCCEEDED job's result.
  if (auto check = store_.check_lease(*id, request.lease().lease_token());
      check.ok() && *check == LeaseCheck::kValid && !has_hdf5_signature(upload)) {
    fs::remove(upload, error);
    return Status(StatusCode::kInvalidArgument,
                  "the uploaded result is not an HDF5 file (no HDF5 signature); upload the attempt's result");
  }
  const auto size = static_cast<std::int64_t>(fs::file_size(upload, error));
  auto job = store_.finish(*id, request.lease().lease_token(), size, now(), [&]() -> Status {
    auto adopted = adopt_upload(request.lease(), *id);
    return adopted.ok() ? Status() : adopted.status();
  });
  if (!job.ok()) return job.status();
  published(*job);
  if (!job->parent_job_id().empty()) notifier_.queue_changed();  // its fit may be leasable now
  spdlog::info("{} succeeded (attempt {}, result {} bytes)", job->id(), job->attempt(), size);
  v1::FinishJobResponse response;
  response.set_state(job->state());
  return response;
}

StatusOr<v1::FinishJobResponse> JobService::fail(const v1::FailJobRequest& request) {
  auto id = parse_id(request.lease().job_id(), "lease.job_id");
  if (!id.ok()) return id.status();
  std::error_code error;
  const fs::path upload = upload_path(request.lease());
  const bool has_upload = fs::exists(upload, error);
  const std::int64_t size = has_upload ? static_cast<std::int64_t>(fs::file_size(upload, error)) : -1;
  // Never refused for its bytes: valid UTF-8, bounded (bytes on the wire).
  const std::string given = sanitize_text(request.reason(), options_.max_reason_bytes);
  const std::string reason = given.empty() ? "the worker reported a failure" : given;
  auto job = store_.fail(*id, request.lease().lease_token(), reason, size, now(), [&]() -> Status {
    if (!has_upload) return {};
    auto adopted = adopt_upload(request.lease(), *id);
    return adopted.ok() ? Status() : adopted.status();
  });
  if (!job.ok()) return job.status();
  published(*job);
  if (!job->parent_job_id().empty()) notifier_.queue_changed();  // its fit may be leasable now
  spdlog::warn("{} failed: {}", job->id(), reason);
  v1::FinishJobResponse response;
  response.set_state(job->state());
  return response;
}

StatusOr<v1::FinishJobResponse> JobService::release(const v1::ReleaseJobRequest& request) {
  auto id = parse_id(request.lease().job_id(), "lease.job_id");
  if (!id.ok()) return id.status();
  const std::string given = sanitize_text(request.reason(), options_.max_reason_bytes);
  const std::string reason = given.empty() ? "handed back by the worker" : given;
  auto job = store_.release(*id, request.lease().lease_token(), reason, now());
  if (!job.ok()) return job.status();
  std::error_code error;
  fs::remove(upload_path(request.lease()), error);
  fs::remove(upload_path(request.lease(), v1::RESULT_PART_XDMF), error);
  published(*job);
  notifier_.queue_changed();
  spdlog::info("{} handed back: {}", job->id(), reason);
  v1::FinishJobResponse response;
  response.set_state(job->state());
  return response;
}

int JobService::reap_expired_leases() {
  auto changed = store_.requeue_expired(now(), static_cast<std::int64_t>(options_.max_run_time_s * 1000.0));
  if (!changed.ok()) {
    spdlog::error("lease reaper: {}", changed.status().to_string());
    return 0;
  }
  for (const v1::Job& job : *changed) {
    published(job);
    if (auto id = parse_job_name(job.id())) remove_uploads(*id);  // that attempt can no longer finish
    spdlog::warn("{} -> {}: {}", job.id(), v1::Job::State_Name(job.state()), job.reason());
  }
  if (!changed->empty()) notifier_.queue_changed();
  return static_cast<int>(changed->size());
}

void JobService::set_draining(bool draining) {
  draining_.store(draining);
  notifier_.queue_changed();  // wake lease long-polls so they answer "nothing"
}

int JobService::release_all_running(const std::string& reason) {
  auto changed = store_.release_all_running(reason, now());
  if (!changed.ok()) return 0;
  for (const v1::Job& job : *changed) published(job);
  return static_cast<int>(changed->size());
}

}  // namespace cellflow::server
