// Shear-flow scene: the predicted thickness of the cell and the lattice that
// resolves it (shear_flow_resolution.h).
#include "physics/scenes/shear_flow/shear_flow_resolution.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::scenes {

namespace {

struct RoscoeRow {
  double ca, d;
};
// roscoe_elastic_sphere_shear.csv: ca, D_lambda1 (Roscoe 1967, lambda = 1)
constexpr RoscoeRow kRoscoeLambda1[] = {{0.01, 0.0125}, {0.02, 0.0250}, {0.05, 0.0621}, {0.1, 0.1216},
                                        {0.2, 0.2273},  {0.3, 0.3131},  {0.4, 0.3821},  {0.5, 0.4384},
                                        {0.6, 0.4851},  {0.75, 0.5421}, {1.0, 0.6135},  {1.25, 0.6662},
                                        {1.5, 0.7068},  {2.0, 0.7656}};

double round_up_to_half(double value) {
  return std::ceil(2.0 * value - 1e-9) / 2.0;
}

}  // namespace

double roscoe_taylor_deformation_lambda1(double ca) {
  if (!(ca > 0.0)) return 0.0;
  const RoscoeRow& first = kRoscoeLambda1[0];
  const RoscoeRow& last = kRoscoeLambda1[std::size(kRoscoeLambda1) - 1];
  const RoscoeRow& before_last = kRoscoeLambda1[std::size(kRoscoeLambda1) - 2];
  if (ca <= first.ca) return small_ca_taylor_deformation(ca);
  if (ca >= last.ca) {
    // 1 - D = (1 - D_last) (Ca / Ca_last)^-p through the last two rows
    const double p = std::log((1.0 - before_last.d) / (1.0 - last.d)) / std::log(last.ca / before_last.ca);
    return 1.0 - (1.0 - last.d) * std::pow(ca / last.ca, -p);
  }
  for (std::size_t i = 1; i < std::size(kRoscoeLambda1); ++i) {
    const RoscoeRow& lo = kRoscoeLambda1[i - 1];
    const RoscoeRow& hi = kRoscoeLambda1[i];
    if (ca <= hi.ca) return lo.d + (ca - lo.ca) / (hi.ca - lo.ca) * (hi.d - lo.d);
  }
  return last.d;
}

double predicted_thickness_over_radius(double ca) {
  const double d = std::clamp(roscoe_taylor_deformation_lambda1(ca), 0.0, 1.0);
  // D = (a3 - a1) / (a3 + a1) (paper eq. 13) with a1 a3 = R^2 (plane, incompressible)
  return 2.0 * std::sqrt((1.0 - d) / (1.0 + d));
}

double predicted_long_axis_over_radius_squared(double ca) {
  const double d = std::clamp(roscoe_taylor_deformation_lambda1(ca), 0.0, 0.999);
  // a3 / a1 = (1 + D) / (1 - D) with a1 a3 = R^2
  return (1.0 + d) / (1.0 - d);
}

double resolving_cells_per_radius(double ca, ibm::Kernel kernel) {
  const double thickness = predicted_thickness_over_radius(ca);
  if (!(thickness > 0.0)) return kMaxResolvingCellsPerRadius;
  // 2 a1 / (width dx) >= margin x 1.5 with dx = R / cpr
  return round_up_to_half(kThicknessMargin * kMinThicknessOverKernel * ibm::kernel_width(kernel) / thickness);
}

double refined_cells_per_radius(double cells_per_radius, double thickness_over_kernel) {
  const double scaled = thickness_over_kernel > 0.0 ? cells_per_radius * kThicknessMargin *
                                                          kMinThicknessOverKernel / thickness_over_kernel
                                                    : kMaxResolvingCellsPerRadius;
  return round_up_to_half(std::max(scaled, 1.25 * cells_per_radius));
}

}  // namespace cellflow::scenes
