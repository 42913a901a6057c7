// Checkpoint and restart of the suspension scene (suspension_checkpoint.h):
// three coarse cells, two of which the shear drives into contact, run N
// steps; a run resumed from the checkpoint written after k steps continues
// bit for bit as the uninterrupted one (every sample with its per-cell
// values and averages, every position frame), with lambda = 1 and with
// lambda = 0.05 (the marking re-made at the resume); a truncated, corrupted,
// foreign or mismatched checkpoint is refused naming the reason, and the run
// then starts from step 0 and matches a fresh run.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "physics/scenes/suspension/suspension.h"

namespace cellflow::scenes {
namespace {

namespace fs = std::filesystem;

constexpr std::uint64_t kSpecHash = 0x5eed5eedULL;

// Three cells of 200 vertices at 3 lattice nodes per radius in the default
// 5 x 8 x 4 R box (15 x 24 x 12 nodes), Re_p raised to 0.2. Cells 0 and 1 sit
// at H/2 -+ 0.45 R, the upper one 2.2 R behind: the shear brings them into
// contact range at about strain 0.5; cell 2 stays clear above.
SuspensionParams tiny_suspension(double lambda) {
  SuspensionParams p;
  const double r = 6e-6;
  SuspendedCellKind kind;
  kind.cell.radius_m = r;
  kind.cell.material.youngs_modulus_pa = 10.0;
  kind.cell.material.poisson_ratio = 0.48;
  kind.cell.target_vertex_count = 200;
  kind.viscosity_ratio = lambda;
  kind.placements = {{{3.0 * r, 3.55 * r, 2.0 * r}, {}},
                     {{0.8 * r, 4.45 * r, 2.0 * r}, {0.3, -0.2, 0.5}},
                     {{3.0 * r, 5.6 * r, 0.0}, {0.1, 0.4, 0.0}}};
  p.kinds.push_back(kind);
  p.capillary_number = 0.1;
  ShearFlowNumerics& f = p.numerics.flow;
  f.cells_per_radius = 3.0;
  f.target_reynolds_number = 0.2;
  f.max_strain = 1.0;
  f.sample_every_strain = 0.1;
  f.snapshot_every_strain = 0.25;
  f.threads = 1;
  p.numerics.average_after_strain = 0.3;
  // With a contrast: not a divisor of the sample interval, so the
  // checkpoints wait for sample steps that are marking steps.
  p.numerics.marking_every_steps = lambda == 1.0 ? 1 : 2;
  return p;
}

struct Outcome {
  SuspensionResult result;
  std::vector<std::vector<double>> frames;  // every on_positions, in order
  std::vector<int> frame_cells;             // the cell of each
  std::vector<int> samples_seen;            // indices of every on_sample, in order
  std::vector<ShearFlowCheckpointWritten> written;
};

// Runs `params`; writes one checkpoint at the `checkpoint_at`-th poll
// (checkpoint steps; 0: none) to `write_path`, resumes from `resume_path` if given.
Outcome run(const SuspensionParams& params, int checkpoint_at, const std::string& write_path,
            const std::string& resume_path = "", std::uint64_t spec_hash = kSpecHash) {
  Outcome out;
  StatusOr<PlannedSuspension> planned = plan_suspension_run(params);
  if (!planned.ok()) {
    out.result.status = planned.status();
    return out;
  }
  SuspensionCallbacks cb;
  cb.on_positions = [&](int, double, int cell, std::span<const double> x) {
    out.frames.emplace_back(x.begin(), x.end());
    out.frame_cells.push_back(cell);
  };
  cb.on_sample = [&](const SuspensionSample& s) { out.samples_seen.push_back(s.index); };
  cb.checkpointing.spec_hash = spec_hash;
  cb.checkpointing.resume_path = resume_path;
  if (checkpoint_at > 0) {
    int polls = 0;
    cb.checkpointing.write_path = write_path;
    cb.checkpointing.due = [polls, checkpoint_at]() mutable { return ++polls == checkpoint_at; };
    cb.checkpointing.on_written = [&](const ShearFlowCheckpointWritten& w) { out.written.push_back(w); };
  }
  out.result = run_suspension(*planned, cb);
  return out;
}

void expect_same_samples(const SuspensionResult& a, const SuspensionResult& b) {
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    const SuspensionSample& x = a.samples[i];
    const SuspensionSample& y = b.samples[i];
    // Bit-identical: equality of doubles, not a tolerance.
    EXPECT_EQ(x.index, y.index) << i;
    EXPECT_EQ(x.time_step, y.time_step) << i;
    EXPECT_EQ(x.mean_taylor_deformation, y.mean_taylor_deformation) << i;
    EXPECT_EQ(x.mean_inclination_deg, y.mean_inclination_deg) << i;
    EXPECT_EQ(x.relative_viscosity, y.relative_viscosity) << i;
    EXPECT_EQ(x.contact_pairs, y.contact_pairs) << i;
    EXPECT_EQ(x.average_taylor_deformation, y.average_taylor_deformation) << i;
    EXPECT_EQ(x.average_taylor_deformation_error, y.average_taylor_deformation_error) << i;
    EXPECT_EQ(x.average_relative_viscosity, y.average_relative_viscosity) << i;
    EXPECT_EQ(x.average_relative_viscosity_error, y.average_relative_viscosity_error) << i;
    ASSERT_EQ(x.cells.size(), y.cells.size()) << i;
    for (std::size_t c = 0; c < x.cells.size(); ++c) {
      EXPECT_EQ(x.cells[c].taylor_deformation, y.cells[c].taylor_deformation) << i << " cell " << c;
      EXPECT_EQ(x.cells[c].inclination_deg, y.cells[c].inclination_deg) << i << " cell " << c;
      EXPECT_EQ(x.cells[c].net_strain, y.cells[c].net_strain) << i << " cell " << c;
      EXPECT_EQ(x.cells[c].semi_axes_m, y.cells[c].semi_axes_m) << i << " cell " << c;
      EXPECT_EQ(x.cells[c].centroid_m, y.cells[c].centroid_m) << i << " cell " << c;
      EXPECT_EQ(x.cells[c].volume_m3, y.cells[c].volume_m3) << i << " cell " << c;
    }
  }
  EXPECT_EQ(a.average_taylor_deformation, b.average_taylor_deformation);
  EXPECT_EQ(a.average_relative_viscosity, b.average_relative_viscosity);
  EXPECT_EQ(a.max_contact_pairs, b.max_contact_pairs);
  EXPECT_EQ(a.time_steps, b.time_steps);
  EXPECT_EQ(a.stop, b.stop);
}

class SuspensionCheckpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("cellflow-susp-ckpt-test-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    path_ = (dir_ / "run.ckpt").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // N steps against k steps + checkpoint + resume + N - k steps.
  void expect_resume_is_bit_identical(double lambda, std::initializer_list<int> checkpoint_polls) {
    const SuspensionParams p = tiny_suspension(lambda);
    const Outcome fresh = run(p, 0, "");
    ASSERT_TRUE(fresh.result.status.ok()) << fresh.result.status.to_string();
    ASSERT_EQ(fresh.result.samples.size(), 11u);
    // The contact forces and their list take part: cells 0 and 1 come within range.
    ASSERT_GT(fresh.result.max_contact_pairs, 0);
    bool resumed_in_contact = false;
    if (lambda != 1.0) ASSERT_GT(fresh.result.marking_updates, 0);
    for (const int at : checkpoint_polls) {
      SCOPED_TRACE("lambda " + std::to_string(lambda) + ", checkpoint at poll " + std::to_string(at));
      const Outcome writer = run(p, at, path_);
      ASSERT_TRUE(writer.result.status.ok()) << writer.result.status.to_string();
      ASSERT_EQ(writer.written.size(), 1u);
      const ShearFlowCheckpointWritten& w = writer.written[0];
      ASSERT_TRUE(w.status.ok()) << w.status.to_string();
      EXPECT_GT(w.time_step, 0);
      EXPECT_LT(w.time_step, fresh.result.time_steps);
      if (lambda != 1.0) EXPECT_EQ(w.time_step % p.numerics.marking_every_steps, 0);
      EXPECT_EQ(fs::file_size(path_), w.bytes);
      const SuspensionSample& at_checkpoint =
          fresh.result.samples[static_cast<std::size_t>(w.last_sample_index)];
      resumed_in_contact = resumed_in_contact || at_checkpoint.contact_pairs > 0;
      std::printf(
          "lambda %g: checkpoint after step %lld (strain %.2f, %d contact pairs): %llu bytes, %.4f s\n",
          lambda, static_cast<long long>(w.time_step), at_checkpoint.strain_units,
          at_checkpoint.contact_pairs, static_cast<unsigned long long>(w.bytes), w.seconds);
      EXPECT_FALSE(fs::exists(path_ + ".tmp"));
      expect_same_samples(fresh.result, writer.result);  // writing changes nothing

      const Outcome resumed = run(p, 0, "", path_);
      ASSERT_TRUE(resumed.result.status.ok()) << resumed.result.status.to_string();
      EXPECT_TRUE(resumed.result.resume_refused.empty()) << resumed.result.resume_refused;
      EXPECT_EQ(resumed.result.resumed_from_step, w.time_step);
      EXPECT_EQ(resumed.result.samples[static_cast<std::size_t>(w.last_sample_index)].time_step, w.time_step);
      expect_same_samples(fresh.result, resumed.result);
      // The resumed run stepped only the rest.
      EXPECT_LT(resumed.result.contact_list_builds, fresh.result.contact_list_builds + 1);
      // Its recorder saw every sample once and every frame of every cell.
      std::vector<int> all(fresh.result.samples.size());
      for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
      EXPECT_EQ(resumed.samples_seen, all);
      ASSERT_FALSE(fresh.frames.empty());
      ASSERT_EQ(resumed.frames.size(), fresh.frames.size());
      EXPECT_EQ(resumed.frame_cells, fresh.frame_cells);
      for (std::size_t f = 0; f < fresh.frames.size(); ++f)
        EXPECT_EQ(resumed.frames[f], fresh.frames[f]) << f;
    }
  }

  fs::path dir_;
  std::string path_;
};

TEST_F(SuspensionCheckpoint, ResumedRunIsBitIdenticalToTheUninterruptedRun) {
  // After strain 0.3 (before the contact) and 0.6 (in contact range).
  expect_resume_is_bit_identical(1.0, {3, 6});
}

// Viscosity contrast: the marking is not in the checkpoint; the resume
// re-marks the restored positions exactly at a marking step.
TEST_F(SuspensionCheckpoint, ResumedRunWithViscosityContrastIsBitIdentical) {
  expect_resume_is_bit_identical(0.05, {4});
}

// A stop that keeps the work (a worker handing its job back) goes on to the
// next checkpoint step (with a contrast: a sample step that is a marking
// step), checkpoints there and stops; the resumed run is bit-identical. A
// cancel (checkpoint_before_stop false) stops at once.
TEST_F(SuspensionCheckpoint, StopThatKeepsTheWorkCheckpointsAtTheNextCheckpointStep) {
  const SuspensionParams p = tiny_suspension(0.05);
  const Outcome fresh = run(p, 0, "");
  ASSERT_TRUE(fresh.result.status.ok()) << fresh.result.status.to_string();
  const std::int64_t every = fresh.result.samples[1].time_step;
  // Odd: sample 3 is no marking step (marking every 2 steps), sample 4 is.
  ASSERT_EQ(every % 2, 1);
  ASSERT_EQ(p.numerics.marking_every_steps, 2);
  for (const bool keep : {true, false}) {
    SCOPED_TRACE(keep ? "keep the work" : "cancel");
    StatusOr<PlannedSuspension> planned = plan_suspension_run(p);
    ASSERT_TRUE(planned.ok());
    int samples = 0;
    std::vector<ShearFlowCheckpointWritten> written;
    SuspensionCallbacks cb;
    cb.on_sample = [&](const SuspensionSample&) { ++samples; };
    cb.should_stop = [&] { return samples >= 4; };  // from the poll after sample 3 on
    cb.checkpointing.spec_hash = kSpecHash;
    cb.checkpointing.write_path = path_;
    cb.checkpointing.due = [] { return false; };  // no periodic checkpoints
    cb.checkpointing.checkpoint_before_stop = [keep] { return keep; };
    cb.checkpointing.on_written = [&](const ShearFlowCheckpointWritten& w) { written.push_back(w); };
    const SuspensionResult stopped = run_suspension(*planned, cb);
    EXPECT_EQ(stopped.stop, ShearFlowStop::kCancelled);
    if (!keep) {
      EXPECT_EQ(stopped.time_steps, 3 * every);
      EXPECT_TRUE(written.empty());
      continue;
    }
    EXPECT_EQ(stopped.time_steps, 4 * every);
    ASSERT_EQ(written.size(), 1u);
    ASSERT_TRUE(written[0].status.ok()) << written[0].status.to_string();
    EXPECT_EQ(written[0].time_step, 4 * every);
    const Outcome resumed = run(p, 0, "", path_);
    EXPECT_EQ(resumed.result.resumed_from_step, 4 * every);
    expect_same_samples(fresh.result, resumed.result);
  }
}

// Writes a checkpoint of tiny_suspension(1) after its 4th checkpoint poll into `path`.
void make_checkpoint(const std::string& path) {
  const Outcome writer = run(tiny_suspension(1.0), 4, path);
  ASSERT_EQ(writer.written.size(), 1u);
  ASSERT_TRUE(writer.written[0].status.ok()) << writer.written[0].status.to_string();
}

// A refused checkpoint: the reason names `why`, and the run from step 0 equals a fresh one.
// (The fresh run of tiny_suspension(1) is made once.)
void expect_refused_and_fresh(const SuspensionParams& p, const std::string& path, const std::string& why,
                              std::uint64_t spec_hash = kSpecHash, bool default_params = false) {
  static const Outcome default_fresh = run(tiny_suspension(1.0), 0, "");
  const Outcome fresh = default_params ? default_fresh : run(p, 0, "");
  ASSERT_TRUE(fresh.result.status.ok()) << fresh.result.status.to_string();
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

TEST_F(SuspensionCheckpoint, TruncatedAndCorruptedCheckpointsAreRefused) {
  make_checkpoint(path_);
  const std::string good = (dir_ / "good.ckpt").string();
  fs::copy_file(path_, good);
  const SuspensionParams p = tiny_suspension(1.0);
  flip_byte(path_, fs::file_size(path_) / 2);  // inside the populations
  expect_refused_and_fresh(p, path_, "payload checksum mismatch", kSpecHash, true);
  fs::copy_file(good, path_, fs::copy_options::overwrite_existing);
  flip_byte(path_, 8 * 300);  // a vertex position of cell 0
  expect_refused_and_fresh(p, path_, "payload checksum mismatch", kSpecHash, true);
  fs::copy_file(good, path_, fs::copy_options::overwrite_existing);
  flip_byte(path_, 8 * 11);  // the time step word
  expect_refused_and_fresh(p, path_, "header checksum mismatch", kSpecHash, true);
  fs::copy_file(good, path_, fs::copy_options::overwrite_existing);
  fs::resize_file(path_, fs::file_size(path_) - 100);
  expect_refused_and_fresh(p, path_, "truncated or padded", kSpecHash, true);
  fs::resize_file(path_, 100);
  expect_refused_and_fresh(p, path_, "shorter than its header", kSpecHash, true);
  {
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out << std::string(4096, 'x');
  }
  expect_refused_and_fresh(p, path_, "not a suspension checkpoint", kSpecHash, true);
  expect_refused_and_fresh(p, (dir_ / "missing.ckpt").string(), "cannot open", kSpecHash, true);
}

TEST_F(SuspensionCheckpoint, CheckpointOfAnotherSpecIsRefused) {
  make_checkpoint(path_);
  expect_refused_and_fresh(tiny_suspension(1.0), path_, "another job spec", kSpecHash + 1, true);
  // The same spec hash with other dimensions (a caller that hashed badly) still fails on them.
  SuspensionParams wider = tiny_suspension(1.0);
  wider.numerics.flow.box_x_radii = 6.0;
  expect_refused_and_fresh(wider, path_, "lattice nx 15 in the file, 18 in this run");
  SuspensionParams two = tiny_suspension(1.0);
  two.kinds[0].placements.pop_back();
  expect_refused_and_fresh(two, path_, "cell count 3 in the file, 2 in this run");
  SuspensionParams finer = tiny_suspension(1.0);
  finer.kinds[0].cell.target_vertex_count = 300;
  expect_refused_and_fresh(finer, path_, "vertex count");
  SuspensionParams markers = tiny_suspension(1.0);
  markers.numerics.flow.hydrodynamic_radius_offset = 0.1;  // the same meshes, other marker scales
  expect_refused_and_fresh(markers, path_, "cells hash");
  SuspensionParams contrast = tiny_suspension(0.05);
  contrast.numerics.marking_every_steps = 1;
  expect_refused_and_fresh(contrast, path_, "marking (1 viscosity contrast) 0 in the file, 1 in this run");
  SuspensionParams doubles = tiny_suspension(1.0);
  doubles.numerics.flow.single_precision = !doubles.numerics.flow.single_precision;
  expect_refused_and_fresh(doubles, path_, "precision");
  // The elastic forces' precision too (every cell takes the scene's).
  SuspensionParams double_forces = tiny_suspension(1.0);
  double_forces.numerics.flow.elastic_single_precision =
      !double_forces.numerics.flow.elastic_single_precision;
  expect_refused_and_fresh(double_forces, path_, "float elastic forces");
}

}  // namespace
}  // namespace cellflow::scenes
