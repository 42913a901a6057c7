// Checkpoint and restart of the shear-flow scene (shear_flow_checkpoint.h):
// a run resumed from the checkpoint written after sample k continues bit for
// bit as the run that wrote it (every sample, the final positions); a
// corrupted, truncated, foreign or mismatched checkpoint is refused naming
// the reason, and the run then starts from step 0 and matches a fresh run.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::scenes {
namespace {

namespace fs = std::filesystem;

// A tiny run: 3 lattice nodes per radius in a 4 R box (12^3 nodes), 200
// vertices, Re_p raised to 0.5: 11 steps per sample, 109 steps to strain 1.
ShearFlowParams tiny_params() {
  ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = 200;
  p.capillary_number = 0.1;
  p.numerics.cells_per_radius = 3.0;
  p.numerics.box_x_radii = 4.0;
  p.numerics.box_y_radii = 4.0;
  p.numerics.box_z_radii = 4.0;
  p.numerics.target_reynolds_number = 0.5;
  p.numerics.max_strain = 1.0;
  p.numerics.sample_every_strain = 0.1;
  p.numerics.snapshot_every_strain = 0.25;
  p.numerics.steady_tolerance = 0.0;
  p.numerics.threads = 1;
  return p;
}

constexpr std::uint64_t kSpecHash = 0x1234abcdULL;

struct Outcome {
  ShearFlowResult result;
  std::vector<std::vector<double>> frames;  // every on_positions, in order
  std::vector<int> samples_seen;            // indices of every on_sample, in order
  std::vector<ShearFlowCheckpointWritten> written;
};

// Runs `params`; writes one checkpoint at the `checkpoint_at`-th sample step
// (1-based; 0: none) to `write_path`, resumes from `resume_path` if given.
Outcome run(const ShearFlowParams& params, int checkpoint_at, const std::string& write_path,
            const std::string& resume_path = "", std::uint64_t spec_hash = kSpecHash) {
  Outcome out;
  ShearFlowCallbacks cb;
  cb.on_positions = [&](int, double, std::span<const double> x) {
    out.frames.emplace_back(x.begin(), x.end());
  };
  cb.on_sample = [&](const ShearFlowSample& s) { out.samples_seen.push_back(s.index); };
  cb.checkpointing.spec_hash = spec_hash;
  cb.checkpointing.resume_path = resume_path;
  if (checkpoint_at > 0) {
    int polls = 0;
    cb.checkpointing.write_path = write_path;
    cb.checkpointing.due = [polls, checkpoint_at]() mutable { return ++polls == checkpoint_at; };
    cb.checkpointing.on_written = [&](const ShearFlowCheckpointWritten& w) { out.written.push_back(w); };
  }
  out.result = run_shear_flow(params, cb);
  return out;
}

void expect_same_samples(const ShearFlowResult& a, const ShearFlowResult& b) {
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    const ShearFlowSample& x = a.samples[i];
    const ShearFlowSample& y = b.samples[i];
    // Bit-identical: equality of doubles, not a tolerance.
    EXPECT_EQ(x.time_step, y.time_step) << i;
    EXPECT_EQ(x.taylor_deformation, y.taylor_deformation) << i;
    EXPECT_EQ(x.inclination_deg, y.inclination_deg) << i;
    EXPECT_EQ(x.net_strain, y.net_strain) << i;
    EXPECT_EQ(x.centroid_m, y.centroid_m) << i;
    EXPECT_EQ(x.elastic_energy_j, y.elastic_energy_j) << i;
    EXPECT_EQ(x.tank_treading_frequency_per_s, y.tank_treading_frequency_per_s) << i;
  }
  EXPECT_EQ(a.steady_taylor_deformation, b.steady_taylor_deformation);
  EXPECT_EQ(a.time_steps, b.time_steps);
}

class ShearFlowCheckpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("cellflow-ckpt-test-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    path_ = (dir_ / "run.ckpt").string();
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  std::string path_;
};

