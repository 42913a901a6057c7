// The shear-flow scene as a job (physics/scenes/shear_flow, paper section
// 7.1): the proto spec converted and validated once into its parameters and
// lattice plan, the result file (connectivity, positions at snapshots, the
// deformation time series, fluid velocity frames, the resolved setup and the
// steady values; layout in jobs/shear_flow/result_schema.json),
// DeformationSample messages and the D(t) CSV.
#pragma once

#include <memory>
#include <string>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "io/h5md.h"
#include "jobs/scene.h"
#include "physics/core/status.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::jobs {

// Registry entry (jobs/registry.cc).
StatusOr<std::unique_ptr<PreparedJob>> prepare_shear_flow(const v1::JobSpec& spec);

// /parameters/setup/*: the resolved flow setup (lattice, time step, Ca, Re,
// wall speed), which the suspension's result shares.
Status write_flow_setup(io::H5mdWriter& writer, const scenes::ShearFlowSetup& setup);

// One frame of /fields/fluid_velocity at lattice step `step` (node (i, j, k)
// at ((i + 1/2) dx, ...), as the cell positions).
Status append_fluid_velocity(io::H5mdWriter& writer, const scenes::FluidVelocitySnapshot& snapshot,
                             std::int64_t step);

// Checkpoint and restart of the flow jobs (the single cell and the
// suspension; their scenes take the same ShearFlowCheckpointing): the spec's
// hash as the checkpoint's identity, a checkpoint at the first checkpoint
// step after each options.checkpoint_interval_s of wall time to
// options.checkpoint_path, resume from options.resume_path, and the events'
// checkpoint_written / checkpoint_before_stop wired to it.
std::uint64_t checkpoint_spec_hash(const v1::JobSpec& spec);
void add_flow_checkpointing(scenes::ShearFlowCheckpointing& checkpointing, const v1::JobSpec& spec,
                            const RunOptions& options, const JobEvents& events);

// A shear-flow sample as the sample message of the API (inclination in radians).
v1::DeformationSample deformation_sample_from(const scenes::ShearFlowSample& sample);

// The shear-flow CSV (the columns of `cellflow result --csv` for a flow job):
// sample, time_s, strain (gammadot t), taylor_deformation, inclination_rad,
// net_strain, a1_m, a2_m, a3_m, tank_treading_frequency_per_s, volume_m3.
std::string deformation_csv_header();
std::string deformation_csv_row(const scenes::ShearFlowSample& sample);

}  // namespace cellflow::jobs
