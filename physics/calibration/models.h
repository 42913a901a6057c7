// Force models of indentation and compression, and the pieces every fit of
// them shares (issue 14). SI units throughout: forces in N, lengths in m,
// moduli in Pa.
//
// Every model here is linear in E at fixed nu and w (the energy is, and so is
// the force): F(d) = E s(d) with a shape s that does not depend on E. The
// best E for data (d_i, F_i) and weights w_i is then the closed-form weighted
// least-squares solution, and only the contact point (and w) need a search.
#pragma once

#include <functional>
#include <span>

#include "physics/core/status.h"

namespace cellflow::calibration {

// --- Hertz models (shared/validation/README.md; E* = E / (1 - nu^2)) ---------
// d: indentation (or total compression) in m; d <= 0 gives 0.

// Rigid paraboloid tip of apex radius r on an elastic half-space:
// F = 4/3 E/(1 - nu^2) sqrt(r) d^1.5
double hertz_paraboloid_force_n(double youngs_modulus_pa, double poisson_ratio, double tip_radius_m,
                                double indentation_m);

// Elastic sphere of radius R pressed on a rigid flat by d:
// F = 4/3 E/(1 - nu^2) sqrt(R) d^1.5
double hertz_sphere_on_flat_force_n(double youngs_modulus_pa, double poisson_ratio, double radius_m,
                                    double indentation_m);

// Elastic sphere between two rigid plates, total compression delta (two
// sphere-on-flat contacts of delta/2 each): F = 4/3 E/(1 - nu^2) R^2 eps^1.5, eps = delta/(2R)
double hertz_plates_force_n(double youngs_modulus_pa, double poisson_ratio, double radius_m,
                            double compression_m);

// Rigid probe of radius Rp on a cell of radius R resting on a plate, total
// indentation delta = d_top + d_bottom, the same force through both contacts:
// F = 4/3 E* sqrt(R12) d_top^1.5 = 4/3 E* sqrt(R) d_bottom^1.5, R12 = Rp R/(Rp + R)
// (scenes::hertz_probe_force_n).
double hertz_probe_force_n(double youngs_modulus_pa, double poisson_ratio, double radius_m,
                           double probe_radius_m, double indentation_m);

// --- Closed-form E -------------------------------------------------------------

// E = sum w_i F_i s_i / sum w_i s_i^2, s_i = F_model(d_i) / E (the shape per
// unit modulus, N/Pa): the weighted least-squares minimiser of
// sum w_i (F_i - E s_i)^2. kInvalidArgument when the sizes differ or the
// shapes are all zero (no point in contact).
StatusOr<double> closed_form_modulus(std::span<const double> shape_n_per_pa, std::span<const double> force_n,
                                     std::span<const double> weights);

// The objective at that E: sum w_i (F_i - E s_i)^2 = sum w F^2 - (sum w F s)^2 / sum w s^2.
double closed_form_objective(std::span<const double> shape_n_per_pa, std::span<const double> force_n,
                             std::span<const double> weights);

// --- 1-D minimisation ----------------------------------------------------------

struct Minimum {
  double x = 0.0;
  double value = 0.0;
  int evaluations = 0;
};

// Minimum of f on [lo, hi]: a scan of grid_points equally spaced points
// (ends included; >= 3) picks the best, then golden-section search in the
// interval between its grid neighbours until it is shorter than tolerance.
// The scan guards against the steps a coarse-mesh curve puts into the
// objective; golden section alone could stop in a side minimum. lo == hi
// returns f(lo).
Minimum minimise_1d(const std::function<double(double)>& f, double lo, double hi, double tolerance,
                    int grid_points = 11);

// --- Contact point as a free parameter -----------------------------------------

struct ContactFit {
  double contact_m = 0.0;  // x0: d_i = x_i - x0
  double youngs_modulus_pa = 0.0;
  double objective = 0.0;  // sum w_i (F_i - E s(x_i - x0))^2 at the minimum
  int points_in_contact = 0;
};

// Fits x0 in [x0_lo, x0_hi] by minimise_1d of the profile
// P(x0) = min_E sum w_i (F_i - E s(x_i - x0))^2 (E closed form inside);
// s(d) is the model's force per unit E (0 for d <= 0). The positions x_i
// need not be sorted. kInvalidArgument on mismatched sizes, an empty or
// inverted window, or no point in contact anywhere in it.
StatusOr<ContactFit> fit_contact_point(std::span<const double> x_m, std::span<const double> force_n,
                                       std::span<const double> weights,
                                       const std::function<double(double indentation_m)>& shape_n_per_pa,
                                       double x0_lo_m, double x0_hi_m);

}  // namespace cellflow::calibration
