#include "server/store.h"

#include <sqlite3.h>

#include <algorithm>
#include <cstdio>
#include <random>

#include "jobs/fit/library_curve.h"

namespace cellflow::server {

namespace {

// The last column counts a study's terminal children (jobs_by_parent).
constexpr const char* kJobColumns =
    "id, request_id, spec, state, attempt, worker_id, reason, fraction_done, remaining_s, last_seq, "
    "result_bytes, memory_bytes, create_ms, start_ms, end_ms, parent_id, child_index, child_count, "
    "CASE WHEN child_count > 0 THEN (SELECT COUNT(*) FROM jobs c WHERE c.parent_id = jobs.id AND c.state >= "
    "3) "
    "ELSE 0 END";

// Migrations: entry i takes the schema from version i to i + 1.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE jobs (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  request_id TEXT UNIQUE,
  spec BLOB NOT NULL,
  state INTEGER NOT NULL CHECK (state BETWEEN 1 AND 5),
  attempt INTEGER NOT NULL DEFAULT 0,
  released INTEGER NOT NULL DEFAULT 0,
  lease_token TEXT,
  lease_expires_ms INTEGER,
  worker_id TEXT NOT NULL DEFAULT '',
  reason TEXT NOT NULL DEFAULT '',
  fraction_done REAL NOT NULL DEFAULT 0,
  remaining_s REAL NOT NULL DEFAULT -1,
  last_seq INTEGER NOT NULL DEFAULT 0,
  result_bytes INTEGER NOT NULL DEFAULT 0,
  memory_bytes INTEGER NOT NULL DEFAULT 0,
  create_ms INTEGER NOT NULL,
  start_ms INTEGER,
  end_ms INTEGER
);
CREATE INDEX jobs_by_state ON jobs (state, id);
CREATE TABLE events (
  job_id INTEGER NOT NULL REFERENCES jobs (id),
  seq INTEGER NOT NULL,
  attempt INTEGER NOT NULL,
  kind TEXT NOT NULL,
  sample_index INTEGER,
  time_ms INTEGER NOT NULL,
  payload BLOB NOT NULL,
  PRIMARY KEY (job_id, seq)
) WITHOUT ROWID;
CREATE UNIQUE INDEX events_by_sample ON events (job_id, kind, sample_index) WHERE sample_index IS NOT NULL;
)sql",
    // 2: authentication. Every job has an owner; request ids are per owner
    // (the UNIQUE request_id column holds owner + U+001F + the client's id;
    // older jobs have owner ''); API tokens are kept as SHA-256 only.
    R"sql(
ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT '';
UPDATE jobs SET request_id = char(31) || request_id WHERE request_id IS NOT NULL;
CREATE INDEX jobs_by_owner ON jobs (owner, id);
CREATE TABLE tokens (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  user TEXT NOT NULL,
  role TEXT NOT NULL CHECK (role IN ('user', 'admin', 'worker')),
  hash TEXT NOT NULL UNIQUE,
  create_ms INTEGER NOT NULL,
  revoke_ms INTEGER
);
)sql",
    // 3: studies (sweeps). A child names its study (parent_id) and its point
    // (child_index); a study counts its children (child_count > 0) and is
    // never leased.
    R"sql(
ALTER TABLE jobs ADD COLUMN parent_id INTEGER REFERENCES jobs (id);
ALTER TABLE jobs ADD COLUMN child_index INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN child_count INTEGER NOT NULL DEFAULT 0;
CREATE INDEX jobs_by_parent ON jobs (parent_id, state);
)sql",
    // 4: checkpoints of running flow jobs; the file is checkpoints/job-N.ckpt.
    R"sql(
CREATE TABLE checkpoints (
  job_id INTEGER PRIMARY KEY REFERENCES jobs (id),
  attempt INTEGER NOT NULL,
  time_step INTEGER NOT NULL,
  last_sample_index INTEGER NOT NULL,
  size_bytes INTEGER NOT NULL,
  time_ms INTEGER NOT NULL
);
)sql",
    // 5: the curve library of fits (issue 14). A fit row (library_fit = 1)
    // names the library curves it reads (library_needs) and is leased only
    // when no job building one of them is queued or running; a library child
    // (library_key = its curve's key text) leaves its curve in library_curves
    // when it ends. Curves outlive the jobs that made them. A need names the
    // key without w (base), its w and the deepest deformation the fit asks of it.
    R"sql(
ALTER TABLE jobs ADD COLUMN library_fit INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN library_key TEXT;
CREATE INDEX jobs_by_library_key ON jobs (library_key, state) WHERE library_key IS NOT NULL;
CREATE TABLE library_needs (
  fit_id INTEGER NOT NULL REFERENCES jobs (id),
  key TEXT NOT NULL,
  base TEXT NOT NULL,
  w REAL NOT NULL,
  needed REAL NOT NULL,
  PRIMARY KEY (fit_id, key)
) WITHOUT ROWID;
CREATE INDEX library_needs_by_key ON library_needs (key);
CREATE TABLE library_curves (
  key TEXT PRIMARY KEY,
  base TEXT NOT NULL,
  w REAL NOT NULL,
  end_deformation REAL NOT NULL,
  curve BLOB NOT NULL,
  job_id INTEGER NOT NULL,
  create_ms INTEGER NOT NULL
);
CREATE INDEX library_curves_by_base ON library_curves (base, w);
)sql",
};

// The request_id column of schema 2: owner, U+001F, the client's request id.
constexpr char kRequestScope = '\x1f';

std::string scoped_request_id(const std::string& owner, const std::string& request_id) {
  return owner + kRequestScope + request_id;
}

std::string client_request_id(const std::string& stored) {
  const auto separator = stored.find(kRequestScope);
  return separator == std::string::npos ? stored : stored.substr(separator + 1);
}

Status sqlite_error(sqlite3* db, const std::string& what) {
  return {StatusCode::kInternal, "sqlite: " + what + ": " + (db ? sqlite3_errmsg(db) : "no connection")};
}

// A prepared statement with positional binds.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK) stmt_ = nullptr;
  }
  ~Stmt() { sqlite3_finalize(stmt_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  bool ok() const { return stmt_ != nullptr; }
  Stmt& bind(int i, std::int64_t v) {
    sqlite3_bind_int64(stmt_, i, v);
    return *this;
  }
  Stmt& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Stmt& bind(int i, double v) {
    sqlite3_bind_double(stmt_, i, v);
    return *this;
  }
  Stmt& bind(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind_blob(int i, const std::string& v) {
    sqlite3_bind_blob(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind_null(int i) {
    sqlite3_bind_null(stmt_, i);
    return *this;
  }
  // SQLITE_ROW, SQLITE_DONE or an error code.
  int step() { return sqlite3_step(stmt_); }
  // Ends a pending read so that COMMIT finds no statement in progress.
  void reset() { sqlite3_reset(stmt_); }
  std::int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  double real(int col) const { return sqlite3_column_double(stmt_, col); }
  bool is_null(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  std::string text(int col) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, col));
    return p ? std::string(p, sqlite3_column_bytes(stmt_, col)) : std::string();
  }
  std::string blob(int col) const {
    const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_, col));
    return p ? std::string(p, sqlite3_column_bytes(stmt_, col)) : std::string();
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

Status exec(sqlite3* db, const char* sql) {
  char* error = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &error) != SQLITE_OK) {
    std::string message = error ? error : "unknown";
    sqlite3_free(error);
    return {StatusCode::kInternal, std::string("sqlite: ") + message + " in: " + sql};
  }
  return {};
}

// BEGIN IMMEDIATE ... COMMIT; rolls back unless committed.
class WriteTransaction {
 public:
  explicit WriteTransaction(sqlite3* db) : db_(db) { status_ = exec(db, "BEGIN IMMEDIATE"); }
  ~WriteTransaction() {
    if (status_.ok() && !committed_) (void)exec(db_, "ROLLBACK");
  }
  const Status& status() const { return status_; }
  Status commit() {
    Status s = exec(db_, "COMMIT");
    committed_ = s.ok();
    return s;
  }

 private:
  sqlite3* db_;
  Status status_;
  bool committed_ = false;
};

google::protobuf::Timestamp timestamp_from_ms(std::int64_t ms) {
  google::protobuf::Timestamp t;
  t.set_seconds(ms / 1000);
  t.set_nanos(static_cast<int>((ms % 1000) * 1000000));
  return t;
}

v1::Job job_from_row(const Stmt& row) {
  v1::Job job;
  job.set_id(job_name(row.int64(0)));
  job.set_request_id(client_request_id(row.text(1)));
  job.mutable_spec()->ParseFromString(row.blob(2));
  job.set_state(static_cast<v1::Job::State>(row.int64(3)));
  job.set_attempt(static_cast<int>(row.int64(4)));
  job.set_worker_id(row.text(5));
  job.set_reason(row.text(6));
  job.set_fraction_done(row.real(7));
  job.set_estimated_remaining_s(row.real(8));
  job.set_last_sequence(row.int64(9));
  job.set_result_size_bytes(row.int64(10));
  job.set_estimated_memory_bytes(row.int64(11));
  *job.mutable_create_time() = timestamp_from_ms(row.int64(12));
  if (!row.is_null(13)) *job.mutable_start_time() = timestamp_from_ms(row.int64(13));
  if (!row.is_null(14)) *job.mutable_end_time() = timestamp_from_ms(row.int64(14));
  if (!row.is_null(15)) job.set_parent_job_id(job_name(row.int64(15)));
  job.set_child_index(static_cast<int>(row.int64(16)));
  job.set_child_count(static_cast<int>(row.int64(17)));
  job.set_children_done(static_cast<int>(row.int64(18)));
  return job;
}

