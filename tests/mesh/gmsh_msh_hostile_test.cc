// Hostile input to the Gmsh reader (issue 13: no spec that reads, hangs or
// crashes anything): special files, pseudo-files, files that are not meshes,
// absurd declared counts, truncation and a seeded fuzz loop. Every case must
// end quickly in ok or an error Status, never block, crash or allocate for
// what the file only claims, and no message may repeat the file's content.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <future>
#include <iterator>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "physics/mesh/sphere_mesh.h"

extern char** environ;

namespace cellflow::mesh {
namespace {

std::string temp_path(const std::string& name) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return ::testing::TempDir() + "cellflow_hostile_" + info->name() + "_" + name;
}

std::string write_bytes(const std::string& name, const std::string& bytes) {
  const std::string path = temp_path(name);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  return path;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

const std::string kHeader = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";

// One tet (nodes 1..4, positive in Gmsh's convention) in a complete file.
std::string one_tet_file() {
  return kHeader +
         "$PhysicalNames\n1\n3 1 \"cytoplasm\"\n$EndPhysicalNames\n"
         "$Entities\n0 0 0 1\n1 0 0 0 1 1 1 1 1 0\n$EndEntities\n"
         "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n"
         "$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n";
}

// A small sphere mesh as written by write_gmsh_msh: the base of the fuzz loop.
std::string sphere_file_bytes() {
  SphereMeshOptions options;
  options.radius_m = 5e-6;
  options.target_vertex_count = 200;
  options.nucleus_radius_m = 2.5e-6;
  const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
  EXPECT_TRUE(mesh.ok()) << mesh.status().to_string();
  const std::string path = ::testing::TempDir() + "cellflow_hostile_sphere_base.msh";
  EXPECT_TRUE(write_gmsh_msh(*mesh, path).ok());
  std::string bytes = slurp(path);
  std::remove(path.c_str());
  return bytes;
}

// read_gmsh_msh on `path` with a deadline: fails the test (instead of hanging
// it) if the call has not returned within 5 s; a blocked FIFO open is then
// released by opening the FIFO for writing.
StatusOr<TetMesh> read_with_deadline(const std::string& path) {
  auto future = std::async(std::launch::async, [path] { return read_gmsh_msh(path); });
  if (future.wait_for(std::chrono::seconds(5)) != std::future_status::ready) {
    ADD_FAILURE() << "read_gmsh_msh(" << path << ") did not return within 5 s";
    const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd >= 0) ::close(fd);
  }
  return future.get();
}

void expect_refused(const StatusOr<TetMesh>& mesh, const std::string& path, const std::string& kind) {
  ASSERT_FALSE(mesh.ok()) << path;
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find(path), std::string::npos) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find(kind), std::string::npos) << mesh.status().message();
}

TEST(GmshMshHostileTest, CharacterDevicesAreRefusedWithoutReading) {
  for (const std::string path : {"/dev/zero", "/dev/urandom", "/dev/null"}) {
    const auto start = std::chrono::steady_clock::now();
    expect_refused(read_with_deadline(path), path, "character device");
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1)) << path;
  }
}

TEST(GmshMshHostileTest, DirectoryIsRefused) {
  std::string dir = ::testing::TempDir();
  if (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  expect_refused(read_with_deadline(dir), dir, "directory");
  expect_refused(read_with_deadline("/"), "/", "directory");
}

TEST(GmshMshHostileTest, FifoIsRefusedWithoutBlocking) {
  const std::string path = temp_path("fifo.msh");
  std::remove(path.c_str());
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0) << std::strerror(errno);
  const auto start = std::chrono::steady_clock::now();
  expect_refused(read_with_deadline(path), path, "FIFO");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  // Through a symbolic link: the target is what counts.
  const std::string link = temp_path("fifo_link.msh");
  std::remove(link.c_str());
  ASSERT_EQ(::symlink(path.c_str(), link.c_str()), 0);
  expect_refused(read_with_deadline(link), link, "FIFO");
  std::remove(link.c_str());
  std::remove(path.c_str());
}

TEST(GmshMshHostileTest, SymlinkToDeviceIsRefused) {
  const std::string link = temp_path("zero_link.msh");
  std::remove(link.c_str());
  ASSERT_EQ(::symlink("/dev/zero", link.c_str()), 0);
  expect_refused(read_with_deadline(link), link, "character device");
  std::remove(link.c_str());
}

