// One shear-flow run from key=value arguments, printing the samples: the
// driver of the resolution and stability studies in this folder.
//   shear_flow_run ca=0.2 cpr=6 vertices=1000 box=10,15,5 re=0.1 tau=1
//                  float=1 kernel=peskin4 max_strain=40 tol=2e-3 window=2
//                  sample=0.1 nu=0.48 threads=0 every=1 ratio=2 offset=0.5
//                  checkpoint=PATH checkpoint_every_s=300 resume=PATH rho=1000 resolve=1
//                  lambda=1 marking_every=0 boundaries=walls|lees_edwards
// resolve=0 turns numerics.resolve_thickness off (the lattice of cpr, a
// warning only); rho sets the fluid density (kg/m^3; the Reynolds number at
// large Ca, where the physical one exceeds re).
// checkpoint=PATH writes a checkpoint at the first sample after each
// checkpoint_every_s of wall time (0: at every sample) and prints its cost
// against the time step; resume=PATH resumes from one.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>

#include "bench/shear_flow/key_value_args.h"
#include "physics/core/passive_threads.h"
#include "physics/scenes/shear_flow/shear_flow.h"

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  using namespace cellflow;
  std::optional<std::map<std::string, std::string>> parsed = bench::parse_key_value_args(argc, argv);
  if (!parsed) return 2;
  std::map<std::string, std::string>& args = *parsed;
  auto get = [&](const char* key, double fallback) { return bench::number_arg(args, key, fallback); };
  scenes::ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = get("E", 10.0);
  p.cell.material.poisson_ratio = get("nu", 0.48);
  p.cell.target_vertex_count = static_cast<int>(get("vertices", scenes::kFlowDefaultVertexCount));
  p.capillary_number = get("ca", 0.2);
  p.viscosity_ratio = get("lambda", 1.0);
  p.fluid_density_kg_m3 = get("rho", p.fluid_density_kg_m3);
  scenes::ShearFlowNumerics& n = p.numerics;
  n.cells_per_radius = get("cpr", n.cells_per_radius);
  if (args.count("box")) {
    std::sscanf(args["box"].c_str(), "%lf,%lf,%lf", &n.box_x_radii, &n.box_y_radii, &n.box_z_radii);
  }
  n.target_reynolds_number = get("re", n.target_reynolds_number);
  if (args.count("nodal"))
    n.volumetric =
        get("nodal", 0.0) != 0.0 ? elastic::VolumetricTerm::kNodalAverage : elastic::VolumetricTerm::kPerTet;
  n.relaxation_time = get("tau", n.relaxation_time);
  n.single_precision = get("float", n.single_precision ? 1 : 0) != 0;
  n.elastic_single_precision = get("elastic_float", n.elastic_single_precision ? 1 : 0) != 0;
  if (args.count("kernel")) {
    StatusOr<ibm::Kernel> k = ibm::parse_kernel(args["kernel"]);
    if (!k.ok()) {
      std::fprintf(stderr, "%s\n", k.status().message().c_str());
      return 2;
    }
    n.ibm_kernel = *k;
  }
  if (args.count("boundaries")) {
    StatusOr<scenes::ShearFlowBoundaries> b = scenes::parse_boundaries(args["boundaries"], "boundaries");
    if (!b.ok()) {
      std::fprintf(stderr, "%s\n", b.status().message().c_str());
      return 2;
    }
    n.boundaries = *b;
  }
  n.max_strain = get("max_strain", n.max_strain);
  n.steady_tolerance = get("tol", n.steady_tolerance);
  n.steady_window_strain = get("window", n.steady_window_strain);
  n.sample_every_strain = get("sample", n.sample_every_strain);
  n.max_stiffness_ratio = get("ratio", n.max_stiffness_ratio);
  n.hydrodynamic_radius_offset = get("offset", n.hydrodynamic_radius_offset);
  n.threads = static_cast<int>(get("threads", 0));
  n.marking_every_steps = static_cast<int>(get("marking_every", 0));
  n.resolve_thickness = get("resolve", n.resolve_thickness ? 1 : 0) != 0;
  const int every = static_cast<int>(get("every", 10));
  scenes::ShearFlowCallbacks cb;
  cb.on_sample = [&](const scenes::ShearFlowSample& s) {
    if (s.index % every != 0) return;
    std::printf(
        "%5d strain %7.3f D %.5f incl %6.2f net_strain %.4f a1 %.3g m tank_treading %.4g /s V %.6g m3 "
        "D_full %.10g incl_full %.10g\n",
        s.index, s.strain_units, s.taylor_deformation, s.inclination_deg, s.net_strain, s.semi_axes_m[0],
        s.tank_treading_frequency_per_s, s.volume_m3, s.taylor_deformation, s.inclination_deg);
    std::fflush(stdout);
  };
  cb.on_restart = [](const scenes::ShearFlowRestart& r) {
    std::printf(
        "restart: thickness %.3f kernel widths at strain %.2f on %.4g cells per radius: now %.4g (%dx%dx%d), "
        "%.1f s abandoned\n",
        r.thickness_over_kernel, r.strain_units, r.old_cells_per_radius, r.new_cells_per_radius, r.setup.nx,
        r.setup.ny, r.setup.nz, r.abandoned_wall_time_s);
    std::fflush(stdout);
  };
  int checkpoints = 0;
  double checkpoint_s = 0.0, checkpoint_max_s = 0.0;
  std::uint64_t checkpoint_bytes = 0;
  if (args.count("checkpoint")) {
    using Clock = std::chrono::steady_clock;
    const double every_s = get("checkpoint_every_s", 300.0);
    cb.checkpointing.write_path = args["checkpoint"];
    cb.checkpointing.due = [every_s, last = Clock::now()]() mutable {
      if (std::chrono::duration<double>(Clock::now() - last).count() < every_s) return false;
      last = Clock::now();
      return true;
    };
    cb.checkpointing.on_written = [&](const scenes::ShearFlowCheckpointWritten& w) {
      if (!w.status.ok()) {
        std::printf("checkpoint failed: %s\n", w.status.to_string().c_str());
        return;
      }
      ++checkpoints;
      checkpoint_s += w.seconds;
      checkpoint_max_s = std::max(checkpoint_max_s, w.seconds);
      checkpoint_bytes = w.bytes;
    };
  }
  if (args.count("resume")) cb.checkpointing.resume_path = args["resume"];
  const scenes::ShearFlowResult r = scenes::run_shear_flow(p, cb);
  const scenes::ShearFlowSetup& s = r.setup;
  std::printf("status %s\nstop %s\n", r.status.to_string().c_str(),
              std::string(scenes::stop_name(r.stop)).c_str());
  std::printf(
      "Ca %.4g gammadot %.4g /s Re %.3g (physical %.3g) lattice %dx%dx%d Mach %.3g steps/strain %.1f\n",
      s.capillary_number, s.shear_rate_per_s, s.reynolds_number_simulated, s.reynolds_number_physical, s.nx,
      s.ny, s.nz, s.mach_number, s.steps_per_strain);
  std::printf(
      "stiffness_ratio %.4g mesh_h/dx %.3f D_ref %.5f steps %lld wall %.1f s (elastic %.1f coupling %.1f "
      "lattice %.1f obs %.1f)\n",
      r.stiffness_ratio, r.mesh_spacing_over_dx, r.reference_taylor_deformation,
      static_cast<long long>(r.time_steps), r.wall_time_s, r.elastic_s, r.coupling_s, r.lattice_s,
      r.observables_s);
  std::printf(
      "steady D %.5f incl %.3f net_strain %.4f tank/gammadot %.4f rel_change %.2e (Roscoe small-Ca D %.5f "
      "incl %.3f)\n",
      r.steady_taylor_deformation, r.steady_inclination_deg, r.steady_net_strain,
      r.tank_treading_frequency_per_s / s.shear_rate_per_s, r.steady_relative_change,
      scenes::small_ca_taylor_deformation(s.capillary_number),
      scenes::small_ca_inclination_deg_lambda1(s.capillary_number));
  std::printf("thickness / kernel %.2f\n", r.thickness_over_kernel);
  std::printf(
      "lambda %.4g tau_in %.4g marking: %lld updates (%lld exact) %.2f s = %.3f ms/step, %lld nodes inside\n",
      s.viscosity_ratio, s.inner_relaxation_time, static_cast<long long>(r.marking_updates),
      static_cast<long long>(r.marking_full), r.marking_s,
      1e3 * r.marking_s / static_cast<double>(std::max<std::int64_t>(r.time_steps, 1)),
      static_cast<long long>(r.marked_nodes));
  std::printf(
      "cells_per_radius %.4g predicted thickness / kernel %.2f thickness / kernel %.2f (min %.2f) restarts "
      "%zu\n",
      s.cells_per_radius, s.predicted_thickness_over_kernel, r.thickness_over_kernel,
      r.min_thickness_over_kernel, r.restarts.size());
  if (r.resumed_from_step >= 0)
    std::printf("resumed after step %lld\n", static_cast<long long>(r.resumed_from_step));
  if (!r.resume_refused.empty()) std::printf("resume refused: %s\n", r.resume_refused.c_str());
  if (checkpoints > 0) {
    const double step_s = r.wall_time_s / static_cast<double>(std::max<std::int64_t>(r.time_steps, 1));
    std::printf(
        "checkpoints %d of %.1f MB: mean %.3f s (max %.3f s) each = %.1f time steps of %.2f ms; "
        "%.2f %% of the run's wall time\n",
        checkpoints, static_cast<double>(checkpoint_bytes) / 1e6, checkpoint_s / checkpoints,
        checkpoint_max_s, checkpoint_s / checkpoints / step_s, 1e3 * step_s,
        100.0 * checkpoint_s / r.wall_time_s);
  }
  for (const std::string& w : r.warnings) std::printf("warning: %s\n", w.c_str());
  return r.status.ok() ? 0 : 1;
}