StatusOr<v1::Job> load_job(sqlite3* db, std::int64_t job_id) {
  const std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id = ?";
  Stmt stmt(db, sql.c_str());
  if (!stmt.ok()) return sqlite_error(db, "prepare get");
  stmt.bind(1, job_id);
  const int rc = stmt.step();
  if (rc == SQLITE_DONE) return Status(StatusCode::kNotFound, "job " + job_name(job_id) + " not found");
  if (rc != SQLITE_ROW) return sqlite_error(db, "get");
  return job_from_row(stmt);
}

const char* kind_name(const v1::JobEvent& event) {
  switch (event.kind_case()) {
    case v1::JobEvent::kStateChange:
      return "state";
    case v1::JobEvent::kProgress:
      return "progress";
    case v1::JobEvent::kForceSample:
      return "force_sample";
    case v1::JobEvent::kDeformationSample:
      return "deformation_sample";
    case v1::JobEvent::kSuspensionSample:
      return "suspension_sample";
    case v1::JobEvent::kChildUpdate:
      return "child";
    case v1::JobEvent::KIND_NOT_SET:
      break;
  }
  return "none";
}

// Appends `event` as the job's next event (inside a write transaction).
StatusOr<std::int64_t> append_event_row(sqlite3* db, std::int64_t job_id, int attempt, v1::JobEvent event,
                                        std::optional<int> sample_index, std::int64_t now_ms) {
  Stmt bump(db, "UPDATE jobs SET last_seq = last_seq + 1 WHERE id = ? RETURNING last_seq");
  bump.bind(1, job_id);
  if (bump.step() != SQLITE_ROW) return sqlite_error(db, "sequence");
  const std::int64_t sequence = bump.int64(0);
  event.set_job_id(job_name(job_id));
  event.set_sequence(sequence);
  event.set_attempt(attempt);
  *event.mutable_time() = timestamp_from_ms(now_ms);
  Stmt insert(db,
              "INSERT INTO events (job_id, seq, attempt, kind, sample_index, time_ms, payload) "
              "VALUES (?, ?, ?, ?, ?, ?, ?)");
  insert.bind(1, job_id).bind(2, sequence).bind(3, attempt).bind(4, std::string(kind_name(event)));
  if (sample_index) {
    insert.bind(5, *sample_index);
  } else {
    insert.bind_null(5);
  }
  insert.bind(6, now_ms).bind_blob(7, event.SerializeAsString());
  if (insert.step() != SQLITE_DONE) return sqlite_error(db, "insert event");
  return sequence;
}

v1::JobEvent state_event(v1::Job::State state, const std::string& reason, const std::string& worker_id) {
  v1::JobEvent event;
  auto* change = event.mutable_state_change();
  change->set_state(state);
  change->set_reason(reason);
  change->set_worker_id(worker_id);
  return event;
}

// Lease state of a job for `token`, read inside the caller's transaction.
StatusOr<LeaseCheck> lease_state(sqlite3* db, std::int64_t job_id, const std::string& token) {
  Stmt stmt(db, "SELECT state, lease_token FROM jobs WHERE id = ?");
  stmt.bind(1, job_id);
  const int rc = stmt.step();
  if (rc == SQLITE_DONE) return Status(StatusCode::kNotFound, "job " + job_name(job_id) + " not found");
  if (rc != SQLITE_ROW) return sqlite_error(db, "lease state");
  const auto state = static_cast<v1::Job::State>(stmt.int64(0));
  if (state == v1::Job::CANCELLED) return LeaseCheck::kCancelled;
  if (state == v1::Job::RUNNING && !stmt.is_null(1) && stmt.text(1) == token) return LeaseCheck::kValid;
  return LeaseCheck::kLost;
}

Status lease_status(LeaseCheck check) {
  if (check == LeaseCheck::kCancelled)
    return {StatusCode::kFailedPrecondition, "lease lost: the job was cancelled"};
  return {StatusCode::kFailedPrecondition, "lease lost: the job is no longer running under this lease token"};
}

// A child's state change, seen by its study (inside the caller's write
// transaction): a ChildUpdate event in the study's log, then the study's
// state rolled up. RUNNING when a child first leaves QUEUED; once every child
// is terminal, SUCCEEDED if all succeeded, else FAILED with the count and the
// first reason. conclude = false appends the event only (a cascade that sets
// the study's state itself).
Status roll_up_study(sqlite3* db, std::int64_t child_id, std::int64_t now_ms, bool conclude = true) {
  std::int64_t parent_id = 0;
  v1::ChildUpdate update;
  {
    Stmt child(db, "SELECT parent_id, child_index, state, reason FROM jobs WHERE id = ?");
    child.bind(1, child_id);
    if (child.step() != SQLITE_ROW) return sqlite_error(db, "child");
    if (child.is_null(0)) return {};
    parent_id = child.int64(0);
    update.set_child_job_id(job_name(child_id));
    update.set_child_index(static_cast<int>(child.int64(1)));
    update.set_state(static_cast<v1::Job::State>(child.int64(2)));
    update.set_reason(child.text(3));
  }
  v1::JobEvent event;
  *event.mutable_child_update() = update;
  if (auto seq = append_event_row(db, parent_id, 0, std::move(event), std::nullopt, now_ms); !seq.ok()) {
    return seq.status();
  }
  if (!conclude) return {};
  // The study's state and counts only: its spec (every axis value) is not parsed per child.
  v1::Job::State study_state = v1::Job::STATE_UNSPECIFIED;
  int count = 0;
  int done = 0;
  bool library_fit = false;
  {
    Stmt study(
        db,
        "SELECT state, child_count, (SELECT COUNT(*) FROM jobs c WHERE c.parent_id = ?1 AND c.state >= 3), "
        "library_fit FROM jobs WHERE id = ?1");
    study.bind(1, parent_id);
    if (study.step() != SQLITE_ROW) return sqlite_error(db, "study");
    study_state = static_cast<v1::Job::State>(study.int64(0));
    count = static_cast<int>(study.int64(1));
    done = static_cast<int>(study.int64(2));
    library_fit = study.int64(3) != 0;
  }
  if (is_terminal(study_state)) return {};
  if (library_fit) {
    // A fit is an ordinary job once leased (claim); while it waits, its
    // fraction is that of its library simulations done.
    if (study_state == v1::Job::QUEUED && is_terminal(update.state())) {
      Stmt progress(db, "UPDATE jobs SET fraction_done = ? WHERE id = ?");
      progress.bind(1, count > 0 ? static_cast<double>(done) / count : 1.0).bind(2, parent_id);
      if (progress.step() != SQLITE_DONE) return sqlite_error(db, "fit progress");
    }
    return {};
  }
  if (study_state == v1::Job::QUEUED && update.state() != v1::Job::QUEUED) {
    Stmt start(db, "UPDATE jobs SET state = ?, start_ms = COALESCE(start_ms, ?), reason = '' WHERE id = ?");
    start.bind(1, static_cast<int>(v1::Job::RUNNING)).bind(2, now_ms).bind(3, parent_id);
    if (start.step() != SQLITE_DONE) return sqlite_error(db, "study start");
    if (auto seq =
            append_event_row(db, parent_id, 0,
                             state_event(v1::Job::RUNNING, "child " + update.child_job_id() + " started", ""),
                             std::nullopt, now_ms);
        !seq.ok()) {
      return seq.status();
    }
  }
  if (!is_terminal(update.state())) return {};
  Stmt progress(db, "UPDATE jobs SET fraction_done = ? WHERE id = ?");
  progress.bind(1, count > 0 ? static_cast<double>(done) / count : 1.0).bind(2, parent_id);
  if (progress.step() != SQLITE_DONE) return sqlite_error(db, "study progress");
  if (done < count) return {};
  // Every child is terminal: the study ends.
  int failed = 0;
  int cancelled = 0;
  {
    Stmt tally(db, "SELECT state, COUNT(*) FROM jobs WHERE parent_id = ? AND state IN (4, 5) GROUP BY state");
    tally.bind(1, parent_id);
    while (tally.step() == SQLITE_ROW) {
      (tally.int64(0) == v1::Job::FAILED ? failed : cancelled) = static_cast<int>(tally.int64(1));
    }
  }
  std::string reason;
  v1::Job::State state = v1::Job::SUCCEEDED;
  if (failed + cancelled > 0) {
    state = v1::Job::FAILED;
    Stmt first(db,
               "SELECT id, child_index, state, reason FROM jobs WHERE parent_id = ? AND state IN (4, 5) "
               "ORDER BY child_index LIMIT 1");
    first.bind(1, parent_id);
    reason = std::to_string(failed) + " of " + std::to_string(count) + " children failed";
    if (cancelled > 0) reason += ", " + std::to_string(cancelled) + " cancelled";
    if (first.step() == SQLITE_ROW) {
      reason += "; first: " + job_name(first.int64(0)) + " (point " + std::to_string(first.int64(1)) + ", " +
                (first.int64(2) == v1::Job::FAILED ? "failed" : "cancelled") + "): " + first.text(3);
    }
  }
  Stmt end(
      db,
      "UPDATE jobs SET state = ?, reason = ?, end_ms = ?, fraction_done = 1.0, remaining_s = 0 WHERE id = ?");
  end.bind(1, static_cast<int>(state)).bind(2, reason).bind(3, now_ms).bind(4, parent_id);
  if (end.step() != SQLITE_DONE) return sqlite_error(db, "study end");
  auto seq = append_event_row(db, parent_id, 0, state_event(state, reason, ""), std::nullopt, now_ms);
  return seq.ok() ? Status() : seq.status();
}

}  // namespace

