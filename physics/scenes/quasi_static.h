// Quasi-static contact scenes (paper section 4.2): compression between two
// rigid plates and colloidal-probe indentation. Each load point is solved to
// mechanical equilibrium; the curve is force against deformation with the
// Hertz prediction beside each point (shared/validation/README.md).
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "physics/core/status.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/scenes/cell_params.h"

namespace cellflow::scenes {

struct QuasiStaticOptions {
  double residual_tolerance = 1e-6;  // |residual| / force scale E R^2 at equilibrium
  int max_newton_iterations = 40;    // per load step, before the step is split
  int max_step_splits = 10;          // a load step may be halved this many times
  // Repulsive wall/probe force per vertex f = k (range - gap)^... ; unset = derived
  // from E, R and the mesh so that penetration stays below 0.5 % of R.
  std::optional<double> contact_stiffness_n_per_m;
  std::optional<double> contact_range_m;
  int threads = 0;  // OpenMP threads for the force kernel; 0 = default
};

struct CompressionParams {
  CellParams cell;
  double max_deformation = 0.5;  // compression / diameter, in (0, 0.9]
  int load_points = 40;          // points of the curve after first contact, >= 1
  QuasiStaticOptions numerics;
};

struct IndentationParams {
  CellParams cell;
  double probe_radius_m = 0.0;      // > 0
  double max_indentation_m = 0.0;   // total approach after first contact, in (0, 0.9 * 2 R)
  int load_points = 40;
  QuasiStaticOptions numerics;
};

Status validate(const CompressionParams& params, std::string_view field_prefix = "compression.");
Status validate(const IndentationParams& params, std::string_view field_prefix = "indentation.");

// One point of a force-deformation curve.
struct CurvePoint {
  int index = 0;                      // 0 .. load_points-1
  double deformation = 0.0;           // compression: delta / (2R); indentation: delta / (2R)
  double displacement_m = 0.0;        // plate or probe travel since first contact
  double force_n = 0.0;               // total reaction on the moving plate or probe
  double hertz_force_n = 0.0;         // Hertz prediction at the same displacement
  double taylor_deformation = 0.0;
  double semi_axes_m[3] = {0, 0, 0};
  double volume_m3 = 0.0;
  double elastic_energy_j = 0.0;
  double max_penetration_m = 0.0;     // deepest vertex beyond a plate/probe surface
  int newton_iterations = 0;
  int step_splits = 0;
  double residual = 0.0;              // final relative residual
};

// Hooks a caller (cellflow-run, the worker) passes in. All optional.
struct SceneCallbacks {
  std::function<void(const CurvePoint&)> on_point;           // after each load point
  std::function<void(double fraction_done)> on_progress;     // 0..1
  std::function<bool()> should_stop;                         // true: stop, result kCancelled
  // Called with the mesh once and with positions at each load point.
  std::function<void(const mesh::TetMesh&)> on_mesh;
  std::function<void(int index, std::span<const double> positions_m)> on_positions;
};

struct QuasiStaticResult {
  Status status;                     // ok, or the failure naming the load step and cause
  std::vector<CurvePoint> curve;     // every point computed, also on failure
};

QuasiStaticResult run_compression(const CompressionParams& params, const SceneCallbacks& callbacks = {});
QuasiStaticResult run_indentation(const IndentationParams& params, const SceneCallbacks& callbacks = {});

// Hertz forces (shared/validation/README.md).
// Sphere between two plates, total compression delta: F = (4/3) E* R^2 eps^1.5, eps = delta/(2R).
double hertz_plates_force_n(const elastic::Material& m, double radius_m, double compression_m);
// Probe (radius Rp) on a cell resting on a plate, total indentation delta; solves
// d_top + d_bottom = delta with equal force through both contacts.
double hertz_probe_force_n(const elastic::Material& m, double radius_m, double probe_radius_m,
                           double indentation_m);

}  // namespace cellflow::scenes
