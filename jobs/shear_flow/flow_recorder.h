// What the result recorders of the two flow jobs (the single cell,
// jobs/shear_flow; the suspension, jobs/suspension) share: the fluid velocity
// frames, the progress stage ("strain x/max"), the stop poll, the H5MD step
// of a time, the flow box of the "cell" group, the stop and warnings of the
// summary, the sample count; and the flow-specific terms of their memory
// estimates. Each scene's recorder adds its mesh, positions and samples.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "jobs/common/result_file.h"
#include "jobs/scene.h"
#include "jobs/shear_flow/shear_flow_job.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::jobs {

class FlowRecorderBase : public ResultRecorder {
 public:
  int samples() const { return samples_; }

 protected:
  FlowRecorderBase(io::H5mdWriter* writer, const scenes::ShearFlowSetup& setup, double max_strain,
                   const JobEvents& events)
      : ResultRecorder(writer), setup_(setup), max_strain_(max_strain), events_(events) {}

  // The callbacks both scenes' callback structs have (ShearFlowCallbacks,
  // SuspensionCallbacks): fluid velocity frames, progress, the stop poll.
  template <class Callbacks>
  void add_flow_callbacks(Callbacks& cb) {
    cb.on_fluid_velocity = [this](const scenes::FluidVelocitySnapshot& snap) {
      keep(append_fluid_velocity(*writer_, snap, step_of(snap.time_s)));
      keep(writer_->flush());
    };
    cb.on_progress = [this](double fraction) {
      if (events_.progress) {
        char stage[64];
        std::snprintf(stage, sizeof stage, "strain %.2f/%.4g", last_strain_, max_strain_);
        events_.progress(fraction, stage);
      }
    };
    cb.should_stop = [this] { return events_.should_stop && events_.should_stop(); };
  }

  // The H5MD step of a time: the lattice time step.
  std::int64_t step_of(double time_s) const;
  // The flow box of the "cell" group: periodic in x (the flow direction) and
  // z, walls at y = 0 and y = H (paper section 7.1); edges n dx per axis
  // (setup.box_m). Flushed.
  void write_flow_box();
  // /summary/stop, and /summary/status when the run failed.
  void write_stop(scenes::ShearFlowStop stop, const Status& status);
  // /summary/warnings (one a line, when any); closes the file; the first error.
  Status close_with_warnings(const std::vector<std::string>& warnings);
  // After a sample was written: counts it, its strain is the progress stage's.
  void sample_written(double strain_units) {
    ++samples_;
    last_strain_ = strain_units;
  }

  scenes::ShearFlowSetup setup_;
  double max_strain_;
  const JobEvents& events_;
  double last_strain_ = 0.0;
  int samples_ = 0;
};

// Memory-estimate terms of a flow job: the largest transient per-node buffer
// in double (the velocity field update after the Couette start and the fluid
// velocity snapshots, 3 values each, one at a time), and the snapshot
// positions a checkpointed run keeps (3 doubles per vertex of every cell a
// frame, up to scenes::kMaxCheckpointSnapshotBytes).
double flow_transient_bytes(const scenes::ShearFlowSetup& setup);
double kept_snapshot_bytes(const scenes::ShearFlowNumerics& numerics, double vertices);

}  // namespace cellflow::jobs