std::string job_name(std::int64_t id) {
  return "job-" + std::to_string(id);
}

std::optional<std::int64_t> parse_job_name(const std::string& name) {
  std::string digits = name.rfind("job-", 0) == 0 ? name.substr(4) : name;
  if (digits.empty() || digits.size() > 18) return std::nullopt;
  std::int64_t id = 0;
  for (char c : digits) {
    if (c < '0' || c > '9') return std::nullopt;
    id = id * 10 + (c - '0');
  }
  if (id <= 0) return std::nullopt;
  return id;
}

bool is_terminal(v1::Job::State state) {
  return state == v1::Job::SUCCEEDED || state == v1::Job::FAILED || state == v1::Job::CANCELLED;
}

class Store::Reader {
 public:
  Reader(Store* store, sqlite3* db) : store_(store), db_(db) {}
  ~Reader() {
    if (db_ == nullptr) return;
    std::lock_guard lock(store_->readers_mutex_);
    store_->idle_readers_.push_back(db_);
  }
  Reader(Reader&& other) noexcept : store_(other.store_), db_(std::exchange(other.db_, nullptr)) {}
  sqlite3* get() const { return db_; }

 private:
  Store* store_;
  sqlite3* db_;
};

namespace {

StatusOr<sqlite3*> open_connection(const StoreOptions& options) {
  sqlite3* db = nullptr;
  const int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
  if (sqlite3_open_v2(options.path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    Status s = sqlite_error(db, "open " + options.path);
    sqlite3_close(db);
    return s;
  }
  sqlite3_busy_timeout(db, options.busy_timeout_ms);
  for (const char* pragma : {"PRAGMA journal_mode = WAL", "PRAGMA foreign_keys = ON"}) {
    if (Status s = exec(db, pragma); !s.ok()) {
      sqlite3_close(db);
      return s;
    }
  }
  if (Status s =
          exec(db, options.synchronous_full ? "PRAGMA synchronous = FULL" : "PRAGMA synchronous = NORMAL");
      !s.ok()) {
    sqlite3_close(db);
    return s;
  }
  return db;
}

}  // namespace

Store::Reader Store::reader() {
  {
    std::lock_guard lock(readers_mutex_);
    if (!idle_readers_.empty()) {
      sqlite3* db = idle_readers_.back();
      idle_readers_.pop_back();
      return Reader(this, db);
    }
  }
  auto db = open_connection(options_);
  return Reader(this, db.ok() ? *db : nullptr);
}

Store::Store(StoreOptions options) : options_(std::move(options)) {
  std::random_device device;
  token_seed_[0] = (static_cast<std::uint64_t>(device()) << 32) ^ device();
  token_seed_[1] = (static_cast<std::uint64_t>(device()) << 32) ^ device();
}

Store::~Store() {
  for (sqlite3* db : idle_readers_) sqlite3_close(db);
  if (writer_) sqlite3_close(writer_);
}

StatusOr<std::unique_ptr<Store>> Store::open(const StoreOptions& options) {
  std::unique_ptr<Store> store(new Store(options));
  auto writer = open_connection(options);
  if (!writer.ok()) return writer.status();
  store->writer_ = *writer;
  if (Status s = store->migrate(); !s.ok()) return s;
  return store;
}

int Store::schema_version() {
  std::lock_guard lock(write_mutex_);
  Stmt stmt(writer_, "SELECT version FROM schema_version");
  return stmt.ok() && stmt.step() == SQLITE_ROW ? static_cast<int>(stmt.int64(0)) : 0;
}

Status Store::migrate() {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  if (Status s = exec(writer_, "CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
      !s.ok()) {
    return s;
  }
  int version = 0;
  {
    Stmt stmt(writer_, "SELECT version FROM schema_version");
    if (stmt.step() == SQLITE_ROW) {
      version = static_cast<int>(stmt.int64(0));
    } else if (Status s = exec(writer_, "INSERT INTO schema_version (version) VALUES (0)"); !s.ok()) {
      return s;
    }
  }
  constexpr int latest = static_cast<int>(sizeof kMigrations / sizeof kMigrations[0]);
  static_assert(latest == kSchemaVersion);
  if (version > latest) {
    return {StatusCode::kFailedPrecondition, "database schema version " + std::to_string(version) +
                                                 " is newer than this server's (" + std::to_string(latest) +
                                                 ")"};
  }
  for (; version < latest; ++version) {
    if (Status s = exec(writer_, kMigrations[version]); !s.ok()) return s;
  }
  Stmt update(writer_, "UPDATE schema_version SET version = ?");
  update.bind(1, latest);
  if (update.step() != SQLITE_DONE) return sqlite_error(writer_, "schema version");
  return txn.commit();
}

namespace {

// The job an earlier submit of this owner's non-empty request_id created, if
// any: a job and a study are idempotent by the same key.
StatusOr<std::optional<v1::Job>> job_of_request(sqlite3* db, const std::string& owner,
                                                const std::string& request_id) {
  if (request_id.empty()) return std::optional<v1::Job>{};
  Stmt find(db, "SELECT id FROM jobs WHERE request_id = ?");
  find.bind(1, scoped_request_id(owner, request_id));
  if (find.step() != SQLITE_ROW) return std::optional<v1::Job>{};
  auto job = load_job(db, find.int64(0));
  if (!job.ok()) return job.status();
  return std::optional<v1::Job>(std::move(*job));
}

// Inserts a queued top-level job (a job, a study or a fit) under the caller's
// transaction; child_count and library_fit are its study/fit columns (0 for
// a plain job). Returns its id.
StatusOr<std::int64_t> insert_top_level_job(sqlite3* db, const std::string& owner,
                                            const std::string& request_id, const v1::JobSpec& spec,
                                            std::int64_t memory_bytes, std::int64_t now_ms, int child_count,
                                            bool library_fit, const char* what) {
  Stmt insert(db,
              "INSERT INTO jobs (request_id, spec, state, memory_bytes, create_ms, owner, child_count, "
              "library_fit) VALUES (?, ?, ?, ?, ?, ?, ?, ?) RETURNING id");
  if (request_id.empty()) {
    insert.bind_null(1);
  } else {
    insert.bind(1, scoped_request_id(owner, request_id));
  }
  insert.bind_blob(2, spec.SerializeAsString()).bind(3, static_cast<int>(v1::Job::QUEUED));
  insert.bind(4, memory_bytes).bind(5, now_ms).bind(6, owner).bind(7, child_count);
  insert.bind(8, library_fit ? 1 : 0);
  if (insert.step() != SQLITE_ROW) return sqlite_error(db, what);
  const std::int64_t id = insert.int64(0);
  insert.step();
  return id;
}

// Inserts a queued child job (of a study, or a library simulation of a fit
// when library_key is set) with its "submitted" event, under the caller's
// transaction. `insert` is the prepared kInsertChildSql
// (reused across a batch). Returns its id.
constexpr const char* kInsertChildSql =
    "INSERT INTO jobs (spec, state, memory_bytes, create_ms, owner, parent_id, child_index, library_key) "
    "VALUES (?, ?, ?, ?, ?, ?, ?, ?) RETURNING id";

StatusOr<std::int64_t> insert_child_job(sqlite3* db, Stmt& insert, const v1::JobSpec& spec,
                                        std::int64_t memory_bytes, std::int64_t now_ms,
                                        const std::string& owner, std::int64_t parent_id, int child_index,
                                        const std::optional<std::string>& library_key,
                                        const std::string& reason, const char* what) {
  insert.reset();
  insert.bind_blob(1, spec.SerializeAsString()).bind(2, static_cast<int>(v1::Job::QUEUED));
  insert.bind(3, memory_bytes).bind(4, now_ms).bind(5, owner).bind(6, parent_id).bind(7, child_index);
  if (library_key) {
    insert.bind(8, *library_key);
  } else {
    insert.bind_null(8);
  }
  if (insert.step() != SQLITE_ROW) return sqlite_error(db, what);
  const std::int64_t child_id = insert.int64(0);
  insert.step();
  insert.reset();
  auto seq =
      append_event_row(db, child_id, 0, state_event(v1::Job::QUEUED, reason, ""), std::nullopt, now_ms);
  if (!seq.ok()) return seq.status();
  return child_id;
}

// The library side of a fit (inside the caller's write transaction): one
// library_needs row per curve key the fit reads, and a child job
// (parent_id = the fit, library_key = the key) per needed curve that the
// library table lacks, no queued or running job is building already (of any
// fit or owner: a curve is built once) and the fit will read; then the fit's
// child_count and library_fit = 1. Returns the number of children queued.
StatusOr<int> queue_library_children(sqlite3* db, std::int64_t fit_id,
                                     const std::vector<Store::LibraryChild>& needs, const std::string& owner,
                                     std::int64_t now_ms) {
  // Under the write lock, so that of two fits submitted together only the
  // first queues a curve and the second waits for that child.
  Stmt need(db, "INSERT OR IGNORE INTO library_needs (fit_id, key, base, w, needed) VALUES (?, ?, ?, ?, ?)");
  // Not queued: a curve held or being built, or one the fit will not read
  // (a stored curve of larger w ends before the deformation the fit needs:
  // it searches w only above that one).
  Stmt known(db,
             "SELECT EXISTS (SELECT 1 FROM library_curves WHERE key = ?1) OR EXISTS (SELECT 1 FROM jobs "
             "WHERE library_key = ?1 AND state IN (1, 2)) OR EXISTS (SELECT 1 FROM library_curves WHERE "
             "base = ?2 AND w > ?3 AND end_deformation < ?4 * (1 - 1e-12))");
  Stmt child(db, kInsertChildSql);
  const std::string reason = "submitted (library simulation of fit " + job_name(fit_id) + ")";
  int queued = 0;
  for (const Store::LibraryChild& c : needs) {
    need.reset();
    need.bind(1, fit_id)
        .bind(2, c.key)
        .bind(3, c.base)
        .bind(4, c.mooney_rivlin_w)
        .bind(5, c.needed_deformation);
    if (need.step() != SQLITE_DONE) return sqlite_error(db, "library need");
    known.reset();
    known.bind(1, c.key).bind(2, c.base).bind(3, c.mooney_rivlin_w).bind(4, c.needed_deformation);
    if (known.step() != SQLITE_ROW) return sqlite_error(db, "library lookup");
    const bool have = known.int64(0) != 0;
    known.reset();
    if (have) continue;
    auto child_id = insert_child_job(db, child, c.spec, c.memory_bytes, now_ms, owner, fit_id, queued, c.key,
                                     reason, "insert library child");
    if (!child_id.ok()) return child_id.status();
    ++queued;
  }
  Stmt count(db, "UPDATE jobs SET child_count = ?, library_fit = 1 WHERE id = ?");
  count.bind(1, queued).bind(2, fit_id);
  if (count.step() != SQLITE_DONE) return sqlite_error(db, "fit children");
  return queued;
}

}  // namespace

// One write transaction for a top-level submit: an earlier job of this
// owner's request_id is returned as it is (idempotent resubmit); otherwise
// `insert` queues the job (and its children) and returns its id, and the
// job is loaded and committed.
StatusOr<Store::Submitted> Store::submit_once(const std::string& request_id, const std::string& owner,
                                              const std::function<StatusOr<std::int64_t>()>& insert) {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  if (auto earlier = job_of_request(writer_, owner, request_id); !earlier.ok()) {
    return earlier.status();
  } else if (earlier->has_value()) {
    return Submitted{std::move(**earlier), true};
  }
  auto id = insert();
  if (!id.ok()) return id.status();
  auto job = load_job(writer_, *id);
  if (!job.ok()) return job.status();
  if (Status s = txn.commit(); !s.ok()) return s;
  return Submitted{std::move(*job), false};
}

StatusOr<Store::Submitted> Store::submit(const v1::JobSpec& spec, const std::string& request_id,
                                         std::int64_t estimated_memory_bytes, std::int64_t now_ms,
                                         const std::string& owner) {
  return submit_once(request_id, owner, [&]() -> StatusOr<std::int64_t> {
    auto id = insert_top_level_job(writer_, owner, request_id, spec, estimated_memory_bytes, now_ms, 0, false,
                                   "insert job");
    if (!id.ok()) return id.status();
    auto seq = append_event_row(writer_, *id, 0, state_event(v1::Job::QUEUED, "submitted", ""), std::nullopt,
                                now_ms);
    if (!seq.ok()) return seq.status();
    return *id;
  });
}

StatusOr<Store::Submitted> Store::submit_study(const v1::JobSpec& study,
                                               const std::vector<StudyChild>& children,
                                               const std::string& request_id, std::int64_t now_ms,
                                               const std::string& owner) {
  return submit_once(request_id, owner, [&]() -> StatusOr<std::int64_t> {
    if (children.empty()) return Status(StatusCode::kInvalidArgument, "study: no children");
    std::int64_t memory = 0;
    for (const StudyChild& child : children) memory = std::max(memory, child.memory_bytes);
    auto study_id = insert_top_level_job(writer_, owner, request_id, study, memory, now_ms,
                                         static_cast<int>(children.size()), false, "insert study");
    if (!study_id.ok()) return study_id.status();
    auto seq = append_event_row(
        writer_, *study_id, 0,
        state_event(v1::Job::QUEUED, "submitted (" + std::to_string(children.size()) + " children)", ""),
        std::nullopt, now_ms);
    if (!seq.ok()) return seq.status();
    // Children: ordinary jobs of the same owner, queued in point order.
    Stmt insert(writer_, kInsertChildSql);
    const std::string reason = "submitted (study " + job_name(*study_id) + ")";
    std::vector<std::int64_t> child_ids;
    child_ids.reserve(children.size());
    for (std::size_t i = 0; i < children.size(); ++i) {
      auto child =
          insert_child_job(writer_, insert, children[i].spec, children[i].memory_bytes, now_ms, owner,
                           *study_id, static_cast<int>(i), std::nullopt, reason, "insert child");
      if (!child.ok()) return child.status();
      child_ids.push_back(*child);
    }
    // Fit points' library simulations after every point, so the points keep
    // consecutive ids; points that share a curve queue it once.
    for (std::size_t i = 0; i < children.size(); ++i) {
      if (children[i].library.empty()) continue;
      auto queued = queue_library_children(writer_, child_ids[i], children[i].library, owner, now_ms);
      if (!queued.ok()) return queued.status();
    }
    return *study_id;
  });
}

StatusOr<Store::Submitted> Store::submit_fit(const v1::JobSpec& fit, std::int64_t memory_bytes,
                                             const std::vector<LibraryChild>& needs,
                                             const std::string& request_id, std::int64_t now_ms,
                                             const std::string& owner) {
  return submit_once(request_id, owner, [&]() -> StatusOr<std::int64_t> {
    // child_count is set below, once the children that need queueing are known.
    auto inserted =
        insert_top_level_job(writer_, owner, request_id, fit, memory_bytes, now_ms, 0, true, "insert fit");
    if (!inserted.ok()) return inserted.status();
    const std::int64_t fit_id = *inserted;
    auto queued = queue_library_children(writer_, fit_id, needs, owner, now_ms);
    if (!queued.ok()) return queued.status();
    const std::string fit_reason =
        *queued > 0 ? "submitted (" + std::to_string(*queued) + " library simulations queued as child jobs)"
                    : "submitted";
    auto seq = append_event_row(writer_, fit_id, 0, state_event(v1::Job::QUEUED, fit_reason, ""),
                                std::nullopt, now_ms);
    if (!seq.ok()) return seq.status();
    return fit_id;
  });
}

StatusOr<Store::FitLibrary> Store::library_curves_for(std::int64_t fit_id, std::int64_t max_bytes) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  FitLibrary out;
  Stmt stmt(r.get(),
            "SELECT l.key, l.curve FROM library_needs n JOIN library_curves l ON l.key = n.key "
            "WHERE n.fit_id = ? ORDER BY l.key");
  stmt.bind(1, fit_id);
  std::int64_t bytes = 0;
  int rc;
  while ((rc = stmt.step()) == SQLITE_ROW) {
    const std::string blob = stmt.blob(1);
    v1::FitLibraryCurve curve;
    // Checked again as read back: the table is only as good as what was written to it.
    if (bytes + static_cast<std::int64_t>(blob.size()) > max_bytes || !curve.ParseFromString(blob) ||
        curve.key() != stmt.text(0) || !jobs::check_library_curve(curve).ok()) {
      ++out.refused;
      continue;
    }
    bytes += static_cast<std::int64_t>(blob.size());
    out.curves.push_back(std::move(curve));
  }
  if (rc != SQLITE_DONE) return sqlite_error(r.get(), "library curves");
  Stmt ran(r.get(), "SELECT COUNT(*) FROM jobs WHERE parent_id = ? AND state IN (3, 4)");
  ran.bind(1, fit_id);
  if (ran.step() == SQLITE_ROW) out.children_run = static_cast<int>(ran.int64(0));
  return out;
}

std::int64_t Store::count_library_curves() {
  Reader r = reader();
  if (!r.get()) return -1;
  Stmt stmt(r.get(), "SELECT COUNT(*) FROM library_curves");
  return stmt.step() == SQLITE_ROW ? stmt.int64(0) : -1;
}

StatusOr<std::int64_t> Store::last_sequence(std::int64_t job_id) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  Stmt stmt(r.get(), "SELECT last_seq FROM jobs WHERE id = ?");
  stmt.bind(1, job_id);
  const int rc = stmt.step();
  if (rc == SQLITE_DONE) return Status(StatusCode::kNotFound, "job " + job_name(job_id) + " not found");
  if (rc != SQLITE_ROW) return sqlite_error(r.get(), "last sequence");
  return stmt.int64(0);
}

