// Internals of the shear-flow scene shared by its translation units
// (shear_flow_plan.cc, shear_flow_observables.cc, stiffness_check.cc,
// shear_flow.cc): the plan, the state of one run and the helpers each part
// calls. Not part of the public interface; include only from these files.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "physics/core/status.h"
#include "physics/coupling/immersed_cell.h"
#include "physics/elastic/elastic_body.h"
#include "physics/elastic/material.h"
#include "physics/lb/fluid.h"
#include "physics/marking/marking.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/scenes/shear_flow/flow_limits.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/units/units.h"

namespace cellflow::scenes::shear_flow_detail {

constexpr double kPi = 3.14159265358979323846;

// mu = mu1 + mu2 of the material.
double shear_modulus(const elastic::Material& material);

// Everything plan_shear_flow derives, with the conversion object.
struct Plan {
  ShearFlowSetup setup;
  units::Units units{1.0, 1.0, 1.0, 1.0};
};

// validate + units + Mach + memory checks (shear_flow_plan.cc).
StatusOr<Plan> make_plan(const ShearFlowParams& params, std::string_view field_prefix);

// S = k_max,lb / (6 pi eta_lb): sets result.stiffness_ratio; kInvalidArgument
// above the kernel's limit (stiffness_check.cc).
Status check_stiffness(const ShearFlowParams& params, const units::Units& u, const elastic::ElasticBody& body,
                       const std::vector<double>& positions_m, const std::string& prefix,
                       ShearFlowResult& result);

// t_wall = now - t0 in seconds.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// When the time loop samples, snapshots and stops (in lattice steps).
struct Schedule {
  std::int64_t sample_steps = 1;
  std::int64_t snapshot_steps = 0;  // 0: no snapshots
  std::int64_t max_steps = 0;
  ShearFlowStop limit_stop = ShearFlowStop::kMaxStrain;
};

// Cell positions of one snapshot as emitted (lattice units), kept for
// checkpoints so that a resumed run's recorder gets every frame.
struct StoredSnapshot {
  int index = 0;
  double time_s = 0.0;
  std::vector<double> x_lb;
};

// State of one run.
struct Run {
  const ShearFlowParams* params = nullptr;
  const ShearFlowCallbacks* callbacks = nullptr;
  Plan plan;
  mesh::TetMesh mesh;
  elastic::ElasticBody body;
  // The immersed cells: one, at the box centre (no cell-cell contact is built).
  coupling::ImmersedCells cells;
  std::vector<double> x_si;             // box coordinates in metres, at samples
  std::vector<double> last_good_x_lb;   // at the last sample
  std::vector<int> tank_vertices;       // surface vertices near z = 0
  std::vector<double> tank_angle;       // last angle of each, rad
  std::vector<double> tank_unwrapped;   // accumulated angle of each, rad
  std::vector<double> tank_mean_angle;  // per sample: mean accumulated angle
  double energy_limit_j = 0.0;
  double last_energy_j = 0.0;
  int snapshot_index = 0;
  bool keep_snapshots = false;            // checkpoints are written: keep every snapshot
  std::vector<StoredSnapshot> snapshots;  // when keep_snapshots
  // Viscosity contrast (viscosity_ratio != 1): the nodes inside the cell,
  // re-marked every marking_every steps (a divisor of the sample interval).
  std::optional<marking::NodeMarking> marking;
  std::int64_t marking_every = 0;
  // The thickness check (numerics.resolve_thickness): called with a sample
  // whose 2 a1 / (kernel width dx) is below kMinThicknessOverKernel; true
  // (a finer lattice was planned): this attempt ends for a restart there.
  std::function<bool(const ShearFlowSample&, double thickness_over_kernel)> refine;
  bool refine_requested = false;
};

// The marking interval of a run (numerics.marking_every_steps, or its
// automatic value) for the plan's wall speed and the sample interval.
std::int64_t marking_interval(const ShearFlowNumerics& n, double wall_speed_lattice,
                              std::int64_t sample_steps);

// Marks the cell's nodes exactly and writes the phases into the fluid (run
// start and resume); `updates_so_far` aligns the marking's update count.
Status start_marking(Run& run, lb::Fluid& fluid, std::int64_t updates_so_far, ShearFlowResult& result);

// The schedule of the run's numerics and plan (shear_flow.cc).
Schedule schedule_of(const Run& run);

// x_SI = X dx of the cell into run.x_si (shear_flow_observables.cc).
void to_si(Run& run);

// Observables at the current positions; appends the sample.
ShearFlowSample take_sample(Run& run, ShearFlowResult& result, std::int64_t step);

// Means over the last window of samples; the drift of D (steady_window_drift).
void summarise(const Run& run, ShearFlowResult& result);

// shear_flow_is_steady on the run's samples at the run's Ca.
bool is_steady(const Run& run, const ShearFlowResult& result);

}  // namespace cellflow::scenes::shear_flow_detail
