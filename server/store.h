// The job queue: one SQLite database in WAL mode, opened by the server alone.
//
// Tables: jobs (one row per job, with its lease; version 3: a study row
// with child_count > 0 and child rows naming it by parent_id), events (job_id, seq,
// attempt, kind, sample_index, payload = a serialized cellflow.v1.JobEvent),
// schema_version (migrated on open), tokens (hashed API tokens; version 2,
// which also gives every job an owner: see server/README.md,
// "Authentication"). Every state change is written in one
// transaction together with its event, so a crash loses nothing that was
// acknowledged. Writers take BEGIN IMMEDIATE (a deferred transaction that
// upgrades to a writer ignores the busy timeout).
//
// Leases are fenced: a claim writes a fresh random lease token, and every
// later write of the attempt (heartbeat, event, finish, fail, release)
// changes the job only WHERE id = ? AND lease_token = ? AND state = RUNNING.
//
// Samples: a sample is identified by (job, kind, index). A sample whose
// index is at most the highest index of that kind already in the job's event
// log is not appended again, whichever attempt reports it: watchers see each
// index once, in increasing order. After a retry, indices the first attempt
// already delivered keep the first attempt's values in the event log; the
// result file is always the complete output of the attempt that finished.
//
// Studies: a child's every state change appends a ChildUpdate event to its
// study and rolls the study's state up in the same transaction (store.cc,
// roll_up_study); a study is never claimed, expired or released.
//
// Library (version 5): fits and their library simulations (submit_fit). A
// library child that ends leaves its curve in library_curves (built from its
// force samples and checked, in the transaction that ends it); a fit is
// leased once no job building a curve it needs is queued or running, and
// gets the stored curves with its lease (library_curves_for).
//
// No gRPC here: the store is tested directly (tests/service/store_test.cc).
// Time comes in as a parameter (milliseconds since the epoch) so tests can
// drive lease expiry without waiting.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cellflow/v1/service.pb.h"
#include "physics/core/status.h"

struct sqlite3;

namespace cellflow::server {

struct StoreOptions {
  std::string path;               // the database file; created when missing
  int busy_timeout_ms = 5000;     // how long a connection waits for a lock
  int max_attempts = 3;           // leases that may expire before the job FAILS
  bool synchronous_full = false;  // FULL: survive power loss; NORMAL (default): survive process crashes
};

// Outcome of a fenced write by a worker.
enum class LeaseCheck {
  kValid,      // the job is RUNNING under this token
  kCancelled,  // the job was cancelled: the worker must stop
  kLost,       // expired and re-leased, or finished: the worker must stop
};

// The job's last checkpoint (one per job).
struct CheckpointRecord {
  int attempt = 0;
  std::int64_t time_step = 0;
  int last_sample_index = -1;
  std::int64_t size_bytes = 0;
  std::int64_t time_ms = 0;
};

struct Claim {
  v1::Job job;
  std::string lease_token;
  int last_delivered_sample_index = -1;
};

// An API token as the store keeps it: never the token, only its SHA-256.
struct TokenRecord {
  std::int64_t id = 0;
  std::string user;
  std::string role;  // "user", "admin" or "worker"
  std::int64_t create_ms = 0;
  std::int64_t revoke_ms = 0;  // 0: not revoked
  bool revoked() const { return revoke_ms != 0; }
};

struct ReportOutcome {
  LeaseCheck lease = LeaseCheck::kLost;
  std::int64_t sequence = 0;  // the event's sequence; 0 when nothing was appended
  std::string refused;        // non-empty: the report was refused (nothing appended; lease renewed)
};

class Store {
 public:
  static constexpr int kSchemaVersion = 5;

  static StatusOr<std::unique_ptr<Store>> open(const StoreOptions& options);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  int schema_version();

  // Queues a job with its QUEUED event, owned by `owner`. A non-empty
  // request_id that `owner` already used returns that job and existed = true
  // (request ids are per owner).
  struct Submitted {
    v1::Job job;
    bool existed = false;
  };
  StatusOr<Submitted> submit(const v1::JobSpec& spec, const std::string& request_id,
                             std::int64_t estimated_memory_bytes, std::int64_t now_ms,
                             const std::string& owner = "");

  // A curve a fit reads from the library (schema 5, see submit_fit).
  struct LibraryChild {
    std::string key;   // curve_key_text (jobs/fit/fit_library.h)
    std::string base;  // the key without w
    double mooney_rivlin_w = 1.0;
    double needed_deformation = 0.0;  // the deepest deformation the fit asks of the key's curves
    v1::JobSpec spec;
    std::int64_t memory_bytes = 0;
  };