StatusOr<v1::Job> Store::get(std::int64_t job_id) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  return load_job(r.get(), job_id);
}

StatusOr<std::vector<v1::Job>> Store::list(std::int64_t after_id, int limit, v1::Job::State state,
                                           const std::string* owner, std::int64_t parent_id) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  const std::string sql = std::string("SELECT ") + kJobColumns +
                          " FROM jobs WHERE id > ? AND (? = 0 OR state = ?)" +
                          (owner ? " AND owner = ?5" : "") + (parent_id > 0 ? " AND parent_id = ?6" : "") +
                          " ORDER BY id LIMIT ?4";
  Stmt stmt(r.get(), sql.c_str());
  stmt.bind(1, after_id).bind(2, static_cast<int>(state)).bind(3, static_cast<int>(state)).bind(4, limit);
  if (owner) stmt.bind(5, *owner);
  if (parent_id > 0) stmt.bind(6, parent_id);
  std::vector<v1::Job> jobs;
  int rc;
  while ((rc = stmt.step()) == SQLITE_ROW) jobs.push_back(job_from_row(stmt));
  if (rc != SQLITE_DONE) return sqlite_error(r.get(), "list");
  return jobs;
}

std::int64_t Store::count(v1::Job::State state) {
  Reader r = reader();
  if (!r.get()) return -1;
  Stmt stmt(r.get(), "SELECT COUNT(*) FROM jobs WHERE state = ? AND (child_count = 0 OR library_fit = 1)");
  stmt.bind(1, static_cast<int>(state));
  return stmt.step() == SQLITE_ROW ? stmt.int64(0) : -1;
}

