// H5MD writer and XDMF sidecar: round trip, layout checked with h5dump,
// XDMF checked with xmllint, and a writer killed after a flush.
#include "io/h5md.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "io/xdmf.h"
#include "tests/io/h5_test_util.h"

namespace cellflow::io {
namespace {

namespace fs = std::filesystem;

using testing::count_existing_items;
using testing::read_valid_xml;
using testing::run_command;

class H5mdTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_io_test_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Two tetrahedra sharing a face; five vertices.
  static std::vector<double> reference() {
    return {0, 0, 0, 1e-6, 0, 0, 0, 1e-6, 0, 0, 0, 1e-6, 1e-6, 1e-6, 1e-6};
  }
  static std::vector<std::int32_t> tets() { return {0, 1, 2, 3, 1, 2, 3, 4}; }

  // Writes three frames and a curve of `points` records; returns the path.
  std::string write_example(int points) {
    const std::string path = (dir_ / "job.h5").string();
    H5mdCreator creator;
    creator.time_unit = "";  // dimensionless load parameter
    creator.time_meaning = "deformation";
    auto writer = H5mdWriter::create(path, creator);
    EXPECT_TRUE(writer.ok()) << writer.status().to_string();
    const std::vector<std::uint8_t> region = {0, 1};
    EXPECT_TRUE((*writer)->write_tetrahedra("cell", tets(), region).ok());
    EXPECT_TRUE((*writer)->write_parameters_json(R"({"compression":{"maxDeformation":0.2}})").ok());
    std::vector<double> x = reference();
    EXPECT_TRUE((*writer)->append_positions("cell", 0, 0.0, x).ok());
    for (int i = 0; i < points; ++i) {
      const double deformation = 0.01 * (i + 1);
      EXPECT_TRUE(
          (*writer)->append_observable("force_n", i + 1, deformation, 1e-9 * (i + 1) * (i + 1), "N").ok());
      EXPECT_TRUE((*writer)->append_observable("deformation", i + 1, deformation, deformation).ok());
      const std::vector<double> axes = {1e-6 - i * 1e-8, 1e-6, 1e-6 + i * 1e-8};
      EXPECT_TRUE((*writer)->append_observable("semi_axes_m", i + 1, deformation, axes, "m").ok());
      EXPECT_TRUE((*writer)->append_count("newton_iterations", i + 1, deformation, 3 + i).ok());
      if (i == points / 2 || i == points - 1) {
        for (double& v : x) v *= 1.0 + deformation;
        EXPECT_TRUE((*writer)->append_positions("cell", i + 1, deformation, x).ok());
      }
      EXPECT_TRUE((*writer)->flush().ok());
    }
    EXPECT_TRUE((*writer)->close().ok());
    return path;
  }

  fs::path dir_;
};

TEST_F(H5mdTest, RoundTripIsExact) {
  const std::string path = write_example(6);
  auto force = read_observable(path, "force_n");
  ASSERT_TRUE(force.ok()) << force.status().to_string();
  ASSERT_EQ(force->step.size(), 6u);
  EXPECT_EQ(force->width, 1);
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(force->step[i], i + 1);
    EXPECT_EQ(force->time[i], 0.01 * (i + 1));  // bit-exact: doubles stored as IEEE f64
    EXPECT_EQ(force->value[i], 1e-9 * (i + 1) * (i + 1));
  }
  auto axes = read_observable(path, "semi_axes_m");
  ASSERT_TRUE(axes.ok());
  EXPECT_EQ(axes->width, 3);
  EXPECT_EQ(axes->value[3 * 5 + 2], 1e-6 + 5 * 1e-8);
  auto names = list_observables(path);
  ASSERT_TRUE(names.ok());
  EXPECT_EQ(*names, (std::vector<std::string>{"deformation", "force_n", "newton_iterations", "semi_axes_m"}));
  auto newton = read_observable(path, "newton_iterations");  // int64 in the file, read as doubles
  ASSERT_TRUE(newton.ok()) << newton.status().to_string();
  EXPECT_EQ(newton->value, (std::vector<double>{3, 4, 5, 6, 7, 8}));
  auto json = read_parameters_json(path);
  ASSERT_TRUE(json.ok());
  EXPECT_EQ(*json, R"({"compression":{"maxDeformation":0.2}})");
  auto frames = count_position_frames(path, "cell");
  ASSERT_TRUE(frames.ok());
  EXPECT_EQ(*frames, 3);
  auto last = read_position_frame(path, "cell", 2);
  ASSERT_TRUE(last.ok());
  EXPECT_EQ(last->step, 6);
  ASSERT_EQ(last->positions_m.size(), 15u);
  EXPECT_DOUBLE_EQ(last->positions_m[3], 1e-6 * 1.04 * 1.06);  // scaled at points 3 and 6, rel. 4 ulp
}