TEST(GmshMshHostileTest, ProcEnvironIsRefusedAndNeverEchoed) {
  ::setenv("CELLFLOW_HOSTILE_TEST_SECRET", "s3cr3t-value-that-must-not-leak", 1);
  const std::string path = "/proc/self/environ";
  const StatusOr<TetMesh> mesh = read_with_deadline(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find(path), std::string::npos) << mesh.status().message();
  // The same bytes handed over in memory (an upload): refused by the parser.
  const std::string bytes = slurp(path);
  ASSERT_FALSE(bytes.empty());
  const StatusOr<TetMesh> from_bytes = read_gmsh_msh_from_bytes(bytes, "upload.msh");
  ASSERT_FALSE(from_bytes.ok());
  EXPECT_EQ(from_bytes.status().code(), StatusCode::kInvalidArgument);
  for (const Status* status : {&mesh.status(), &from_bytes.status()}) {
    const std::string& message = status->message();
    const char* path_value = std::getenv("PATH");
    if (path_value != nullptr && std::strlen(path_value) > 0) {
      EXPECT_EQ(message.find(path_value), std::string::npos) << message;
    }
    EXPECT_EQ(message.find("s3cr3t"), std::string::npos) << message;
    EXPECT_EQ(message.find("CELLFLOW_HOSTILE"), std::string::npos) << message;
    for (char** env = environ; *env != nullptr; ++env) {
      const char* eq = std::strchr(*env, '=');
      if (eq == nullptr || std::strlen(eq + 1) < 8) continue;
      EXPECT_EQ(message.find(eq + 1), std::string::npos) << "leaks " << *env << ": " << message;
    }
  }
}

TEST(GmshMshHostileTest, RegularNonMeshFileIsRefusedWithoutEchoingIt) {
  const std::string path = "/etc/passwd";
  const std::string bytes = slurp(path);
  if (bytes.empty()) GTEST_SKIP() << "no /etc/passwd";
  const std::string first_line = bytes.substr(0, bytes.find('\n'));
  const std::string first_field = first_line.substr(0, first_line.find(':') + 1);
  const StatusOr<TetMesh> mesh = read_with_deadline(path);
  const StatusOr<TetMesh> from_bytes = read_gmsh_msh_from_bytes(bytes, "upload.msh");
  for (const StatusOr<TetMesh>* result : {&mesh, &from_bytes}) {
    ASSERT_FALSE(result->ok());
    EXPECT_EQ(result->status().code(), StatusCode::kInvalidArgument);
    const std::string& message = result->status().message();
    EXPECT_NE(message.find(":1:"), std::string::npos) << message;
    EXPECT_EQ(message.find(first_line), std::string::npos) << message;
    EXPECT_EQ(message.find(first_field), std::string::npos) << message;
  }
}

TEST(GmshMshHostileTest, BadPathsAreErrors) {
  EXPECT_FALSE(read_gmsh_msh("").ok());
  EXPECT_FALSE(read_gmsh_msh(std::string("/etc/passwd\0.msh", 16)).ok());
  const StatusOr<TetMesh> missing = read_gmsh_msh(temp_path("missing/dir/file.msh"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
}

// 122 bytes that claim 1e11 nodes: refused from the header, before any
// allocation, naming the count; also with the node limit lifted (then the
// bytes left cannot hold them).
TEST(GmshMshHostileTest, HugeDeclaredNodeCountIsRefusedBeforeAllocation) {
  std::string text =
      kHeader + "$Nodes\n1 100000000000 1 100000000000\n3 1 0 100000000000\n1\n0 0 0\n$EndNodes\n";
  text += std::string(122 - text.size() - 1, ' ') + "\n";
  ASSERT_EQ(text.size(), 122u);
  const std::string path = write_bytes("huge_nodes.msh", text);
  const StatusOr<TetMesh> mesh = read_with_deadline(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kResourceExhausted) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find(path + ":5:"), std::string::npos) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find("100000000000"), std::string::npos) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find("2000000"), std::string::npos) << mesh.status().message();

  MeshReadLimits unlimited;
  unlimited.max_nodes = LLONG_MAX;
  unlimited.max_elements = LLONG_MAX;
  const StatusOr<TetMesh> lifted = read_gmsh_msh(path, 1.0, unlimited);
  ASSERT_FALSE(lifted.ok());
  EXPECT_EQ(lifted.status().code(), StatusCode::kInvalidArgument) << lifted.status().message();
  EXPECT_NE(lifted.status().message().find("100000000000"), std::string::npos) << lifted.status().message();
  EXPECT_NE(lifted.status().message().find("bytes follow"), std::string::npos) << lifted.status().message();
  std::remove(path.c_str());
}