  // Queues a study and all its children in one transaction: the study row
  // (child_count = children.size(), never leased, memory = the largest
  // child's) with its QUEUED event, then one ordinary job per child (owned
  // by `owner`, parent_id = the study, child_index = its position; their ids
  // follow the study's in point order). The request_id covers the whole
  // study. The children were validated by the caller. A child with library
  // needs is a fit that reads library curves: it is queued as submit_fit
  // queues a fit (library_fit = 1, its library_needs, and a grandchild job
  // per curve nobody holds or builds, parent_id = the fit child), after all
  // the points; cancel and delete of the study reach those grandchildren.
  struct StudyChild {
    v1::JobSpec spec;
    std::int64_t memory_bytes = 0;
    std::vector<LibraryChild> library;
  };
  StatusOr<Submitted> submit_study(const v1::JobSpec& study, const std::vector<StudyChild>& children,
                                   const std::string& request_id, std::int64_t now_ms,
                                   const std::string& owner = "");

  // Queues a fit that reads library curves (schema 5) in one transaction: the
  // fit row (library_fit = 1, with its QUEUED event), one library_needs row
  // per curve key it reads, and one child job (parent_id = the fit,
  // library_key = the curve's key) per needed curve that the library table
  // lacks and no queued or running job is building already (of any fit or
  // owner: a curve is built once) and that the fit will read (not below a
  // stored curve of larger w that ends before the deformation the fit
  // needs). child_count is the children queued here.
  // The fit is leased only when no job building a curve it needs is queued
  // or running; its children's roll-up never ends it.
  // A library child that fails part-way, its curve ending before the
  // deformation the fits reading that key need, cancels the queued and
  // running jobs of the key's smaller w that only such fits need (they
  // search w above it: jobs/fit/fit_job.cc).
  StatusOr<Submitted> submit_fit(const v1::JobSpec& fit, std::int64_t memory_bytes,
                                 const std::vector<LibraryChild>& needs, const std::string& request_id,
                                 std::int64_t now_ms, const std::string& owner = "");
  // The stored curves of the keys a fit needs, each checked again
  // (jobs::check_library_curve) and at most max_bytes in all; the rest are
  // counted in `refused` (the fit simulates those itself).
  struct FitLibrary {
    std::vector<v1::FitLibraryCurve> curves;
    int refused = 0;
    int children_run = 0;  // the fit's children that ran to their end (not cancelled)
  };
  StatusOr<FitLibrary> library_curves_for(std::int64_t fit_id, std::int64_t max_bytes);
  std::int64_t count_library_curves();

  StatusOr<v1::Job> get(std::int64_t job_id);
  // The job's last event sequence (no spec parsed: a study's waking of its watchers).
  StatusOr<std::int64_t> last_sequence(std::int64_t job_id);
  // Jobs with id > after_id, oldest first, at most `limit`; state 0 = any;
  // owner null = every owner's; parent_id > 0: only that study's children.
  StatusOr<std::vector<v1::Job>> list(std::int64_t after_id, int limit, v1::Job::State state,
                                      const std::string* owner = nullptr, std::int64_t parent_id = 0);
  // Jobs in `state`, studies not counted (they are never leased).
  std::int64_t count(v1::Job::State state);

  // QUEUED or RUNNING -> CANCELLED (clears the lease); a cancelled job is
  // returned as it is; SUCCEEDED or FAILED gives kFailedPrecondition. A
  // study's queued and running children are cancelled with it, in the same
  // transaction (in *cancelled_children).
  struct CancelledChild {
    std::int64_t id = 0;
    std::int64_t last_sequence = 0;  // its CANCELLED event
    bool was_running = false;        // it had a lease (and maybe an upload)
  };
  StatusOr<v1::Job> cancel(std::int64_t job_id, const std::string& reason, std::int64_t now_ms,
                           std::vector<CancelledChild>* cancelled_children = nullptr);

  // Leases the oldest QUEUED job (attempt + 1, fresh token); nullopt if none.
  StatusOr<std::optional<Claim>> claim(const std::string& worker_id, std::int64_t now_ms,
                                       std::int64_t lease_ttl_ms);

  // Renews the lease.
  StatusOr<LeaseCheck> heartbeat(std::int64_t job_id, const std::string& lease_token, std::int64_t now_ms,
                                 std::int64_t lease_ttl_ms);
  // Renews the lease and appends `event` (sequence, attempt and time are set
  // here). sample_index: set for samples (see the header comment); an index
  // beyond the next one (a gap, which would hide the samples in between) is
  // refused (outcome.refused), an index already delivered is not appended.
  StatusOr<ReportOutcome> append_event(std::int64_t job_id, const std::string& lease_token,
                                       v1::JobEvent event, std::optional<int> sample_index,
                                       std::int64_t now_ms, std::int64_t lease_ttl_ms);

