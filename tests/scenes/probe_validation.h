// Shared by probe_validation_test and probe_validation_long_test: the
// validation/fe probe cases and their comparison with the CalculiX curves.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "physics/core/status.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {

// Largest |F / F_ref - 1| and largest step ratio the coarse setting (1000
// vertices, 10 points, default numerics) may reach. Measured 2026-12-04
// with the rings of the graded surface moved (mesh::PoleGrading::
// ring_jitter 1): small probe 3.28 % (at 0.2 um), step ratio 1.035, 3527
// vertices after the grading; colloidal probe 3.19 % (at 2 um), 1.029, 2222
// vertices (plain rings, 2026-12-02: 3.69 % / 1.058 / 3466 and 2.79 % /
// 1.036 / 2203). The error bounds leave 0.3-1.2 % for round-off of TetGen
// and the Newton path, the step bound 2-3 %.
inline constexpr double kSmallProbeCoarseError = 0.045;
inline constexpr double kColloidalProbeCoarseError = 0.035;
inline constexpr double kCoarseStepRatio = 1.06;
// Largest step between consecutive load points against the reference's raw
// step at the default setting: measured 1.029 colloidal, 1.059 small probe
// with the rings moved (1.029 / 1.041 against a local fit of the
// references, whose own steps reach 1.010 / 1.019; plain rings 1.075 /
// 1.092; validation/fe/README.md, README "Rings taken into contact one
// vertex at a time"). The reference's own steps against a smooth fit reach
// 1.05, so the bound on the raw ratio leaves that.
inline constexpr double kDefaultStepRatio = 1.08;

// The validation/fe cases (compare_cellflow.py CASES), nu = 0.48, w = 1.
inline IndentationParams small_probe(int vertices, int load_points) {
  IndentationParams p;
  p.cell.radius_m = 8e-6;
  p.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = vertices;
  p.probe_radius_m = 2.5e-6;
  p.max_indentation_m = 2e-6;
  p.load_points = load_points;
  p.numerics.threads = 1;
  return p;
}

inline IndentationParams colloidal_probe(int vertices, int load_points) {
  IndentationParams p;
  p.cell.radius_m = 40e-6;
  p.cell.material = {.youngs_modulus_pa = 580.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = vertices;
  p.probe_radius_m = 26.5e-6;
  p.max_indentation_m = 20e-6;
  p.load_points = load_points;
  p.numerics.threads = 1;
  return p;
}

// (indentation, force) of validation/fe/curves/NAME.csv, bounded read.
inline std::vector<std::pair<double, double>> reference_curve(const std::string& name) {
  std::ifstream in(std::string(CELLFLOW_SOURCE_DIR) + "/validation/fe/curves/" + name + ".csv");
  std::vector<std::pair<double, double>> rows;
  std::string line;
  std::getline(in, line);  // indentation_m,displacement_m,force_n
  while (rows.size() < 100000 && std::getline(in, line)) {
    std::istringstream fields(line);
    std::string x, displacement, force;
    if (!std::getline(fields, x, ',') || !std::getline(fields, displacement, ',') ||
        !std::getline(fields, force))
      break;
    rows.emplace_back(std::stod(x), std::stod(force));
  }
  return rows;
}

// Linear interpolation; NaN outside the curve.
inline double interpolate(const std::vector<std::pair<double, double>>& curve, double x) {
  const auto it = std::lower_bound(curve.begin(), curve.end(), std::make_pair(x, -1e300));
  if (it == curve.begin() || it == curve.end()) return std::nan("");
  const auto& [x1, f1] = *it;
  const auto& [x0, f0] = *(it - 1);
  return f0 + (x - x0) / (x1 - x0) * (f1 - f0);
}

struct ProbeComparison {
  Status status;
  double largest_error = 0.0;  // |F / F_ref - 1| over the compared range
  double largest_error_at_m = 0.0;
  bool monotone = true;
  // max over consecutive compared points of (F_i - F_{i-1}) / (F_ref(x_i) - F_ref(x_{i-1}))
  double largest_step_ratio = 0.0;
  std::size_t vertices = 0;
};

// Runs the case and compares from the first indentation on (small
// probe 0.1 um, colloidal 0.25 um).
inline ProbeComparison compare_with_reference(const IndentationParams& params) {
  const bool small = params.probe_radius_m < 10e-6;
  const std::vector<std::pair<double, double>> reference =
      reference_curve(small ? "small_probe" : "colloidal_probe");
  const double first = small ? 0.1e-6 : 0.25e-6;
  ProbeComparison c;
  if (reference.size() < 10) {
    c.status = Status(StatusCode::kNotFound, "reference curve missing");
    return c;
  }
  SceneCallbacks callbacks;
  callbacks.on_mesh = [&c](const mesh::TetMesh& m) { c.vertices = m.num_vertices(); };
  const QuasiStaticResult r = run_indentation(params, callbacks);
  c.status = r.status;
  double last_f = 0.0, last_ref = 0.0;
  bool have_last = false;
  for (const CurvePoint& p : r.curve) {
    const double ref = interpolate(reference, p.displacement_m);
    if (!(p.displacement_m >= first * (1.0 - 1e-9)) || std::isnan(ref)) continue;
    const double error = p.force_n / ref - 1.0;
    if (std::abs(error) > c.largest_error) {
      c.largest_error = std::abs(error);
      c.largest_error_at_m = p.displacement_m;
    }
    if (have_last) {
      if (p.force_n <= last_f) c.monotone = false;
      c.largest_step_ratio = std::max(c.largest_step_ratio, (p.force_n - last_f) / (ref - last_ref));
    }
    last_f = p.force_n;
    last_ref = ref;
    have_last = true;
  }
  if (!have_last && c.status.ok()) c.status = Status(StatusCode::kInternal, "no point in the compared range");
  return c;
}

// One line per comparison in the test log: the figures the README quotes.
inline void print_comparison(const char* name, const ProbeComparison& c) {
  std::printf(
      "%s: largest |error| %.2f %% at %.3g um, monotone %d, largest step / reference step %.3f, %zu "
      "vertices\n",
      name, 100.0 * c.largest_error, 1e6 * c.largest_error_at_m, c.monotone ? 1 : 0, c.largest_step_ratio,
      c.vertices);
}

}  // namespace cellflow::scenes