TEST(GmshMshHostileTest, EveryHugeDeclaredCountIsRefused) {
  MeshReadLimits unlimited;
  unlimited.max_nodes = LLONG_MAX;
  unlimited.max_elements = LLONG_MAX;
  const std::string big = "9223372036854775807";
  const std::string tail =
      "$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n"
      "$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n";
  const std::vector<std::string> cases = {
      kHeader + "$PhysicalNames\n" + big + "\n3 1 \"a\"\n$EndPhysicalNames\n" + tail,
      kHeader + "$Entities\n" + big + " 0 0 0\n$EndEntities\n" + tail,
      kHeader + "$Entities\n0 0 0 " + big + "\n$EndEntities\n" + tail,
      kHeader + "$Entities\n0 0 0 1\n1 0 0 0 1 1 1 " + big + " 1 0\n$EndEntities\n" + tail,
      kHeader + "$Entities\n0 0 0 1\n1 0 0 0 1 1 1 1e300 1 0\n$EndEntities\n" + tail,
      kHeader + "$Entities\n0 0 0 1\n1e300 0 0 0 1 1 1 1 nan 0\n$EndEntities\n" + tail,
      kHeader + "$Nodes\n" + big + " 4 1 4\n3 1 0 4\n$EndNodes\n",
      kHeader + "$Nodes\n1 " + big + " 1 4\n3 1 0 4\n$EndNodes\n",
      kHeader + "$Nodes\n1 4 1 4\n3 1 0 " + big + "\n1\n$EndNodes\n",
      kHeader + "$Nodes\n1 4 1 4\n3 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n$EndNodes\n",
      kHeader + "$Nodes\n2 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 1 0 4\n$EndNodes\n",
      kHeader + "$Nodes\n1 -4 1 4\n$EndNodes\n",
      kHeader + "$Nodes\n1 4 1 4\n3 1 0 -1\n$EndNodes\n",
      kHeader + tail.substr(0, tail.find("$Elements")) + "$Elements\n" + big + " 1 1 1\n$EndElements\n",
      kHeader + tail.substr(0, tail.find("$Elements")) + "$Elements\n1 " + big + " 1 1\n$EndElements\n",
      kHeader + tail.substr(0, tail.find("$Elements")) + "$Elements\n1 1 1 1\n3 1 4 " + big +
          "\n1 1 2 3 4\n$EndElements\n",
      kHeader + tail.substr(0, tail.find("$Elements")) +
          "$Elements\n1 1 1 1\n3 1 4 2\n1 1 2 3 4\n2 1 2 3 4\n" + "$EndElements\n",
      kHeader + tail.substr(0, tail.find("$Elements")) + "$Elements\n1 1 1 1\n3 99999999999 4 1\n" +
          "1 1 2 3 4\n$EndElements\n",
      kHeader + tail + tail,  // a second $Nodes section
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    for (const MeshReadLimits& limits : {MeshReadLimits{}, unlimited}) {
      const StatusOr<TetMesh> mesh = read_gmsh_msh_from_bytes(cases[i], "case.msh", 1.0, limits);
      ASSERT_FALSE(mesh.ok()) << "case " << i;
      EXPECT_NE(mesh.status().message().find("case.msh:"), std::string::npos) << mesh.status().message();
    }
  }
}