namespace {

// QUEUED or RUNNING -> CANCELLED with its event (inside a write transaction);
// the event's sequence.
StatusOr<std::int64_t> cancel_row(sqlite3* db, std::int64_t job_id, int attempt, const std::string& worker_id,
                                  const std::string& reason, std::int64_t now_ms) {
  Stmt update(
      db,
      "UPDATE jobs SET state = ?, lease_token = NULL, lease_expires_ms = NULL, reason = ?, end_ms = ? "
      "WHERE id = ?");
  update.bind(1, static_cast<int>(v1::Job::CANCELLED)).bind(2, reason).bind(3, now_ms).bind(4, job_id);
  if (update.step() != SQLITE_DONE) return sqlite_error(db, "cancel");
  return append_event_row(db, job_id, attempt, state_event(v1::Job::CANCELLED, reason, worker_id),
                          std::nullopt, now_ms);
}

}  // namespace

StatusOr<v1::Job> Store::cancel(std::int64_t job_id, const std::string& reason, std::int64_t now_ms,
                                std::vector<CancelledChild>* cancelled_children) {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  auto job = load_job(writer_, job_id);
  if (!job.ok()) return job.status();
  if (job->state() == v1::Job::CANCELLED) return job;
  if (is_terminal(job->state())) {
    return Status(
        StatusCode::kFailedPrecondition,
        job->id() + " has already " + (job->state() == v1::Job::SUCCEEDED ? "succeeded" : "failed"));
  }
  if (job->child_count() > 0) {
    // A study: its queued and running children first (each with its
    // ChildUpdate in the study's log), then the study, whose CANCELLED event
    // ends its watchers' streams after the children's.
    std::vector<CancelledChild> children;
    std::vector<std::pair<int, std::string>> leases;  // attempt, worker
    // A study's fit points that wait for library simulations: those
    // grandchildren first (their ChildUpdates go to the fit's log), then the
    // children.
    for (const char* sql :
         {"SELECT id, state, attempt, worker_id FROM jobs WHERE parent_id IN (SELECT id FROM jobs WHERE "
          "parent_id = ?) AND state IN (1, 2) ORDER BY id",
          "SELECT id, state, attempt, worker_id FROM jobs WHERE parent_id = ? AND state IN (1, 2) "
          "ORDER BY child_index"}) {
      Stmt find(writer_, sql);
      find.bind(1, job_id);
      while (find.step() == SQLITE_ROW) {
        children.push_back({find.int64(0), 0, find.int64(1) == v1::Job::RUNNING});
        leases.emplace_back(static_cast<int>(find.int64(2)), find.text(3));
      }
    }
    const std::string child_reason = reason + " (study " + job->id() + " cancelled)";
    for (std::size_t i = 0; i < children.size(); ++i) {
      auto seq = cancel_row(writer_, children[i].id, leases[i].first, leases[i].second, child_reason, now_ms);
      if (!seq.ok()) return seq.status();
      children[i].last_sequence = *seq;
      if (Status s = roll_up_study(writer_, children[i].id, now_ms, /*conclude=*/false); !s.ok()) return s;
    }
    if (cancelled_children) *cancelled_children = std::move(children);
  }
  if (auto seq = cancel_row(writer_, job_id, job->attempt(), job->worker_id(), reason, now_ms); !seq.ok()) {
    return seq.status();
  }
  if (Status s = roll_up_study(writer_, job_id, now_ms); !s.ok()) return s;
  auto updated = load_job(writer_, job_id);
  if (!updated.ok()) return updated.status();
  if (Status s = txn.commit(); !s.ok()) return s;
  return updated;
}

StatusOr<std::optional<Claim>> Store::claim(const std::string& worker_id, std::int64_t now_ms,
                                            std::int64_t lease_ttl_ms) {
  std::lock_guard lock(write_mutex_);
  // A fresh 128-bit token per lease: splitmix64 over a random seed and a counter.
  auto mix = [](std::uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  };
  ++token_counter_;
  char token[33];
  std::snprintf(
      token, sizeof token, "%016llx%016llx",
      static_cast<unsigned long long>(mix(token_seed_[0] + token_counter_)),
      static_cast<unsigned long long>(mix(token_seed_[1] ^ (token_counter_ * 0x2545f4914f6cdd1dULL))));

  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  Stmt update(
      writer_,
      "UPDATE jobs SET state = ?1, attempt = attempt + 1, lease_token = ?2, lease_expires_ms = ?3, "
      "worker_id = ?4, start_ms = COALESCE(start_ms, ?5), reason = '', fraction_done = 0, remaining_s = -1 "
      "WHERE id = (SELECT id FROM jobs j WHERE state = ?6 AND (child_count = 0 OR library_fit = 1) "
      // a fit waits until no job building one of its library curves is queued or running
      "AND NOT EXISTS (SELECT 1 FROM library_needs n JOIN jobs c ON c.library_key = n.key AND c.state IN (1, "
      "2) "
      "WHERE n.fit_id = j.id) ORDER BY id LIMIT 1) "
      "RETURNING id, attempt");
  update.bind(1, static_cast<int>(v1::Job::RUNNING))
      .bind(2, std::string(token))
      .bind(3, now_ms + lease_ttl_ms);
  update.bind(4, worker_id).bind(5, now_ms).bind(6, static_cast<int>(v1::Job::QUEUED));
  const int rc = update.step();
  if (rc == SQLITE_DONE) return std::optional<Claim>();
  if (rc != SQLITE_ROW) return sqlite_error(writer_, "claim");
  const std::int64_t id = update.int64(0);
  const int attempt = static_cast<int>(update.int64(1));
  update.step();
  auto seq = append_event_row(
      writer_, id, attempt,
      state_event(v1::Job::RUNNING, "leased (attempt " + std::to_string(attempt) + ")", worker_id),
      std::nullopt, now_ms);
  if (!seq.ok()) return seq.status();
  if (Status s = roll_up_study(writer_, id, now_ms); !s.ok()) return s;
  Claim claim;
  auto job = load_job(writer_, id);
  if (!job.ok()) return job.status();
  claim.job = std::move(*job);
  claim.lease_token = token;
  Stmt last(writer_, "SELECT MAX(sample_index) FROM events WHERE job_id = ? AND sample_index IS NOT NULL");
  last.bind(1, id);
  if (last.step() == SQLITE_ROW && !last.is_null(0))
    claim.last_delivered_sample_index = static_cast<int>(last.int64(0));
  last.reset();
  if (Status s = txn.commit(); !s.ok()) return s;
  return std::optional<Claim>(std::move(claim));
}

