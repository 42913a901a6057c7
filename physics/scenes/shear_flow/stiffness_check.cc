// Shear-flow scene: stability of the explicit elastic update, the stiffest
// vertex mode of the cell against the Stokes drag of one lattice spacing,
// checked before the run starts.
#include <Eigen/SparseCore>
#include <cmath>
#include <string>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/ibm/ibm.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/scenes/shear_flow/shear_flow_internal.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

namespace shear_flow_detail {

namespace {

// Largest eigenvalue of the elastic tangent stiffness at the reference
// configuration (N/m) by power iteration: the stiffest vertex mode.
double stiffest_mode(const elastic::ElasticBody& body, const std::vector<double>& positions_m, int threads) {
  elastic::TangentAssembler assembler(body);
  assembler.set_threads(threads);
  assembler.assemble(positions_m.data());
  Eigen::VectorXd v(assembler.stiffness().rows()), w(v.size());
  // Deterministic start with components in every mode.
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = std::sin(1.0 + 0.7 * static_cast<double>(i));
  v.normalize();
  double lambda = 0.0;
  for (int it = 0; it < 200; ++it) {
    assembler.multiply(v.data(), w.data());  // K v, with the applied volumetric part if any
    const double next = v.dot(w);            // Rayleigh quotient, v normalised
    const double norm = w.norm();
    if (!(norm > 0.0)) break;
    v = w / norm;
    if (it > 20 && std::abs(next - lambda) < 1e-4 * std::abs(next)) {
      lambda = next;
      break;
    }
    lambda = next;
  }
  return lambda;
}

}  // namespace

// Stability of the explicit update: the stiffest vertex mode against the
// Stokes drag of one lattice spacing, both in lattice units,
//   S = k_max,lb / (6 pi eta_lb),  k_max,lb = k_max dt^2 / m,  eta_lb = nu_lb (density 1).
// The update X += U dt relaxes a vertex mode of stiffness k with a mobility
// of about 1 / (6 pi eta_lb a) per step, a ~ dx; it scales as dt / (eta / mu).
// Limits per kernel: default_stiffness_limit (calibrated by blow-up runs).
Status check_stiffness(const ShearFlowParams& params, const units::Units& u, const elastic::ElasticBody& body,
                       const std::vector<double>& positions_m, const std::string& prefix,
                       ShearFlowResult& result) {
  return check_flow_stiffness(params, u, body, positions_m, prefix, result.setup.capillary_number,
                              &result.stiffness_ratio);
}

}  // namespace shear_flow_detail

Status check_flow_stiffness(const ShearFlowParams& params, const units::Units& u,
                            const elastic::ElasticBody& body, const std::vector<double>& positions_m,
                            std::string_view prefix_view, double capillary_number, double* ratio_out) {
  using shear_flow_detail::kPi;
  const std::string prefix(prefix_view);
  const ShearFlowNumerics& n = params.numerics;
  const double k_max = shear_flow_detail::stiffest_mode(body, positions_m, n.threads);
  // k_lb = F_lb / x_lb = force_to_lattice(k_max dx)
  const double k_lb = u.force_to_lattice(k_max * u.dx_m());
  const double drag_lb = 6.0 * kPi * u.kinematic_viscosity_lattice();
  // Scaled markers (numerics.hydrodynamic_radius_offset) spread F / s and
  // move the vertices by U / s: the coupling sees the stiffness k / s^2.
  const double s = 1.0 - radius_offset(n) * u.dx_m() / params.cell.radius_m;
  const double stiffness_ratio = k_lb / drag_lb / (s * s);
  if (ratio_out != nullptr) *ratio_out = stiffness_ratio;
  // The calibrated limits hold for per-tet volume terms, whose stiffest modes
  // alternate from vertex to vertex and are smoothed away by the kernel; the
  // nodal average's stiffest modes span a vertex patch and pass through it:
  // with peskin4 they blew up at ratio 1.96 (Ca = 0.001, 4 cells per radius,
  // 1000 vertices) and ran at 0.98. Half the limit for them.
  const double calibrated = default_stiffness_limit(n.ibm_kernel) *
                            (n.volumetric == elastic::VolumetricTerm::kNodalAverage ? 0.5 : 1.0);
  const double limit = n.max_stiffness_ratio > 0.0 ? n.max_stiffness_ratio : calibrated;
  if (!(stiffness_ratio <= limit)) {
    return invalid_argument(
        "the explicit elastic update would be unstable: stiffest vertex mode k_max / (6 pi eta dx) = " +
        number_text(stiffness_ratio, 6) + " (lattice units) exceeds the limit " + number_text(limit, 6) +
        " of " + std::string(ibm::kernel_name(n.ibm_kernel)) + " (" + prefix +
        "numerics.max_stiffness_ratio; Ca = " + number_text(capillary_number, 6) +
        "). The ratio scales as dt / (eta / mu): lower " + prefix + "numerics.target_reynolds_number (now " +
        number_text(n.target_reynolds_number, 6) + ") or " + prefix + "numerics.relaxation_time (now " +
        number_text(n.relaxation_time, 6) + "), raise " + prefix + "numerics.cells_per_radius (now " +
        number_text(n.cells_per_radius, 6) + ")" +
        (n.ibm_kernel == ibm::Kernel::kPeskin4
             ? std::string()
             : ", or use " + prefix + "numerics.ibm_kernel = peskin4 (the most stable)"));
  }
  return Status::ok_status();
}

double default_stiffness_limit(ibm::Kernel kernel) {
  switch (kernel) {
    case ibm::Kernel::kPeskin4:
      return 2.5;
    case ibm::Kernel::kPeskin3:
      return 0.4;
    case ibm::Kernel::kTrilinear:
      return 0.05;
  }
  return 0.05;
}

}  // namespace cellflow::scenes
