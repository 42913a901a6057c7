// Error metrics of the accuracy benchmark (issue 5, item 1): force curves
// compared at common deformations, Richardson extrapolation in the mesh
// spacing with the observed order, and the Pareto front of error against time.
#pragma once

#include <span>
#include <string>
#include <vector>

namespace cellflow::bench {

// from, from + step, ..., to (inclusive, up to rounding).
std::vector<double> uniform_grid(double from, double to, double step);

// Force at each grid deformation, interpolated linearly in deformation on the
// curve (deformation[i], force[i]) (increasing deformation) with the point of
// first contact (0, 0) in front: the plates start at the zero-force distance.
// A grid point beyond the last deformation of the curve gives NaN (a curve
// that stopped early is not extrapolated).
std::vector<double> forces_on_grid(std::span<const double> deformation, std::span<const double> force,
                                   std::span<const double> grid);

// Largest |test / reference - 1| over the entries; NaN if any entry is NaN or
// the sizes differ.
double max_relative_error(std::span<const double> test, std::span<const double> reference);

// Three solutions on meshes of spacing h1 < h2 < h3 (F1 the finest), each a
// vector over the same deformation grid.
struct Richardson {
  // Least-squares ratio of successive differences, S = <F3-F2, F2-F1> / |F2-F1|^2;
  // S > 0 means monotone convergence, and S = (h3^p - h2^p) / (h2^p - h1^p)
  // defines the observed order p (S = r^p for a constant ratio r).
  double difference_ratio = 0.0;
  double order = 0.0;                   // observed p; NaN where no p in (0, 20] fits
  std::vector<double> pointwise_order;  // p of each grid point alone (NaN where oscillatory)
  bool usable = false;                  // p in (0.5, 4): extrapolated is the reference
  std::vector<double> extrapolated;     // F1 + (F1 - F2) / ((h2/h1)^p - 1); F1 when !usable
};
Richardson richardson_extrapolate(double h1, double h2, double h3, std::span<const double> f1,
                                  std::span<const double> f2, std::span<const double> f3);

// Observed order p of (h3^p - h2^p) / (h2^p - h1^p) = ratio (h1 < h2 < h3),
// found by bisection on (0, 20]; NaN when ratio is out of that range.
double observed_order(double h1, double h2, double h3, double ratio);

// The settings of a one-factor sweep: `base` with `field` set to each of
// `values` in turn.
template <class Setting, class Field, class Values>
std::vector<Setting> vary(const Setting& base, Field Setting::*field, const Values& values) {
  std::vector<Setting> settings;
  for (const auto value : values) {
    Setting s = base;
    s.*field = value;
    settings.push_back(s);
  }
  return settings;
}

// front[i]: no other point is at least as fast and at least as accurate and
// strictly better in one of the two. Points with a NaN or non-positive time or
// error are never on the front and do not dominate.
std::vector<bool> pareto_front(std::span<const double> time_s, std::span<const double> error);

}  // namespace cellflow::bench