StatusOr<LeaseCheck> Store::heartbeat(std::int64_t job_id, const std::string& lease_token,
                                      std::int64_t now_ms, std::int64_t lease_ttl_ms) {
  std::lock_guard lock(write_mutex_);
  Stmt update(writer_, "UPDATE jobs SET lease_expires_ms = ? WHERE id = ? AND lease_token = ? AND state = ?");
  update.bind(1, now_ms + lease_ttl_ms)
      .bind(2, job_id)
      .bind(3, lease_token)
      .bind(4, static_cast<int>(v1::Job::RUNNING));
  if (update.step() != SQLITE_DONE) return sqlite_error(writer_, "heartbeat");
  if (sqlite3_changes(writer_) == 1) return LeaseCheck::kValid;
  return lease_state(writer_, job_id, lease_token);
}

StatusOr<ReportOutcome> Store::append_event(std::int64_t job_id, const std::string& lease_token,
                                            v1::JobEvent event, std::optional<int> sample_index,
                                            std::int64_t now_ms, std::int64_t lease_ttl_ms) {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  // The fence: renew the lease only if this token still holds it.
  Stmt renew(writer_,
             "UPDATE jobs SET lease_expires_ms = ? WHERE id = ? AND lease_token = ? AND state = ? RETURNING "
             "attempt");
  renew.bind(1, now_ms + lease_ttl_ms)
      .bind(2, job_id)
      .bind(3, lease_token)
      .bind(4, static_cast<int>(v1::Job::RUNNING));
  const int rc = renew.step();
  if (rc != SQLITE_ROW) {
    if (rc != SQLITE_DONE) return sqlite_error(writer_, "renew");
    auto check = lease_state(writer_, job_id, lease_token);
    if (!check.ok()) return check.status();
    return ReportOutcome{*check, 0, {}};
  }
  const int attempt = static_cast<int>(renew.int64(0));
  renew.step();
  if (sample_index) {
    Stmt last(
        writer_,
        "SELECT MAX(sample_index) FROM events WHERE job_id = ? AND kind = ? AND sample_index IS NOT NULL");
    last.bind(1, job_id).bind(2, std::string(kind_name(event)));
    const bool any = last.step() == SQLITE_ROW && !last.is_null(0);
    const std::int64_t highest = any ? last.int64(0) : -1;
    last.reset();
    const bool delivered = highest >= *sample_index;
    if (*sample_index > highest + 1) {
      if (Status s = txn.commit(); !s.ok()) return s;
      ReportOutcome outcome{LeaseCheck::kValid, 0, {}};
      outcome.refused = "index: " + std::to_string(*sample_index) + " skips ahead; the next sample is " +
                        std::to_string(highest + 1) + " (samples come in order, without gaps)";
      return outcome;
    }
    if (delivered) {
      // Already delivered (by this attempt's resend or an earlier attempt): keep the lease renewal only.
      if (Status s = txn.commit(); !s.ok()) return s;
      return ReportOutcome{LeaseCheck::kValid, 0, {}};
    }
  }
  if (event.has_progress()) {
    Stmt progress(writer_, "UPDATE jobs SET fraction_done = ?, remaining_s = ? WHERE id = ?");
    progress.bind(1, event.progress().fraction_done())
        .bind(2, event.progress().estimated_remaining_s())
        .bind(3, job_id);
    if (progress.step() != SQLITE_DONE) return sqlite_error(writer_, "progress");
  }
  auto seq = append_event_row(writer_, job_id, attempt, std::move(event), sample_index, now_ms);
  if (!seq.ok()) return seq.status();
  if (Status s = txn.commit(); !s.ok()) return s;
  return ReportOutcome{LeaseCheck::kValid, *seq, {}};
}

namespace {

// A library curve that ended early (at end_deformation) tells every fit
// whose curves of that key must reach further that it searches w only above
// this one (curves of smaller w end earlier still: strain hardening weakens
// as w falls; jobs/fit/fit_job.cc cuts its grid there): the queued and
// running jobs building that key's curves of smaller w that only such fits
// need are cancelled (with their ChildUpdate), in the caller's transaction.
// A worker running one learns it at its next heartbeat.
Status cancel_unneeded_curves(sqlite3* db, const std::string& key, double end_deformation,
                              std::int64_t now_ms) {
  std::string base;
  double w = 0.0;
  {
    Stmt find(db, "SELECT base, w FROM library_needs WHERE key = ? LIMIT 1");
    find.bind(1, key);
    if (find.step() != SQLITE_ROW) return {};
    base = find.text(0);
    w = find.real(1);
  }
  struct Useless {
    std::int64_t id;
    int attempt;
    std::string worker_id;
    double w;
  };
  std::vector<Useless> useless;
  {
    // Every need of such a job's key: same base, smaller w, and a fit that needs more than this curve
    // reaches.
    Stmt find(db,
              "SELECT c.id, c.attempt, c.worker_id, MIN(n.w) FROM jobs c JOIN library_needs n ON n.key = "
              "c.library_key WHERE c.state IN (1, 2) AND n.base = ?1 AND n.w < ?2 GROUP BY c.id "
              "HAVING MIN(n.needed) > ?3");
    find.bind(1, base).bind(2, w).bind(3, end_deformation);
    while (find.step() == SQLITE_ROW) {
      useless.push_back({find.int64(0), static_cast<int>(find.int64(1)), find.text(2), find.real(3)});
    }
  }
  char reason[240];
  std::snprintf(reason, sizeof reason,
                "not needed: the curve at w = %g ends at deformation %.4g, below what the fits need; they "
                "search w only above it",
                w, end_deformation);
  for (const Useless& u : useless) {
    auto seq = cancel_row(db, u.id, u.attempt, u.worker_id, reason, now_ms);
    if (!seq.ok()) return seq.status();
    if (Status s = roll_up_study(db, u.id, now_ms); !s.ok()) return s;
  }
  return {};
}

// A library child that ended (inside the caller's write transaction): its
// force samples become the curve of its library_key, unless a curve of that
// key is stored already or the samples fail the checks (a hostile or broken
// worker: nothing stored, the fit simulates the curve itself).
Status store_library_curve(sqlite3* db, std::int64_t job_id, const std::string& failure,
                           std::int64_t now_ms) {
  std::string key;
  v1::JobSpec spec;
  {
    Stmt row(db, "SELECT library_key, spec FROM jobs WHERE id = ?");
    row.bind(1, job_id);
    if (row.step() != SQLITE_ROW) return sqlite_error(db, "library child");
    if (row.is_null(0)) return {};
    key = row.text(0);
    if (!spec.ParseFromString(row.blob(1))) return {};
  }
  std::vector<v1::ForceSample> samples;
  {
    Stmt events(db,
                "SELECT payload FROM events WHERE job_id = ? AND kind = 'force_sample' ORDER BY sample_index "
                "LIMIT ?");
    events.bind(1, job_id).bind(2, jobs::kMaxLibraryCurvePoints + 1);
    while (events.step() == SQLITE_ROW) {
      v1::JobEvent event;
      if (!event.ParseFromString(events.blob(0)) || !event.has_force_sample()) return {};
      samples.push_back(event.force_sample());
    }
  }
  auto curve = jobs::library_curve_from_samples(key, spec, std::move(samples), failure);
  if (!curve.ok()) return {};
  std::string base;
  {
    Stmt find(db, "SELECT base FROM library_needs WHERE key = ? LIMIT 1");
    find.bind(1, key);
    if (find.step() != SQLITE_ROW) return {};  // no fit needs it any more (deleted)
    base = find.text(0);
  }
  const double end = curve->deformation(curve->deformation_size() - 1);
  Stmt insert(
      db,
      "INSERT OR IGNORE INTO library_curves (key, base, w, end_deformation, curve, job_id, create_ms) "
      "VALUES (?, ?, ?, ?, ?, ?, ?)");
  insert.bind(1, key).bind(2, base).bind(3, curve->mooney_rivlin_w()).bind(4, end);
  insert.bind_blob(5, curve->SerializeAsString()).bind(6, job_id).bind(7, now_ms);
  if (insert.step() != SQLITE_DONE) return sqlite_error(db, "insert library curve");
  if (!failure.empty()) return cancel_unneeded_curves(db, key, end, now_ms);
  return {};
}

// The fenced terminal transition shared by finish, fail and release.
StatusOr<v1::Job> end_attempt(sqlite3* db, std::int64_t job_id, const std::string& lease_token,
                              v1::Job::State state, const std::string& reason, std::int64_t result_size_bytes,
                              std::int64_t now_ms, const std::function<Status()>& before_commit) {
  WriteTransaction txn(db);
  if (!txn.status().ok()) return txn.status();
  const bool released = state == v1::Job::QUEUED;
  Stmt update(
      db, released ? "UPDATE jobs SET state = ?1, lease_token = NULL, lease_expires_ms = NULL, reason = ?2, "
                     "released = released + 1, fraction_done = 0, remaining_s = -1 "
                     "WHERE id = ?3 AND lease_token = ?4 AND state = ?5 RETURNING attempt, worker_id"
                   : "UPDATE jobs SET state = ?1, lease_token = NULL, lease_expires_ms = NULL, reason = ?2, "
                     "end_ms = ?6, result_bytes = CASE WHEN ?7 < 0 THEN result_bytes ELSE ?7 END, "
                     "fraction_done = CASE WHEN ?1 = 3 THEN 1.0 ELSE fraction_done END, remaining_s = 0 "
                     "WHERE id = ?3 AND lease_token = ?4 AND state = ?5 RETURNING attempt, worker_id");
  update.bind(1, static_cast<int>(state)).bind(2, reason).bind(3, job_id).bind(4, lease_token);
  update.bind(5, static_cast<int>(v1::Job::RUNNING));
  if (!released) update.bind(6, now_ms).bind(7, result_size_bytes);
  const int rc = update.step();
  if (rc != SQLITE_ROW) {
    if (rc != SQLITE_DONE) return sqlite_error(db, "end attempt");
    auto check = lease_state(db, job_id, lease_token);
    if (!check.ok()) return check.status();
    return lease_status(*check);
  }
  const int attempt = static_cast<int>(update.int64(0));
  const std::string worker_id = update.text(1);
  update.step();
  if (before_commit) {
    if (Status s = before_commit(); !s.ok()) return s;
  }
  if (state == v1::Job::SUCCEEDED || state == v1::Job::FAILED) {
    // In this transaction: a fit leased after the commit finds the curve.
    if (Status s = store_library_curve(db, job_id, state == v1::Job::FAILED ? reason : "", now_ms); !s.ok()) {
      return s;
    }
  }
  auto seq =
      append_event_row(db, job_id, attempt, state_event(state, reason, worker_id), std::nullopt, now_ms);
  if (!seq.ok()) return seq.status();
  if (Status s = roll_up_study(db, job_id, now_ms); !s.ok()) return s;
  auto job = load_job(db, job_id);
  if (!job.ok()) return job.status();
  if (Status s = txn.commit(); !s.ok()) return s;
  return job;
}

}  // namespace

