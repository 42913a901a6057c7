// Broken and hostile inputs give an error naming the file and the problem,
// never a crash, a hang or a silently short curve.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>

#include "afm_test_util.h"
#include "io/afm/read_force_curve.h"

namespace cellflow::afm {
namespace {

namespace fs = std::filesystem;
using testing::data_file;

class AfmBadInput : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "afm-bad-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& content) {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << content;
    return p;
  }

  fs::path dir_;
};

void expect_error_mentions(const StatusOr<ForceCurve>& r, const std::string& a, const std::string& b = "") {
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(a), std::string::npos) << r.status().message();
  if (!b.empty()) {
    EXPECT_NE(r.status().message().find(b), std::string::npos) << r.status().message();
  }
}

TEST_F(AfmBadInput, EmptyFile) {
  const std::string p = write("empty.csv", "");
  expect_error_mentions(read_force_curve(p), p, "empty");
}

TEST_F(AfmBadInput, TruncatedJpkArchive) {
  std::ifstream in(data_file("fmt-jpk-fd_spot3-0192.jpk-force"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 1000u);
  const std::string p = write("half.jpk-force", bytes.substr(0, bytes.size() / 2));
  expect_error_mentions(read_force_curve(p), p, "zip");
}

TEST_F(AfmBadInput, Directory) {
  expect_error_mentions(read_force_curve(dir_.string()), dir_.string(), "directory");
}

TEST_F(AfmBadInput, FifoReturnsAtOnce) {
  const std::string p = (dir_ / "pipe.csv").string();
  ASSERT_EQ(::mkfifo(p.c_str(), 0600), 0);
  // Run on a thread so that a blocking open shows as a timeout, not a hang
  // of the whole suite (ctest's timeout would still end it).
  auto f = std::async(std::launch::async, [&] { return read_force_curve(p); });
  ASSERT_EQ(f.wait_for(std::chrono::seconds(5)), std::future_status::ready) << "reader blocked on a FIFO";
  expect_error_mentions(f.get(), p, "FIFO");
}

TEST_F(AfmBadInput, MissingFile) {
  const std::string p = (dir_ / "nope.csv").string();
  auto r = read_force_curve(p);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
}

TEST_F(AfmBadInput, NonNumericDataNamesTheLine) {
  const std::string p = write("bad.csv", "# comment\nindentation (um),force (nN)\n0,0\n0.1,0.2\n0.2,abc\n");
  expect_error_mentions(read_force_curve(p), p + ": line 5", "abc");
}

TEST_F(AfmBadInput, NonNumericNtmdtNamesTheLine) {
  const std::string p = write("bad.txt", "1,0\t2,0\t3,0\n1,5\t2,5\t3,5\n1,7\tx\t3,7\n");
  ReadOptions o;
  o.spring_constant_n_per_m = 0.1;
  o.sensitivity_m_per_v = 10.0;
  expect_error_mentions(read_force_curve(p, o), "line 3", "'x'");
}

TEST_F(AfmBadInput, UnknownUnits) {
  const std::string p = write("units.csv", "indentation (um),force (furlongs)\n0,0\n");
  expect_error_mentions(read_force_curve(p), "unknown unit 'furlongs'", "line 1");
  const std::string q = write("nounit.csv", "indentation (um),force\n0,0\n");
  expect_error_mentions(read_force_curve(q), "has no unit");
  const std::string r = write("wrongdim.csv", "indentation (nN),force (nN)\n0,0\n");
  expect_error_mentions(read_force_curve(r), "does not fit");
}

TEST_F(AfmBadInput, FileSizeLimit) {
  ReadOptions o;
  o.max_file_bytes = 1000;
  expect_error_mentions(read_force_curve(data_file("fmt-jpk-fd_spot3-0192.jpk-force"), o),
                        "exceeds the limit");
}

TEST_F(AfmBadInput, ZipEntryOverDeclaredSizeLimit) {
  ReadOptions o;
  o.max_entry_bytes = 5000;  // segments/0/segment-header.properties of spot3 inflates to 11407 bytes
  auto r = read_force_curve(data_file("fmt-jpk-fd_spot3-0192.jpk-force"), o);
  expect_error_mentions(r, "declares", "over the limit");
  EXPECT_EQ(r.status().code(), StatusCode::kResourceExhausted);
}

TEST_F(AfmBadInput, TextRenamedToJpk) {
  const std::string p = write("fake.jpk-force", "not a zip at all\n");
  expect_error_mentions(read_force_curve(p), p, "zip");
}

TEST(AfmColumnText, ReadsUnitsFromTheHeader) {
  namespace fs = std::filesystem;
  const fs::path p = fs::temp_directory_path() / ("afm-cols-" + std::to_string(::getpid()) + ".tsv");
  std::ofstream(p) << "time_s\theight_um\tforce_n\tsegment\n"
                      "0\t0.0\t1e-10\tapproach\n0.1\t0.5\t2e-10\tapproach\n0.2\t0.4\t1.5e-10\tretract\n";
  auto c = read_force_curve(p.string());
  fs::remove(p);
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_EQ(c->segments.size(), 2u);
  EXPECT_DOUBLE_EQ(c->segments[0].height_m[1], 0.5e-6);
  EXPECT_DOUBLE_EQ(c->segments[0].force_n[1], 2e-10);
  EXPECT_EQ(c->segments[1].kind, SegmentKind::kRetract);
}

// The curves cellflow-run and validation/fe write: a dimensionless
// deformation (ignored: it needs R) beside the displacement in metres.
TEST(AfmColumnText, ReadsCurvesOfCellflowRunAndTheFeReferences) {
  namespace fs = std::filesystem;
  const fs::path p = fs::temp_directory_path() / ("afm-fe-" + std::to_string(::getpid()) + ".csv");
  std::ofstream(p) << "deformation,displacement_m,force_n\n0.01,1.72e-07,1e-11\n0.02,3.44e-07,3e-11\n";
  auto c = read_force_curve(p.string());
  fs::remove(p);
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_EQ(c->segments.size(), 1u);
  ASSERT_EQ(c->segments[0].force_n.size(), 2u);
  EXPECT_DOUBLE_EQ(c->segments[0].force_n[1], 3e-11);
  EXPECT_EQ(c->metadata.height_channel, "indentation");
}

}  // namespace
}  // namespace cellflow::afm
