// Synthetic measured curves made by the scenes, and the coarse library
// numerics the default-suite tests share.
#pragma once

#include <random>
#include <vector>

#include "physics/calibration/curve_library.h"
#include "physics/calibration/fit.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::calibration::testing {

constexpr double kRadius = 8.6e-6;  // the paper's mean REF52 radius

// Coarse numerics of the default suite: 400 vertices, 15 load points to 0.75.
inline LibraryNumerics coarse_numerics(int vertices = 400, int load_points = 15) {
  LibraryNumerics n;
  n.target_vertex_count = vertices;
  n.load_points = load_points;
  n.max_deformation = 0.75;
  return n;
}

// The library simulates cells of the test's radius, so that its meshes and
// the data's are the same (TetGen meshes each radius afresh).
inline LibraryOptions same_mesh_options() {
  LibraryOptions o;
  o.reference_radius_m = kRadius;
  o.reference_modulus_pa = 100.0;
  return o;
}

// The plates scene at (E, w), nu = 0.48.
inline scenes::QuasiStaticResult run_plates(double e, double w, int vertices, int load_points,
                                            double max_deformation, double radius = kRadius) {
  scenes::CompressionParams p;
  p.cell.radius_m = radius;
  p.cell.material = {.youngs_modulus_pa = e, .poisson_ratio = 0.48, .mooney_rivlin_w = w};
  p.cell.target_vertex_count = vertices;
  p.max_deformation = max_deformation;
  p.load_points = load_points;
  p.numerics.threads = 1;
  return scenes::run_compression(p);
}

// A measured curve from a scene curve: the indentation reported from a
// contact estimate that lies `offset_m` before the true contact (so the fit
// should find s = offset_m), `pre_contact` zero-force samples before the
// true contact, and multiplicative noise F (1 + noise N(0, 1)), seeded.
inline MeasuredCurve measured_from(const scenes::QuasiStaticResult& run, double radius, double offset_m,
                                   double noise, unsigned seed, int pre_contact = 4) {
  MeasuredCurve m;
  m.radius_m = radius;
  const double step = run.curve.at(0).displacement_m;
  for (int k = pre_contact; k > 0; --k) {
    m.indentation_m.push_back(offset_m - k * step);
    m.force_n.push_back(0.0);
  }
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (const scenes::CurvePoint& p : run.curve) {
    m.indentation_m.push_back(offset_m + p.displacement_m);
    m.force_n.push_back(p.force_n * (1.0 + noise * normal(rng)));
  }
  return m;
}

}  // namespace cellflow::calibration::testing