TEST_F(ShearFlowCheckpoint, ResumedRunIsBitIdenticalToTheUninterruptedRun) {
  const ShearFlowParams p = tiny_params();
  const Outcome fresh = run(p, 0, "");
  ASSERT_TRUE(fresh.result.status.ok()) << fresh.result.status.to_string();
  ASSERT_EQ(fresh.result.samples.size(), 11u);

  // The writer: a checkpoint after the 5th or 6th sample step (strain 0.5 or 0.6;
  // 11 steps per sample: one odd and one even AA phase).
  for (const int at : {5, 6}) {
    SCOPED_TRACE("checkpoint after sample step " + std::to_string(at));
    const Outcome writer = run(p, at, path_);
    ASSERT_TRUE(writer.result.status.ok()) << writer.result.status.to_string();
    ASSERT_EQ(writer.written.size(), 1u);
    ASSERT_TRUE(writer.written[0].status.ok()) << writer.written[0].status.to_string();
    EXPECT_EQ(writer.written[0].last_sample_index, at);
    EXPECT_EQ(writer.written[0].time_step % 2, at % 2);
    EXPECT_GT(writer.written[0].bytes, 0u);
    EXPECT_EQ(fs::file_size(path_), writer.written[0].bytes);
    EXPECT_FALSE(fs::exists(path_ + ".tmp"));
    expect_same_samples(fresh.result, writer.result);  // writing changes nothing

    const Outcome resumed = run(p, 0, "", path_);
    ASSERT_TRUE(resumed.result.status.ok()) << resumed.result.status.to_string();
    EXPECT_TRUE(resumed.result.resume_refused.empty()) << resumed.result.resume_refused;
    EXPECT_EQ(resumed.result.resumed_from_step, writer.written[0].time_step);
    expect_same_samples(fresh.result, resumed.result);
    // The recorder of the resumed run saw every sample once and every frame.
    std::vector<int> all(fresh.result.samples.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    EXPECT_EQ(resumed.samples_seen, all);
    ASSERT_EQ(resumed.frames.size(), fresh.frames.size());
    for (std::size_t f = 0; f < fresh.frames.size(); ++f) EXPECT_EQ(resumed.frames[f], fresh.frames[f]) << f;
    ASSERT_FALSE(fresh.frames.empty());
  }
}

// Viscosity contrast: the marking is not in the checkpoint; the resumed run
// re-marks the restored positions exactly at the checkpoint's step (a
// marking step) and continues bit for bit.
TEST_F(ShearFlowCheckpoint, ResumedRunWithViscosityContrastIsBitIdentical) {
  ShearFlowParams p = tiny_params();
  p.viscosity_ratio = 0.05;
  const Outcome fresh = run(p, 0, "");
  ASSERT_TRUE(fresh.result.status.ok()) << fresh.result.status.to_string();
  ASSERT_GT(fresh.result.marking_updates, 0);
  const Outcome writer = run(p, 5, path_);
  ASSERT_EQ(writer.written.size(), 1u);
  ASSERT_TRUE(writer.written[0].status.ok()) << writer.written[0].status.to_string();
  const Outcome resumed = run(p, 0, "", path_);
  ASSERT_TRUE(resumed.result.status.ok()) << resumed.result.status.to_string();
  EXPECT_TRUE(resumed.result.resume_refused.empty()) << resumed.result.resume_refused;
  EXPECT_EQ(resumed.result.resumed_from_step, writer.written[0].time_step);
  expect_same_samples(fresh.result, resumed.result);
  EXPECT_EQ(resumed.result.marking_updates, fresh.result.marking_updates);
  EXPECT_EQ(resumed.result.marked_nodes, fresh.result.marked_nodes);
  ASSERT_EQ(resumed.frames.size(), fresh.frames.size());
  EXPECT_EQ(resumed.frames.back(), fresh.frames.back());
}

// A stop that keeps the work (a worker handing its job back) goes on to the
// next sample step, checkpoints there and stops; the resumed run is again
// bit-identical. A cancel (checkpoint_before_stop false) stops at once.
TEST_F(ShearFlowCheckpoint, StopThatKeepsTheWorkCheckpointsAtTheNextSampleStep) {
  ShearFlowParams p = tiny_params();
  p.numerics.max_strain = 3.0;  // past step 256, where a stop is polled between samples
  const Outcome fresh = run(p, 0, "");
  ASSERT_TRUE(fresh.result.status.ok());
  const std::int64_t every = fresh.result.samples[1].time_step;
  ASSERT_NE(256 % every, 0) << "the 256-step poll must fall between samples";
  const std::int64_t next_sample_step = (256 / every + 1) * every;

  for (const bool keep : {true, false}) {
    SCOPED_TRACE(keep ? "keep the work" : "cancel");
    int polls_since_armed = -1;  // armed by the last sample before step 256
    std::vector<ShearFlowCheckpointWritten> written;
    ShearFlowCallbacks cb;
    cb.on_sample = [&](const ShearFlowSample& s) {
      if (s.time_step + every > 256 && polls_since_armed < 0) polls_since_armed = 0;
    };
    // Asked to stop from the poll at step 256 on: the poll at that last
    // sample step itself still says go on.
    cb.should_stop = [&] { return polls_since_armed >= 0 && polls_since_armed++ > 0; };
    cb.checkpointing.spec_hash = kSpecHash;
    cb.checkpointing.write_path = path_;
    cb.checkpointing.due = [] { return false; };  // no periodic checkpoints
    cb.checkpointing.checkpoint_before_stop = [keep] { return keep; };
    cb.checkpointing.on_written = [&](const ShearFlowCheckpointWritten& w) { written.push_back(w); };
    const ShearFlowResult stopped = run_shear_flow(p, cb);
    EXPECT_EQ(stopped.stop, ShearFlowStop::kCancelled);
    if (!keep) {
      EXPECT_EQ(stopped.time_steps, 256);
      EXPECT_TRUE(written.empty());
      continue;
    }
    EXPECT_EQ(stopped.time_steps, next_sample_step);
    ASSERT_EQ(written.size(), 1u);
    ASSERT_TRUE(written[0].status.ok());
    EXPECT_EQ(written[0].time_step, next_sample_step);
    const Outcome resumed = run(p, 0, "", path_);
    EXPECT_EQ(resumed.result.resumed_from_step, next_sample_step);
    expect_same_samples(fresh.result, resumed.result);
  }
}

// Writes a checkpoint of tiny_params after its 4th sample step into `path`.
void make_checkpoint(const std::string& path) {
  const Outcome writer = run(tiny_params(), 4, path);
  ASSERT_EQ(writer.written.size(), 1u);
  ASSERT_TRUE(writer.written[0].status.ok());
}

// A refused checkpoint: the reason names `why`, and the run from step 0 equals a fresh one.
void expect_refused_and_fresh(const ShearFlowParams& p, const std::string& path, const std::string& why,
                              std::uint64_t spec_hash = kSpecHash) {
  const Outcome fresh = run(p, 0, "");
  const Outcome resumed = run(p, 0, "", path, spec_hash);
  ASSERT_TRUE(resumed.result.status.ok()) << resumed.result.status.to_string();
  EXPECT_EQ(resumed.result.resumed_from_step, -1);
  EXPECT_NE(resumed.result.resume_refused.find(why), std::string::npos)
      << "expected \"" << why << "\" in: " << resumed.result.resume_refused;
  bool warned = false;
  for (const std::string& w : resumed.result.warnings)
    warned = warned || w.find("started from step 0") != std::string::npos;
  EXPECT_TRUE(warned) << "no warning says the run started from step 0";
  expect_same_samples(fresh.result, resumed.result);
}

void flip_byte(const std::string& path, std::uint64_t offset) {
  std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
  f.seekg(static_cast<std::streamoff>(offset));
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ 0x10);
  f.seekp(static_cast<std::streamoff>(offset));
  f.write(&c, 1);
}