TEST_F(H5mdTest, WidthMismatchIsRejected) {
  auto writer = H5mdWriter::create((dir_ / "w.h5").string());
  ASSERT_TRUE(writer.ok());
  const std::vector<double> two = {1.0, 2.0};
  ASSERT_TRUE((*writer)->append_observable("a", 0, 0.0, two).ok());
  EXPECT_EQ((*writer)->append_observable("a", 1, 1.0, 3.0).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ((*writer)->append_count("a", 1, 1.0, 3).code(), StatusCode::kInvalidArgument);  // not a count
  ASSERT_TRUE((*writer)->append_count("n", 0, 0.0, 3).ok());
  EXPECT_EQ((*writer)->append_observable("n", 1, 1.0, 3.0).code(), StatusCode::kInvalidArgument);
  H5mdBox box;
  box.has_edges = true;  // edges 0: refused
  EXPECT_EQ((*writer)->set_box("cell", box).code(), StatusCode::kInvalidArgument);
}

TEST_F(H5mdTest, H5dumpShowsTheH5mdLayout) {
  const std::string path = write_example(4);
  int code = 0;
  const std::string header = run_command(std::string(CELLFLOW_H5DUMP) + " -H " + path, &code);
  ASSERT_EQ(code, 0) << header;
  for (const char* needle :
       {"GROUP \"h5md\"", "GROUP \"author\"", "GROUP \"creator\"", "GROUP \"particles\"", "GROUP \"cell\"",
        "GROUP \"box\"", "GROUP \"position\"", "DATASET \"step\"", "DATASET \"time\"", "DATASET \"value\"",
        "GROUP \"observables\"", "GROUP \"force_n\"", "GROUP \"connectivity\"", "GROUP \"parameters\"",
        "DATASET \"job_spec_json\"", "GROUP \"modules\"", "GROUP \"units\""}) {
    EXPECT_NE(header.find(needle), std::string::npos) << "missing " << needle;
  }
  const std::string version = run_command(std::string(CELLFLOW_H5DUMP) + " -a /h5md/version " + path, &code);
  ASSERT_EQ(code, 0);
  EXPECT_NE(version.find("1, 1"), std::string::npos) << version;
  const std::string value =
      run_command(std::string(CELLFLOW_H5DUMP) + " -H -d /particles/cell/position/value " + path, &code);
  ASSERT_EQ(code, 0);
  EXPECT_NE(value.find("( 3, 5, 3 )"), std::string::npos) << value;
  EXPECT_EQ(header.find("GROUP \"xdmf\""), std::string::npos) << "positions are stored once";
  // Units in the H5MD syntax; the dimensionless load parameter has none.
  const std::string attributes = run_command(std::string(CELLFLOW_H5DUMP) + " -A " + path, &code);
  ASSERT_EQ(code, 0);
  EXPECT_NE(attributes.find("\"m\""), std::string::npos);
  EXPECT_NE(attributes.find("\"N\""), std::string::npos);
  EXPECT_NE(attributes.find("H5T_STD_REF_OBJECT"), std::string::npos)
      << "particles_group is an object reference";
  EXPECT_NE(attributes.find("\"none\", \"none\", \"none\""), std::string::npos);
  const std::string time =
      run_command(std::string(CELLFLOW_H5DUMP) + " -A -d /observables/force_n/time " + path, &code);
  EXPECT_EQ(time.find("ATTRIBUTE \"unit\""), std::string::npos) << time;
  EXPECT_NE(time.find("ATTRIBUTE \"meaning\""), std::string::npos) << time;
}

TEST_F(H5mdTest, XdmfIsValidXmlNamingExistingDatasets) {
  const std::string path = write_example(4);
  const std::string xdmf = (dir_ / "job.xdmf").string();
  ASSERT_TRUE(write_xdmf(path, xdmf).ok());
  const std::string xml = read_valid_xml(xdmf);
  // 3 frames x (topology, geometry hyperslab of the positions, region), the
  // file named with a directory part.
  EXPECT_EQ(count_existing_items(path, xml, std::regex(R"(>\./job\.h5:(/[^<]+)</DataItem>)")), 9);
  const std::regex grid(R"(<Grid Name="cell" GridType="Uniform")");
  EXPECT_EQ(std::distance(std::sregex_iterator(xml.begin(), xml.end(), grid), std::sregex_iterator()), 3);
  // Frame 2 is record 2 of the one position dataset.
  EXPECT_NE(xml.find("<DataItem Dimensions=\"3 3\" Format=\"XML\">2 0 0 1 1 1 1 5 3</DataItem>\n"
                     "              <DataItem Dimensions=\"3 5 3\" NumberType=\"Float\" Precision=\"8\" "
                     "Format=\"HDF\">./job.h5:/particles/cell/position/value</DataItem>"),
            std::string::npos)
      << xml;
  EXPECT_NE(xml.find("CollectionType=\"Temporal\""), std::string::npos);
  EXPECT_NE(xml.find("<Time Value=\"0.029999999999999999\"/>"), std::string::npos) << xml;  // point 3
}

// A vector field on a uniform grid (the fluid velocity of a flow job): the
// components land interleaved in [nz][ny][nx][3] frames, and the XDMF names
// every frame beside the cell frames.
TEST_F(H5mdTest, VectorFieldFramesAndXdmfBesideTheCell) {
  const std::string path = (dir_ / "flow.h5").string();
  UniformGrid grid;
  grid.nx = 4;
  grid.ny = 3;
  grid.nz = 2;
  grid.spacing_m = 1e-6;
  for (double& o : grid.origin_m) o = 0.5e-6;
  const std::size_t nodes = 24;
  {
    auto writer = H5mdWriter::create(path);
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->write_tetrahedra("cell", tets(), {}).ok());
    for (int frame = 0; frame < 2; ++frame) {
      std::vector<double> x(nodes), y(nodes), z(nodes);
      for (std::size_t n = 0; n < nodes; ++n) {
        x[n] = 1.0 * n + frame;  // exact in float32
        y[n] = -2.0 * n;
        z[n] = 0.5 * n;
      }
      ASSERT_TRUE((*writer)->append_positions("cell", 10 * frame, 0.1 * frame, reference()).ok());
      ASSERT_TRUE(
          (*writer)->append_vector_field("fluid_velocity", 10 * frame, 0.1 * frame, grid, x, y, z).ok());
    }
    UniformGrid other = grid;
    other.nx = 5;
    const std::vector<double> wrong(30, 0.0);
    EXPECT_EQ((*writer)->append_vector_field("fluid_velocity", 30, 0.3, other, wrong, wrong, wrong).code(),
              StatusCode::kInvalidArgument);
    ASSERT_TRUE((*writer)->write_scalar("/summary/steady_taylor_deformation", 0.25, "1").ok());
    ASSERT_TRUE((*writer)->write_string("/summary/stop", "steady").ok());
    ASSERT_TRUE((*writer)->close().ok());
  }
  auto frames = count_field_frames(path, "fluid_velocity");
  ASSERT_TRUE(frames.ok());
  EXPECT_EQ(*frames, 2);
  EXPECT_EQ(*count_field_frames(path, "absent"), 0);
  EXPECT_EQ(*read_scalar(path, "/summary/steady_taylor_deformation"), 0.25);
  EXPECT_EQ(*read_string(path, "/summary/stop"), "steady");

  // One time series [frames][nz][ny][nx][3]: node (i, j, k) = (1, 2, 1) is
  // element 1 + 4 (2 + 3 * 1) = 21 of frame 1.
  hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  hid_t dataset = H5Dopen2(file, "/fields/fluid_velocity/value", H5P_DEFAULT);
  ASSERT_GE(dataset, 0);
  hid_t space = H5Dget_space(dataset);
  ASSERT_EQ(H5Sget_simple_extent_ndims(space), 5);
  hsize_t dims[5];
  H5Sget_simple_extent_dims(space, dims, nullptr);
  H5Sclose(space);
  EXPECT_EQ(std::vector<hsize_t>(dims, dims + 5), (std::vector<hsize_t>{2, 2, 3, 4, 3}));
  std::vector<float> values(2 * nodes * 3);
  ASSERT_GE(H5Dread(dataset, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Dclose(dataset);
  H5Fclose(file);
  const std::size_t frame1 = nodes * 3;
  EXPECT_EQ(values[frame1 + 21 * 3 + 0], 22.0f);
  EXPECT_EQ(values[frame1 + 21 * 3 + 1], -42.0f);
  EXPECT_EQ(values[frame1 + 21 * 3 + 2], 10.5f);
  EXPECT_EQ(values[21 * 3 + 0], 21.0f);  // frame 0

  const std::string xdmf = (dir_ / "flow.xdmf").string();
  ASSERT_TRUE(write_xdmf(path, xdmf).ok());
  const std::string xml = read_valid_xml(xdmf);
  EXPECT_NE(xml.find("TopologyType=\"3DCoRectMesh\" Dimensions=\"2 3 4\""), std::string::npos) << xml;
  EXPECT_NE(xml.find(">1 0 0 0 0 1 1 1 1 1 1 2 3 4 3</DataItem>"), std::string::npos) << xml;
  EXPECT_NE(xml.find(">./flow.h5:/fields/fluid_velocity/value</DataItem>"), std::string::npos) << xml;
  EXPECT_NE(xml.find(">./flow.h5:/particles/cell/position/value</DataItem>"), std::string::npos) << xml;
  // Two times, each a spatial collection of the named blocks cell and fluid_velocity.
  const std::regex spatial_re(R"(CollectionType="Spatial")");
  EXPECT_EQ(std::distance(std::sregex_iterator(xml.begin(), xml.end(), spatial_re), std::sregex_iterator()),
            2);
  const std::regex cell_re(R"(<Grid Name="cell" GridType="Uniform")");
  EXPECT_EQ(std::distance(std::sregex_iterator(xml.begin(), xml.end(), cell_re), std::sregex_iterator()), 2);
  const std::regex fluid_re(R"(<Grid Name="fluid_velocity" GridType="Uniform")");
  EXPECT_EQ(std::distance(std::sregex_iterator(xml.begin(), xml.end(), fluid_re), std::sregex_iterator()), 2);
}

TEST_F(H5mdTest, KilledWriterLeavesReadableFile) {
  const std::string path = (dir_ / "killed.h5").string();
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto writer = H5mdWriter::create(path);
    if (!writer.ok()) _exit(10);
    const std::vector<std::int32_t> t = tets();
    if (!(*writer)->write_tetrahedra("cell", t, {}).ok()) _exit(11);
    const std::vector<double> x = reference();
    for (int i = 0; i < 5; ++i) {
      if (!(*writer)->append_observable("force_n", i, i, 0.5 * i).ok()) _exit(12);
      if (!(*writer)->append_positions("cell", i, i, x).ok()) _exit(13);
      if (!(*writer)->flush().ok()) _exit(14);
    }
    // Unflushed work, then death without closing.
    (void)(*writer)->append_observable("force_n", 5, 5, 2.5);
    raise(SIGKILL);
    _exit(15);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status)) << "child exited with " << WEXITSTATUS(status);
  auto force = read_observable(path, "force_n");
  ASSERT_TRUE(force.ok()) << force.status().to_string();
  ASSERT_GE(force->step.size(), 5u);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(force->value[i], 0.5 * i);
  auto frames = count_position_frames(path, "cell");
  ASSERT_TRUE(frames.ok());
  EXPECT_EQ(*frames, 5);
  int code = 0;
  run_command(std::string(CELLFLOW_H5DUMP) + " -H " + path, &code);
  EXPECT_EQ(code, 0);
}

}  // namespace
}  // namespace cellflow::io