TEST(GmshMshHostileTest, LimitsAreEnforced) {
  const std::string text = one_tet_file();
  ASSERT_TRUE(read_gmsh_msh_from_bytes(text).ok()) << read_gmsh_msh_from_bytes(text).status().to_string();
  MeshReadLimits limits;
  limits.max_nodes = 3;
  StatusOr<TetMesh> mesh = read_gmsh_msh_from_bytes(text, "n.msh", 1.0, limits);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(mesh.status().message().find("declares 4 nodes"), std::string::npos) << mesh.status().message();
  limits = {};
  limits.max_elements = 0;
  mesh = read_gmsh_msh_from_bytes(text, "e.msh", 1.0, limits);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kResourceExhausted);
  limits = {};
  limits.max_bytes = text.size() - 1;
  mesh = read_gmsh_msh_from_bytes(text, "b.msh", 1.0, limits);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kResourceExhausted);
  const std::string path = write_bytes("limit.msh", text);
  mesh = read_gmsh_msh(path, 1.0, limits);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(mesh.status().message().find(path), std::string::npos) << mesh.status().message();
  limits.max_bytes = text.size();
  EXPECT_TRUE(read_gmsh_msh(path, 1.0, limits).ok());
  std::remove(path.c_str());
}

// A sparse file over the default 64 MiB: refused from its size, not read.
TEST(GmshMshHostileTest, OversizedFileIsRefusedFromItsSize) {
  const std::string path = temp_path("sparse.msh");
  { std::ofstream(path, std::ios::binary | std::ios::trunc) << one_tet_file(); }
  ASSERT_EQ(::truncate(path.c_str(), (off_t{64} << 20) + 1), 0) << std::strerror(errno);
  const auto start = std::chrono::steady_clock::now();
  const StatusOr<TetMesh> mesh = read_with_deadline(path);
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), StatusCode::kResourceExhausted) << mesh.status().message();
  EXPECT_NE(mesh.status().message().find("67108865"), std::string::npos) << mesh.status().message();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  std::remove(path.c_str());
}

TEST(GmshMshHostileTest, HugeCoordinatesAreErrorsNotInfinities) {
  std::string text = one_tet_file();
  text.replace(text.find("0 0 1\n$EndNodes"), 5, "0 0 1e300");
  StatusOr<TetMesh> mesh = read_gmsh_msh_from_bytes(text, "big.msh", 1e10);
  ASSERT_FALSE(mesh.ok());
  text = one_tet_file();
  for (const char* from : {"1 0 0\n", "0 1 0\n"}) text.replace(text.find(from), 5, "1e200 1e200 1e200");
  mesh = read_gmsh_msh_from_bytes(text, "big.msh");
  EXPECT_FALSE(mesh.ok() && !std::isfinite(mesh->positions_m[3]));
  for (const char* coordinate : {"nan", "inf", "-inf"}) {
    std::string t = one_tet_file();
    t.replace(t.find("0 0 1\n$EndNodes"), 1, coordinate);
    EXPECT_FALSE(read_gmsh_msh_from_bytes(t, "nan.msh").ok()) << coordinate;
  }
}

TEST(GmshMshHostileTest, FileAndBytesReadTheSameMesh) {
  const std::string bytes = sphere_file_bytes();
  const std::string path = write_bytes("sphere.msh", bytes);
  const StatusOr<TetMesh> a = read_gmsh_msh(path);
  const StatusOr<TetMesh> b = read_gmsh_msh_from_bytes(bytes, path);
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  ASSERT_TRUE(b.ok()) << b.status().to_string();
  EXPECT_EQ(a->positions_m, b->positions_m);
  EXPECT_EQ(a->tets, b->tets);
  EXPECT_EQ(a->tet_region, b->tet_region);
  std::remove(path.c_str());
}