TEST_F(ShearFlowCheckpoint, CorruptedPayloadIsRefused) {
  make_checkpoint(path_);
  flip_byte(path_, fs::file_size(path_) / 2);  // inside the populations
  expect_refused_and_fresh(tiny_params(), path_, "payload checksum mismatch");
}

TEST_F(ShearFlowCheckpoint, CorruptedHeaderIsRefused) {
  make_checkpoint(path_);
  flip_byte(path_, 8 * 11);  // the time step word
  expect_refused_and_fresh(tiny_params(), path_, "header checksum mismatch");
}

TEST_F(ShearFlowCheckpoint, TruncatedFileIsRefused) {
  make_checkpoint(path_);
  fs::resize_file(path_, fs::file_size(path_) - 100);
  expect_refused_and_fresh(tiny_params(), path_, "truncated");
  fs::resize_file(path_, 100);
  expect_refused_and_fresh(tiny_params(), path_, "shorter than its header");
}

TEST_F(ShearFlowCheckpoint, CheckpointOfAnotherSpecIsRefused) {
  make_checkpoint(path_);
  expect_refused_and_fresh(tiny_params(), path_, "another job spec", kSpecHash + 1);
  // The same spec hash with other dimensions (a caller that hashed badly) still fails on them.
  ShearFlowParams wider = tiny_params();
  wider.numerics.box_x_radii = 5.0;
  expect_refused_and_fresh(wider, path_, "lattice nx 12 in the file, 15 in this run");
  ShearFlowParams finer = tiny_params();
  finer.cell.target_vertex_count = 300;
  expect_refused_and_fresh(finer, path_, "vertex count");
  ShearFlowParams doubles = tiny_params();
  doubles.numerics.single_precision = false;
  expect_refused_and_fresh(doubles, path_, "precision");
  // The elastic forces' precision too: the same spec run with double forces
  // would not continue the float-force trajectory.
  ShearFlowParams double_forces = tiny_params();
  double_forces.numerics.elastic_single_precision = !tiny_params().numerics.elastic_single_precision;
  expect_refused_and_fresh(double_forces, path_, "float elastic forces");
}

TEST_F(ShearFlowCheckpoint, GarbageAndMissingFilesAreRefused) {
  {
    std::ofstream out(path_, std::ios::binary);
    const std::string junk(4096, 'x');
    out << junk;
  }
  expect_refused_and_fresh(tiny_params(), path_, "not a shear-flow checkpoint");
  expect_refused_and_fresh(tiny_params(), (dir_ / "missing.ckpt").string(), "cannot open");
}

}  // namespace
}  // namespace cellflow::scenes
