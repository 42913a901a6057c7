// Runs one job spec in this process: converts it with jobs::to_params, runs
// its scene with callbacks that report every sample as it is computed, and
// writes the HDF5 result (physics/io, H5MD layout). No gRPC here: the worker
// passes callbacks that forward to the server; tests and benchmarks call it
// directly.
//
// Quasi-static scenes emit ForceSamples and write the force curve; the
// shear-flow scene emits DeformationSamples and writes the deformation time
// series, the cell trajectory at snapshot intervals, optional fluid velocity
// snapshots (/fields/fluid_velocity), the resolved setup (/parameters/setup)
// and the steady values (/summary) through the same H5mdWriter.
#pragma once

#include <functional>
#include <string>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::worker {

// What a running job reports. All optional.
struct JobEvents {
  std::function<void(const v1::ForceSample&)> force_sample;
  std::function<void(const v1::DeformationSample&)> deformation_sample;
  std::function<void(double fraction_done, const std::string& stage)> progress;
  std::function<bool()> should_stop;  // true: stop at the next check, outcome kCancelled
};

struct RunOptions {
  std::string result_path;   // the HDF5 file to write (the caller picks a temporary name)
  int position_frames = 10;  // quasi-static: frames between the reference and the final state, at most
                             // (a flow job writes every snapshot of numerics.snapshot_every_strain)
  int threads = 0;           // OpenMP threads for the physics; 0: the spec's / default
  int debug_delay_per_point_ms = 0;  // testing aid: a cancellable pause after each load point (quasi-static)
  std::string program_version = "0.1.0";
};

struct RunOutcome {
  Status status;                // OK; kCancelled when should_stop said so; otherwise the failure
  bool result_written = false;  // the result file exists and holds what was computed
  int samples = 0;
};

RunOutcome run_job(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events);

// A curve point as the sample message of the API.
v1::ForceSample force_sample_from(const scenes::CurvePoint& point);
// A shear-flow sample as the sample message of the API (inclination in radians).
v1::DeformationSample deformation_sample_from(const scenes::ShearFlowSample& sample);

}  // namespace cellflow::worker