StatusOr<v1::Job> Store::finish(std::int64_t job_id, const std::string& lease_token,
                                std::int64_t result_size_bytes, std::int64_t now_ms,
                                const std::function<Status()>& before_commit) {
  std::lock_guard lock(write_mutex_);
  return end_attempt(writer_, job_id, lease_token, v1::Job::SUCCEEDED, "", result_size_bytes, now_ms,
                     before_commit);
}

StatusOr<v1::Job> Store::fail(std::int64_t job_id, const std::string& lease_token, const std::string& reason,
                              std::int64_t result_size_bytes, std::int64_t now_ms,
                              const std::function<Status()>& before_commit) {
  std::lock_guard lock(write_mutex_);
  return end_attempt(writer_, job_id, lease_token, v1::Job::FAILED, reason, result_size_bytes, now_ms,
                     before_commit);
}

StatusOr<v1::Job> Store::release(std::int64_t job_id, const std::string& lease_token,
                                 const std::string& reason, std::int64_t now_ms) {
  std::lock_guard lock(write_mutex_);
  return end_attempt(writer_, job_id, lease_token, v1::Job::QUEUED, reason, -1, now_ms, {});
}

StatusOr<std::vector<v1::Job>> Store::requeue_expired(std::int64_t now_ms, std::int64_t max_run_ms) {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  struct Expired {
    std::int64_t id;
    int attempt;
    int released;
    std::string worker_id;
    bool overdue;
  };
  std::vector<Expired> expired;
  {
    // The attempt's start: the time of its RUNNING event (events of the attempt, kind "state").
    Stmt find(writer_,
              "SELECT id, attempt, released, worker_id, lease_expires_ms >= ?2 FROM jobs j WHERE state = ?1 "
              "AND (child_count = 0 OR library_fit = 1) "
              "AND (lease_expires_ms < ?2 OR (?3 > 0 AND (SELECT MIN(time_ms) FROM events e WHERE "
              "e.job_id = j.id AND e.attempt = j.attempt AND e.kind = 'state') < ?2 - ?3))");
    find.bind(1, static_cast<int>(v1::Job::RUNNING)).bind(2, now_ms).bind(3, max_run_ms);
    while (find.step() == SQLITE_ROW) {
      expired.push_back({find.int64(0), static_cast<int>(find.int64(1)), static_cast<int>(find.int64(2)),
                         find.text(3), find.int64(4) != 0});
    }
  }
  std::vector<v1::Job> changed;
  for (const Expired& e : expired) {
    const int counted = e.attempt - e.released;
    const bool give_up = counted >= options_.max_attempts;
    const std::string why = e.overdue ? "attempt " + std::to_string(e.attempt) + " of worker " + e.worker_id +
                                            " ran longer than the server's limit of " +
                                            std::to_string(max_run_ms / 1000) + " s (--max-run-time-s)"
                                      : "lease of worker " + e.worker_id + " expired";
    const std::string reason =
        give_up ? why + "; " + std::to_string(counted) + " attempts reached the limit of " +
                      std::to_string(options_.max_attempts)
                : why + (e.overdue ? "" : " (attempt " + std::to_string(e.attempt) + ")");
    const v1::Job::State state = give_up ? v1::Job::FAILED : v1::Job::QUEUED;
    Stmt update(
        writer_,
        "UPDATE jobs SET state = ?, lease_token = NULL, lease_expires_ms = NULL, reason = ?, "
        "end_ms = CASE WHEN ? THEN ? ELSE NULL END, fraction_done = 0, remaining_s = -1 WHERE id = ?");
    update.bind(1, static_cast<int>(state))
        .bind(2, reason)
        .bind(3, give_up ? 1 : 0)
        .bind(4, now_ms)
        .bind(5, e.id);
    if (update.step() != SQLITE_DONE) return sqlite_error(writer_, "requeue");
    auto seq = append_event_row(writer_, e.id, e.attempt, state_event(state, reason, e.worker_id),
                                std::nullopt, now_ms);
    if (!seq.ok()) return seq.status();
    if (Status s = roll_up_study(writer_, e.id, now_ms); !s.ok()) return s;
    auto job = load_job(writer_, e.id);
    if (!job.ok()) return job.status();
    changed.push_back(std::move(*job));
  }
  if (Status s = txn.commit(); !s.ok()) return s;
  return changed;
}

Status Store::extend_running_leases(std::int64_t now_ms, std::int64_t lease_ttl_ms) {
  std::lock_guard lock(write_mutex_);
  Stmt update(writer_,
              "UPDATE jobs SET lease_expires_ms = MAX(COALESCE(lease_expires_ms, 0), ?) WHERE state = ? "
              "AND (child_count = 0 OR library_fit = 1)");
  update.bind(1, now_ms + lease_ttl_ms).bind(2, static_cast<int>(v1::Job::RUNNING));
  if (update.step() != SQLITE_DONE) return sqlite_error(writer_, "extend leases");
  return {};
}

Status Store::forgive_running_attempts() {
  std::lock_guard lock(write_mutex_);
  Stmt update(
      writer_,
      "UPDATE jobs SET released = released + 1 WHERE state = ? AND (child_count = 0 OR library_fit = 1)");
  update.bind(1, static_cast<int>(v1::Job::RUNNING));
  if (update.step() != SQLITE_DONE) return sqlite_error(writer_, "forgive attempts");
  return {};
}

Status Store::delete_job(std::int64_t job_id, std::vector<std::int64_t>* deleted_children) {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  auto job = load_job(writer_, job_id);
  if (!job.ok()) return job.status();
  if (!is_terminal(job->state())) {
    return {StatusCode::kFailedPrecondition, "job_id: " + job->id() + " is " +
                                                 v1::Job::State_Name(job->state()) +
                                                 "; only a SUCCEEDED, FAILED or CANCELLED job can be deleted "
                                                 "(cancel it first)"};
  }
  if (!job->parent_job_id().empty()) {
    return {StatusCode::kFailedPrecondition,
            "job_id: " + job->id() + " is point " + std::to_string(job->child_index()) + " of study " +
                job->parent_job_id() + "; delete the study (it deletes its children)"};
  }
  std::vector<std::int64_t> children;
  {
    // Its children, and the library simulations of a study's fit points.
    Stmt find(
        writer_,
        "SELECT id FROM jobs WHERE parent_id = ?1 OR parent_id IN (SELECT id FROM jobs WHERE parent_id = "
        "?1) ORDER BY id");
    find.bind(1, job_id);
    while (find.step() == SQLITE_ROW) children.push_back(find.int64(0));
  }
  // A terminal study has only terminal children (it ends after its last
  // child), and a fit ends only after its library simulations.
  constexpr const char* kGrandchildren =
      "(SELECT id FROM jobs WHERE parent_id IN (SELECT id FROM jobs WHERE parent_id = ?1))";
  const std::string grand_events = std::string("DELETE FROM events WHERE job_id IN ") + kGrandchildren;
  const std::string grand_checkpoints =
      std::string("DELETE FROM checkpoints WHERE job_id IN ") + kGrandchildren;
  const std::string grand_jobs = std::string("DELETE FROM jobs WHERE id IN ") + kGrandchildren;
  for (const char* sql :
       {grand_events.c_str(), grand_checkpoints.c_str(), grand_jobs.c_str(),
        "DELETE FROM library_needs WHERE fit_id IN (SELECT id FROM jobs WHERE parent_id = ?1)",
        "DELETE FROM events WHERE job_id IN (SELECT id FROM jobs WHERE parent_id = ?1)",
        "DELETE FROM checkpoints WHERE job_id IN (SELECT id FROM jobs WHERE parent_id = ?1)",
        "DELETE FROM jobs WHERE parent_id = ?1", "DELETE FROM library_needs WHERE fit_id = ?1",
        "DELETE FROM events WHERE job_id = ?1", "DELETE FROM checkpoints WHERE job_id = ?1",
        "DELETE FROM jobs WHERE id = ?1"}) {
    Stmt remove(writer_, sql);
    remove.bind(1, job_id);
    if (remove.step() != SQLITE_DONE) return sqlite_error(writer_, "delete job");
  }
  if (Status s = txn.commit(); !s.ok()) return s;
  if (deleted_children) *deleted_children = std::move(children);
  return {};
}