// Every prefix of a valid file that cuts into $EndElements or earlier is an
// error naming the file; the file variant too for a sample of cut points.
TEST(GmshMshHostileTest, TruncatedFilesAreErrors) {
  const std::string bytes = sphere_file_bytes();
  ASSERT_GT(bytes.size(), 1000u);
  for (std::size_t cut = 0; cut + 1 < bytes.size(); cut += (cut < 400 ? 1 : 97)) {
    const StatusOr<TetMesh> mesh =
        read_gmsh_msh_from_bytes(std::string_view(bytes).substr(0, cut), "cut.msh");
    ASSERT_FALSE(mesh.ok()) << "cut at " << cut;
    EXPECT_NE(mesh.status().message().find("cut.msh"), std::string::npos) << mesh.status().message();
  }
  for (std::size_t cut : {std::size_t{0}, std::size_t{5}, bytes.size() / 2, bytes.size() - 2}) {
    const std::string path = write_bytes("cut.msh", bytes.substr(0, cut));
    const StatusOr<TetMesh> mesh = read_gmsh_msh(path);
    ASSERT_FALSE(mesh.ok()) << "cut at " << cut;
    EXPECT_NE(mesh.status().message().find(path), std::string::npos) << mesh.status().message();
    std::remove(path.c_str());
  }
  EXPECT_TRUE(read_gmsh_msh_from_bytes(std::string_view(bytes).substr(0, bytes.size() - 1), "x").ok());
}

// Seeded fuzz (20000 cases): random bytes and mutations of two valid files (a one-tet file
// with physical names and entities, and a small sphere). Each must return ok
// or an error that names the source; never crash, hang or allocate without
// bound.
TEST(GmshMshHostileTest, FuzzedBytesNeverCrash) {
  std::mt19937_64 rng(20261201);
  const std::vector<std::string> bases = {one_tet_file(), sphere_file_bytes()};
  const std::vector<std::string> tokens = {"0",
                                           "-1",
                                           "1",
                                           "4",
                                           "99999999999",
                                           "9223372036854775807",
                                           "-9223372036854775808",
                                           "1e308",
                                           "nan",
                                           "inf",
                                           "-0",
                                           "$Nodes",
                                           "$Elements",
                                           "$EndNodes",
                                           "\n",
                                           " ",
                                           "\"",
                                           "\r\n",
                                           std::string(1, '\0')};
  auto uniform = [&](std::size_t n) { return static_cast<std::size_t>(rng() % (n == 0 ? 1 : n)); };
  const auto start = std::chrono::steady_clock::now();
  int ok_count = 0;
  int error_count = 0;
  for (int iteration = 0; iteration < 20000; ++iteration) {
    std::string bytes;
    if (iteration % 10 == 0) {
      bytes.resize(uniform(600));
      for (char& c : bytes) c = static_cast<char>(rng());
      if (iteration % 20 == 0) bytes = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n" + bytes;
    } else {
      bytes = bases[iteration % 4 == 1 ? 1 : 0];
      const int mutations = 1 + static_cast<int>(uniform(4));
      for (int m = 0; m < mutations; ++m) {
        const std::size_t at = uniform(bytes.size());
        switch (uniform(6)) {
          case 0:  // flip a byte
            bytes[at] = static_cast<char>(rng());
            break;
          case 1:  // a digit to another digit
            if (bytes[at] >= '0' && bytes[at] <= '9') bytes[at] = static_cast<char>('0' + uniform(10));
            break;
          case 2:  // delete a range
            bytes.erase(at, uniform(40));
            break;
          case 3:  // insert a token
            bytes.insert(at, tokens[uniform(tokens.size())]);
            break;
          case 4: {  // replace the number at `at` with a token
            std::size_t end = at;
            while (end < bytes.size() && bytes[end] != ' ' && bytes[end] != '\n') ++end;
            bytes.replace(at, end - at, tokens[uniform(tokens.size())]);
            break;
          }
          default: {  // duplicate a range
            const std::size_t length = uniform(200);
            bytes.insert(at, bytes.substr(uniform(bytes.size()), length));
            break;
          }
        }
      }
    }
    const StatusOr<TetMesh> mesh = read_gmsh_msh_from_bytes(bytes, "fuzz.msh");
    if (mesh.ok()) {
      ++ok_count;
      EXPECT_EQ(mesh->positions_m.size(), 3 * mesh->on_surface.size());
      for (std::int32_t v : mesh->tets) ASSERT_LT(static_cast<std::size_t>(v), mesh->num_vertices());
    } else {
      ++error_count;
      ASSERT_EQ(mesh.status().message().rfind("fuzz.msh", 0), 0u) << mesh.status().message();
    }
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("fuzz: %d ok, %d errors in %.2f s\n", ok_count, error_count, seconds);
  EXPECT_GT(error_count, 10000);
  EXPECT_LT(seconds, 5.0);
}

}  // namespace
}  // namespace cellflow::mesh
