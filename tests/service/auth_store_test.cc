// Authentication pieces without a server: the schema 1 -> 2 migration (job
// owners, per-user request ids), the tokens table, token generation and
// hashing, the Authenticator's verdicts and the loopback rule.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <set>

#include "server/auth.h"
#include "server/store.h"

namespace cellflow::server {
namespace {

namespace fs = std::filesystem;

class AuthStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_auth_store_test_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    options_.path = (dir_ / "jobs.sqlite").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::unique_ptr<Store> open() {
    auto store = Store::open(options_);
    EXPECT_TRUE(store.ok()) << store.status().to_string();
    return store.ok() ? std::move(*store) : nullptr;
  }

  fs::path dir_;
  StoreOptions options_;
};

v1::JobSpec spec() {
  v1::JobSpec spec;
  spec.mutable_compression()->set_max_deformation(0.1);
  return spec;
}

TEST_F(AuthStoreTest, SchemaOneDatabaseMigratesKeepingItsJobsAndRequestIds) {
  // A database as the schema-1 server left it: one job with a request id.
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(options_.path.c_str(), &db), SQLITE_OK);
    const char* v1_schema = R"sql(
CREATE TABLE schema_version (version INTEGER NOT NULL);
INSERT INTO schema_version (version) VALUES (1);
CREATE TABLE jobs (
  id INTEGER PRIMARY KEY AUTOINCREMENT, request_id TEXT UNIQUE, spec BLOB NOT NULL,
  state INTEGER NOT NULL CHECK (state BETWEEN 1 AND 5), attempt INTEGER NOT NULL DEFAULT 0,
  released INTEGER NOT NULL DEFAULT 0, lease_token TEXT, lease_expires_ms INTEGER,
  worker_id TEXT NOT NULL DEFAULT '', reason TEXT NOT NULL DEFAULT '', fraction_done REAL NOT NULL DEFAULT 0,
  remaining_s REAL NOT NULL DEFAULT -1, last_seq INTEGER NOT NULL DEFAULT 0, result_bytes INTEGER NOT NULL DEFAULT 0,
  memory_bytes INTEGER NOT NULL DEFAULT 0, create_ms INTEGER NOT NULL, start_ms INTEGER, end_ms INTEGER);
CREATE INDEX jobs_by_state ON jobs (state, id);
CREATE TABLE events (job_id INTEGER NOT NULL REFERENCES jobs (id), seq INTEGER NOT NULL, attempt INTEGER NOT NULL,
  kind TEXT NOT NULL, sample_index INTEGER, time_ms INTEGER NOT NULL, payload BLOB NOT NULL,
  PRIMARY KEY (job_id, seq)) WITHOUT ROWID;
CREATE UNIQUE INDEX events_by_sample ON events (job_id, kind, sample_index) WHERE sample_index IS NOT NULL;
INSERT INTO jobs (request_id, spec, state, create_ms) VALUES ('old-request', x'', 1, 1000);
)sql";
    char* error = nullptr;
    ASSERT_EQ(sqlite3_exec(db, v1_schema, nullptr, nullptr, &error), SQLITE_OK) << (error ? error : "");
    sqlite3_close(db);
  }
  auto store = open();
  ASSERT_TRUE(store);
  EXPECT_EQ(store->schema_version(), Store::kSchemaVersion);  // migrated through every version
  auto job = store->get(1);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->request_id(), "old-request");
  EXPECT_TRUE(job->parent_job_id().empty());  // schema 3: an older job is neither child nor study
  EXPECT_EQ(job->child_count(), 0);
  auto owner = store->job_owner(1);
  ASSERT_TRUE(owner.ok());
  EXPECT_EQ(*owner, "");  // older jobs belong to nobody: admins see them
  // The old request id is the owner-less one's; another user's same id is a new job.
  auto again = store->submit(spec(), "old-request", 0, 2000, "");
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->existed);
  auto alice = store->submit(spec(), "old-request", 0, 2000, "alice");
  ASSERT_TRUE(alice.ok());
  EXPECT_FALSE(alice->existed);
  EXPECT_EQ(alice->job.request_id(), "old-request");
  auto bob = store->submit(spec(), "old-request", 0, 2000, "bob");
  ASSERT_TRUE(bob.ok());
  EXPECT_FALSE(bob->existed);
  EXPECT_NE(bob->job.id(), alice->job.id());
  const std::string who = "alice";
  auto listed = store->list(0, 10, v1::Job::STATE_UNSPECIFIED, &who);
  ASSERT_TRUE(listed.ok());
  ASSERT_EQ(listed->size(), 1u);
  EXPECT_EQ((*listed)[0].id(), alice->job.id());
  auto all = store->list(0, 10, v1::Job::STATE_UNSPECIFIED);
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(all->size(), 3u);
}

