// Runs one job spec in this process: converts it with spec::to_params, runs
// its scene with callbacks that report every sample as it is computed, and
// writes the HDF5 result (physics/io, H5MD layout). No gRPC here: the worker
// passes callbacks that forward to the server; tests and benchmarks call it
// directly.
//
// Adding a scene (shear flow) is one more case in run_job(): convert its spec,
// call the scene with callbacks that emit DeformationSamples and write
// frames and time series through the same H5mdWriter.
#pragma once

#include <functional>
#include <string>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"
#include "physics/scenes/quasi_static.h"

namespace cellflow::worker {

// What a running job reports. All optional.
struct JobEvents {
  std::function<void(const v1::ForceSample&)> force_sample;
  std::function<void(const v1::DeformationSample&)> deformation_sample;
  std::function<void(double fraction_done, const std::string& stage)> progress;
  std::function<bool()> should_stop;  // true: stop at the next check, outcome kCancelled
};

struct RunOptions {
  std::string result_path;           // the HDF5 file to write (the caller picks a temporary name)
  int position_frames = 10;          // frames between the reference and the final state, at most
  int threads = 0;                   // OpenMP threads for the physics; 0: the spec's / default
  int debug_delay_per_point_ms = 0;  // testing aid: a cancellable pause after each load point
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

// The observables a quasi-static result holds, in the column order of
// `cellflow result --csv` (after "point"); semi_axes_m is 3 wide.
inline constexpr const char* kCurveObservables[] = {
    "deformation",   "displacement_m", "force_n",          "hertz_force_n",     "taylor_deformation",
    "semi_axes_m",   "volume_m3",      "elastic_energy_j", "max_penetration_m", "newton_iterations",
    "cg_iterations", "step_splits",    "residual"};

}  // namespace cellflow::worker