StatusOr<std::vector<v1::Job>> Store::release_all_running(const std::string& reason, std::int64_t now_ms) {
  std::vector<std::pair<std::int64_t, std::string>> running;
  {
    Reader r = reader();
    Stmt find(r.get(),
              "SELECT id, lease_token FROM jobs WHERE state = ? AND (child_count = 0 OR library_fit = 1)");
    find.bind(1, static_cast<int>(v1::Job::RUNNING));
    while (find.step() == SQLITE_ROW) running.emplace_back(find.int64(0), find.text(1));
  }
  std::vector<v1::Job> changed;
  for (const auto& [id, token] : running) {
    auto job = release(id, token, reason, now_ms);
    if (job.ok()) changed.push_back(std::move(*job));
  }
  return changed;
}

StatusOr<std::vector<v1::JobEvent>> Store::events_after(std::int64_t job_id, std::int64_t after_sequence,
                                                        int limit) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  Stmt stmt(r.get(), "SELECT payload FROM events WHERE job_id = ? AND seq > ? ORDER BY seq LIMIT ?");
  stmt.bind(1, job_id).bind(2, after_sequence).bind(3, limit);
  std::vector<v1::JobEvent> events;
  int rc;
  while ((rc = stmt.step()) == SQLITE_ROW) {
    v1::JobEvent event;
    if (!event.ParseFromString(stmt.blob(0))) return Status(StatusCode::kInternal, "corrupt event payload");
    events.push_back(std::move(event));
  }
  if (rc != SQLITE_DONE) return sqlite_error(r.get(), "events");
  return events;
}

StatusOr<LeaseCheck> Store::check_lease(std::int64_t job_id, const std::string& lease_token) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  return lease_state(r.get(), job_id, lease_token);
}

// --- ownership and API tokens ---

StatusOr<std::string> Store::job_owner(std::int64_t job_id) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  Stmt stmt(r.get(), "SELECT owner FROM jobs WHERE id = ?");
  stmt.bind(1, job_id);
  const int rc = stmt.step();
  if (rc == SQLITE_DONE) return Status(StatusCode::kNotFound, "job " + job_name(job_id) + " not found");
  if (rc != SQLITE_ROW) return sqlite_error(r.get(), "owner");
  return stmt.text(0);
}

StatusOr<std::int64_t> Store::add_token(const std::string& user, const std::string& role,
                                        const std::string& token_hash, std::int64_t now_ms) {
  std::lock_guard lock(write_mutex_);
  Stmt insert(writer_, "INSERT INTO tokens (user, role, hash, create_ms) VALUES (?, ?, ?, ?) RETURNING id");
  insert.bind(1, user).bind(2, role).bind(3, token_hash).bind(4, now_ms);
  if (insert.step() != SQLITE_ROW) return sqlite_error(writer_, "insert token");
  const std::int64_t id = insert.int64(0);
  insert.step();
  return id;
}

namespace {

constexpr const char* kTokenColumns = "id, user, role, create_ms, COALESCE(revoke_ms, 0)";

TokenRecord token_from_row(const Stmt& row) {
  return TokenRecord{row.int64(0), row.text(1), row.text(2), row.int64(3), row.int64(4)};
}

}  // namespace

StatusOr<std::optional<TokenRecord>> Store::find_token(const std::string& token_hash) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  const std::string sql = std::string("SELECT ") + kTokenColumns + " FROM tokens WHERE hash = ?";
  Stmt stmt(r.get(), sql.c_str());
  stmt.bind(1, token_hash);
  const int rc = stmt.step();
  if (rc == SQLITE_DONE) return std::optional<TokenRecord>();
  if (rc != SQLITE_ROW) return sqlite_error(r.get(), "find token");
  return std::optional<TokenRecord>(token_from_row(stmt));
}

StatusOr<std::vector<TokenRecord>> Store::list_tokens() {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  const std::string sql = std::string("SELECT ") + kTokenColumns + " FROM tokens ORDER BY id";
  Stmt stmt(r.get(), sql.c_str());
  std::vector<TokenRecord> tokens;
  int rc;
  while ((rc = stmt.step()) == SQLITE_ROW) tokens.push_back(token_from_row(stmt));
  if (rc != SQLITE_DONE) return sqlite_error(r.get(), "list tokens");
  return tokens;
}

StatusOr<int> Store::revoke_tokens(std::int64_t id, const std::string& user, std::int64_t now_ms) {
  std::lock_guard lock(write_mutex_);
  Stmt update(writer_, id > 0 ? "UPDATE tokens SET revoke_ms = ?1 WHERE id = ?2 AND revoke_ms IS NULL"
                              : "UPDATE tokens SET revoke_ms = ?1 WHERE user = ?3 AND revoke_ms IS NULL");
  update.bind(1, now_ms);
  if (id > 0) {
    update.bind(2, id);
  } else {
    update.bind(3, user);
  }
  if (update.step() != SQLITE_DONE) return sqlite_error(writer_, "revoke");
  return sqlite3_changes(writer_);
}

std::int64_t Store::count_tokens(bool include_revoked) {
  Reader r = reader();
  if (!r.get()) return -1;
  Stmt stmt(r.get(), include_revoked ? "SELECT COUNT(*) FROM tokens"
                                     : "SELECT COUNT(*) FROM tokens WHERE revoke_ms IS NULL");
  return stmt.step() == SQLITE_ROW ? stmt.int64(0) : -1;
}

// --- checkpoints ---

Status Store::save_checkpoint(std::int64_t job_id, const std::string& lease_token,
                              const CheckpointRecord& record, const std::function<Status()>& before_commit) {
  std::lock_guard lock(write_mutex_);
  WriteTransaction txn(writer_);
  if (!txn.status().ok()) return txn.status();
  auto check = lease_state(writer_, job_id, lease_token);
  if (!check.ok()) return check.status();
  if (*check != LeaseCheck::kValid) return lease_status(*check);
  Stmt upsert(writer_,
              "INSERT INTO checkpoints (job_id, attempt, time_step, last_sample_index, size_bytes, time_ms) "
              "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT (job_id) DO UPDATE SET attempt = excluded.attempt, "
              "time_step = excluded.time_step, last_sample_index = excluded.last_sample_index, "
              "size_bytes = excluded.size_bytes, time_ms = excluded.time_ms");
  upsert.bind(1, job_id)
      .bind(2, record.attempt)
      .bind(3, record.time_step)
      .bind(4, record.last_sample_index)
      .bind(5, record.size_bytes)
      .bind(6, record.time_ms);
  if (upsert.step() != SQLITE_DONE) return sqlite_error(writer_, "save checkpoint");
  if (before_commit) {
    if (Status s = before_commit(); !s.ok()) return s;
  }
  return txn.commit();
}

StatusOr<std::optional<CheckpointRecord>> Store::checkpoint(std::int64_t job_id) {
  Reader r = reader();
  if (!r.get()) return Status(StatusCode::kInternal, "sqlite: no reader connection");
  Stmt stmt(
      r.get(),
      "SELECT attempt, time_step, last_sample_index, size_bytes, time_ms FROM checkpoints WHERE job_id = ?");
  stmt.bind(1, job_id);
  const int rc = stmt.step();
  if (rc == SQLITE_DONE) return std::optional<CheckpointRecord>();
  if (rc != SQLITE_ROW) return sqlite_error(r.get(), "checkpoint");
  CheckpointRecord record;
  record.attempt = static_cast<int>(stmt.int64(0));
  record.time_step = stmt.int64(1);
  record.last_sample_index = static_cast<int>(stmt.int64(2));
  record.size_bytes = stmt.int64(3);
  record.time_ms = stmt.int64(4);
  return std::optional<CheckpointRecord>(record);
}

Status Store::delete_checkpoint(std::int64_t job_id) {
  std::lock_guard lock(write_mutex_);
  Stmt remove(writer_, "DELETE FROM checkpoints WHERE job_id = ?");
  remove.bind(1, job_id);
  if (remove.step() != SQLITE_DONE) return sqlite_error(writer_, "delete checkpoint");
  return {};
}

}  // namespace cellflow::server