TEST_F(AuthStoreTest, TokensAreStoredHashedListedAndRevoked) {
  auto store = open();
  ASSERT_TRUE(store);
  std::set<std::string> seen;
  for (int i = 0; i < 20; ++i) {
    auto token = generate_token();
    ASSERT_TRUE(token.ok());
    EXPECT_EQ(token->size(), 43u);  // 32 bytes, base64url, no padding
    EXPECT_EQ(token->find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_"),
              std::string::npos);
    EXPECT_TRUE(seen.insert(*token).second);
  }
  // SHA-256 of "abc" (FIPS 180-2 test vector).
  EXPECT_EQ(hash_token("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");

  const std::string alice = *generate_token(), alice2 = *generate_token(), worker = *generate_token();
  auto a = store->add_token("alice", "user", hash_token(alice), 1000);
  auto a2 = store->add_token("alice", "admin", hash_token(alice2), 1000);
  auto w = store->add_token("w", "worker", hash_token(worker), 1000);
  ASSERT_TRUE(a.ok() && a2.ok() && w.ok());
  EXPECT_EQ(store->count_tokens(), 3);

  Authenticator auth(store.get(), AuthMode::kToken);
  using Api = Authenticator::Api;
  EXPECT_EQ(auth.check(Api::kPublic, "").status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(auth.check(Api::kPublic, "Basic abc").status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(auth.check(Api::kPublic, "Bearer " + alice + "x").status.error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  Verdict ok = auth.check(Api::kPublic, "Bearer " + alice);
  ASSERT_TRUE(ok.status.ok()) << ok.status.error_message();
  EXPECT_EQ(ok.identity.user, "alice");
  EXPECT_FALSE(ok.identity.admin);
  EXPECT_TRUE(auth.check(Api::kPublic, "Bearer " + alice2).identity.admin);
  EXPECT_EQ(auth.check(Api::kWorker, "Bearer " + alice).status.error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(auth.check(Api::kPublic, "Bearer " + worker).status.error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_TRUE(auth.check(Api::kWorker, "Bearer " + worker).status.ok());
  auth.set_local_worker_secret("local-secret");
  EXPECT_TRUE(auth.check(Api::kWorker, "Bearer local-secret").status.ok());
  EXPECT_EQ(auth.check(Api::kPublic, "Bearer local-secret").status.error_code(),
            grpc::StatusCode::UNAUTHENTICATED);

  // Revoke one by id, then the rest of the user's.
  auto by_id = store->revoke_tokens(*a, "", 2000);
  ASSERT_TRUE(by_id.ok());
  EXPECT_EQ(*by_id, 1);
  EXPECT_EQ(auth.check(Api::kPublic, "Bearer " + alice).status.error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(auth.check(Api::kPublic, "Bearer " + alice2).status.ok());
  auto by_user = store->revoke_tokens(0, "alice", 3000);
  ASSERT_TRUE(by_user.ok());
  EXPECT_EQ(*by_user, 1);  // the one still valid
  EXPECT_FALSE(auth.check(Api::kPublic, "Bearer " + alice2).status.ok());
  EXPECT_EQ(store->count_tokens(), 1);
  EXPECT_EQ(store->count_tokens(true), 3);
  auto listed = store->list_tokens();
  ASSERT_TRUE(listed.ok());
  ASSERT_EQ(listed->size(), 3u);
  EXPECT_EQ((*listed)[0].user, "alice");
  EXPECT_EQ((*listed)[0].revoke_ms, 2000);
  EXPECT_EQ((*listed)[1].role, "admin");
  EXPECT_EQ((*listed)[1].revoke_ms, 3000);
  EXPECT_FALSE((*listed)[2].revoked());

  // --auth none: everyone is the local admin.
  Authenticator none(store.get(), AuthMode::kNone);
  Verdict local = none.check(Api::kPublic, "");
  EXPECT_TRUE(local.status.ok());
  EXPECT_TRUE(local.identity.admin);
}

TEST(AuthAddressTest, LoopbackAddresses) {
  for (const char* address : {"127.0.0.1:50051", "127.0.0.1:0", "127.1.2.3:1", "localhost:50051",
                              "[::1]:50051", "unix:/run/cellflow.sock", "unix-abstract:cellflow"}) {
    EXPECT_TRUE(is_loopback_address(address)) << address;
  }
  for (const char* address : {"0.0.0.0:50051", "[::]:50051", "10.0.0.5:50051", "login1:50051", ":50051",
                              "127.0.0.1.example.org:1", "128.0.0.1:1"}) {
    EXPECT_FALSE(is_loopback_address(address)) << address;
  }
}

TEST(AuthAddressTest, UserNames) {
  EXPECT_TRUE(valid_user_name("alice"));
  EXPECT_TRUE(valid_user_name("a.b-c_d@host"));
  EXPECT_FALSE(valid_user_name(""));
  EXPECT_FALSE(valid_user_name("with space"));
  EXPECT_FALSE(valid_user_name(std::string(65, 'a')));
  EXPECT_FALSE(valid_user_name("semi;colon"));
}

}  // namespace
}  // namespace cellflow::server
