// Shear-flow scene: the lattice that resolves the cell's thickness. At large
// Ca the cell flattens into a sheet whose thickness 2 a1 approaches the
// width of the immersed-boundary kernel, which then averages the fluid
// velocity over both faces and spreads the forces of both onto the same
// nodes. Measured at Ca = 2 (docs/shear_flow/large_ca.md): down to about
// 0.7 kernel widths the lattice does not move D (6, 9 and 12 cells per
// radius within 0.4 %; 6 cells per radius within 1.1 % of the exact steady
// ellipsoid). The plan picks the lattice from a prediction of the steady
// thickness, and the run checks the thickness at every sample and restarts
// on a finer lattice when it falls below kMinThicknessOverKernel kernel
// widths (shear_flow.cc).
#pragma once

#include "physics/ibm/ibm.h"

namespace cellflow::scenes {

// Roscoe's steady Taylor deformation for viscosity ratio lambda = 1
// (shared/validation/roscoe_elastic_sphere_shear.csv, column D_lambda1),
// linear between its rows (Ca 0.01 ... 2), D = (5/4) Ca below 0.01, and above
// Ca = 2 the power law 1 - D ~ Ca^-0.778 through its last two rows (an
// extrapolation; no theory number there).
double roscoe_taylor_deformation_lambda1(double capillary_number);

// Predicted steady thickness 2 a1 / R of the cell: Roscoe's deformation is a
// plane one of an incompressible sphere (a2 = R, a1 a3 = R^2; measured at
// Ca = 2, 6 cells per radius: a1 a3 = 0.96 R^2), so with
// a3 / a1 = (1 + D) / (1 - D), a1 / R = sqrt((1 - D) / (1 + D)).
double predicted_thickness_over_radius(double capillary_number);

// Predicted (a3 / R)^2 = (1 + D) / (1 - D) of the long half-axis a3 by the
// same plane deformation: the length on which the deformed cell meets the
// flow, so its Reynolds number is Re_p (a3 / R)^2 (7.5 Re_p at Ca = 2).
double predicted_long_axis_over_radius_squared(double capillary_number);

// The Stokes acceleration (ShearFlowNumerics::target_reynolds_number) lets the
// deformed cell's Reynolds number Re_p (a3 / R)^2 reach this many targets.
// Measured at Ca = 2 (a3 = 2.6 R; docs/shear_flow/large_ca.md): Re_p 0.039
// (0.29 on a3) settled within 1.1 % of the exact steady D, Re_p 0.1 (0.75 on
// a3) left D 5 % above it and rising at strain 50. With 3 the target binds
// from Ca of about 0.7 (Re_p 0.04 at Ca = 2); below, Re_p = target as before.
inline constexpr double kLongAxisReynoldsAllowance = 3.0;

// The thickness control acts only on a flattened cell, 2 a1 below this many
// radii (predicted: Ca above about 0.27, D above 0.28): a lattice that does
// not resolve the sphere itself (3 cells per radius in the coarse tests) is
// the caller's choice, and the run only warns.
inline constexpr double kFlattenedThicknessOverRadius = 1.5;

// The lattice predictions are made with this margin over
// kMinThicknessOverKernel: the prediction is the steady shape, and the
// transient overshoots it (Ca = 2, 6 cells per radius: predicted 1.09 kernel
// widths, 0.81 at the overshoot, 0.99 steady; docs/shear_flow/large_ca.md).
inline constexpr double kThicknessMargin = 1.1;

// Cells per radius at which the predicted thickness spans
// kThicknessMargin x kMinThicknessOverKernel kernel widths, rounded up to a
// multiple of 0.5: cpr = margin x 1.5 x width / (2 a1 / R).
double resolving_cells_per_radius(double capillary_number, ibm::Kernel kernel);

// A run's finer lattice after a sample measured `thickness_over_kernel`
// below the limit at `cells_per_radius`: the thickness scaled to the margin
// (it scales with cells_per_radius at a fixed shape), at least 1.25 x the old
// value (an under-resolved cell is thinner than the resolved one), rounded
// up to a multiple of 0.5.
double refined_cells_per_radius(double cells_per_radius, double thickness_over_kernel);

// The finest lattice the scene chooses by itself (predicted or on a
// restart): above it the plan's memory and work limits bind for the default
// box, and the user sets cells_per_radius.
inline constexpr double kMaxResolvingCellsPerRadius = 16.0;
// Restarts on a finer lattice per run at most. One: the cell thins the same
// on any lattice (docs/shear_flow/large_ca.md), and each restart costs
// (cpr_new / cpr_old)^5 of the run.
inline constexpr int kMaxResolutionRestarts = 1;

}  // namespace cellflow::scenes