  // RUNNING -> SUCCEEDED / FAILED / QUEUED (released), fenced by the token.
  // `before_commit` runs inside the transaction once the fence held (e.g. to
  // move the attempt's result file into place); its error rolls back.
  // result_size_bytes < 0 keeps the stored size.
  StatusOr<v1::Job> finish(std::int64_t job_id, const std::string& lease_token,
                           std::int64_t result_size_bytes, std::int64_t now_ms,
                           const std::function<Status()>& before_commit = {});
  StatusOr<v1::Job> fail(std::int64_t job_id, const std::string& lease_token, const std::string& reason,
                         std::int64_t result_size_bytes, std::int64_t now_ms,
                         const std::function<Status()>& before_commit = {});
  // Hands the job back to the queue; the attempt does not count against max_attempts.
  StatusOr<v1::Job> release(std::int64_t job_id, const std::string& lease_token, const std::string& reason,
                            std::int64_t now_ms);

  // RUNNING jobs whose lease expired before now_ms go back to QUEUED, or to
  // FAILED once max_attempts leases have expired. Returns the changed jobs.
  // max_run_ms > 0: an attempt leased longer ago than that loses its lease
  // too (a worker that only heartbeats cannot hold a job forever).
  StatusOr<std::vector<v1::Job>> requeue_expired(std::int64_t now_ms, std::int64_t max_run_ms = 0);
  // On start-up: the attempts of jobs RUNNING when the server stopped are not
  // charged, whether their worker renews the lease or it expires.
  Status forgive_running_attempts();
  // Removes a terminal job's row and events; FAILED_PRECONDITION otherwise.
  // A study's children go with it (their ids in *deleted_children); a child
  // alone is not deleted (FAILED_PRECONDITION: delete its study).
  Status delete_job(std::int64_t job_id, std::vector<std::int64_t>* deleted_children = nullptr);
  // On start-up: every running lease expires no sooner than now + ttl, so a
  // worker that outlived a server restart can still renew it.
  Status extend_running_leases(std::int64_t now_ms, std::int64_t lease_ttl_ms);
  // On shutdown: every RUNNING job back to QUEUED (not counted as an attempt).
  StatusOr<std::vector<v1::Job>> release_all_running(const std::string& reason, std::int64_t now_ms);

  // Events with sequence > after_sequence, in order, at most `limit`.
  StatusOr<std::vector<v1::JobEvent>> events_after(std::int64_t job_id, std::int64_t after_sequence,
                                                   int limit);

  // Lease state as the fence sees it (for acks).
  StatusOr<LeaseCheck> check_lease(std::int64_t job_id, const std::string& lease_token);

  // --- ownership and API tokens (server/auth.h) ---
  // The identity that submitted the job ("" for jobs older than schema 2).
  StatusOr<std::string> job_owner(std::int64_t job_id);
  // Stores a token's hash; returns its id.
  StatusOr<std::int64_t> add_token(const std::string& user, const std::string& role,
                                   const std::string& token_hash, std::int64_t now_ms);
  StatusOr<std::optional<TokenRecord>> find_token(const std::string& token_hash);
  StatusOr<std::vector<TokenRecord>> list_tokens();
  // Revokes token `id` (id > 0) or every token of `user`; returns how many
  // were revoked now.
  StatusOr<int> revoke_tokens(std::int64_t id, const std::string& user, std::int64_t now_ms);
  std::int64_t count_tokens(bool include_revoked = false);

  // --- checkpoints of running flow jobs (schema 3; files: JobService) ---
  // Records the attempt's checkpoint in place of the job's previous one, only
  // while `lease_token` holds the job (the fence); `before_commit` moves the
  // file into place inside the transaction. kFailedPrecondition: lease lost.
  Status save_checkpoint(std::int64_t job_id, const std::string& lease_token, const CheckpointRecord& record,
                         const std::function<Status()>& before_commit);
  StatusOr<std::optional<CheckpointRecord>> checkpoint(std::int64_t job_id);
  Status delete_checkpoint(std::int64_t job_id);

 private:
  explicit Store(StoreOptions options);
  Status migrate();
  // The shared frame of submit, submit_study and submit_fit: the write
  // transaction, the idempotent request_id lookup, then `insert` (returns
  // the new top-level job's id), the load and the commit.
  StatusOr<Submitted> submit_once(const std::string& request_id, const std::string& owner,
                                  const std::function<StatusOr<std::int64_t>()>& insert);
  // A reader connection from the pool; returned by the guard's destructor.
  class Reader;
  Reader reader();

  StoreOptions options_;
  std::mutex write_mutex_;  // one writer connection, one writer at a time
  sqlite3* writer_ = nullptr;
  std::mutex readers_mutex_;
  std::vector<sqlite3*> idle_readers_;
  std::uint64_t token_counter_ = 0;
  std::uint64_t token_seed_[2] = {0, 0};
};

// "job-42" <-> 42. Accepts a bare "42" too.
std::string job_name(std::int64_t id);
std::optional<std::int64_t> parse_job_name(const std::string& name);

bool is_terminal(v1::Job::State state);

}  // namespace cellflow::server
