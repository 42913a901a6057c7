// Shear-flow scene input handling: the derived setup (Ca <-> shear rate, wall
// speed, Reynolds scaling, Mach number), refusals naming the option, and the
// run protocol (callbacks, stop reasons, cancellation) on a tiny run.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "physics/elastic/material.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::scenes {
namespace {

// A 6 um cell, E = 10 Pa (mu = 3.38 Pa), water; Ca = 0.05 gives
// gammadot = 169 /s and Re_p = 0.006, raised to the target 0.1.
ShearFlowParams base_params() {
  ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = 400;
  p.capillary_number = 0.05;
  p.numerics.cells_per_radius = 4.0;
  p.numerics.threads = 1;  // beside other tests on a shared machine
  return p;
}

void expect_refused(const ShearFlowParams& p, StatusCode code, const std::string& field) {
  const StatusOr<ShearFlowSetup> plan = plan_shear_flow(p);
  ASSERT_FALSE(plan.ok()) << "expected a refusal naming " << field;
  EXPECT_EQ(plan.status().code(), code) << plan.status().to_string();
  EXPECT_NE(plan.status().message().find(field), std::string::npos) << plan.status().to_string();
  // run_shear_flow refuses the same way, before anything runs.
  const ShearFlowResult r = run_shear_flow(p);
  EXPECT_EQ(r.status.code(), code);
  EXPECT_EQ(r.stop, ShearFlowStop::kFailed);
  EXPECT_TRUE(r.samples.empty());
}

TEST(ShearFlowPlan, DerivedSetup) {
  const ShearFlowParams p = base_params();
  const StatusOr<ShearFlowSetup> plan = plan_shear_flow(p);
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  const ShearFlowSetup& s = *plan;
  const double mu = 10.0 / (2.0 * 1.48);
  EXPECT_NEAR(s.shear_modulus_pa, mu, 1e-12 * mu);
  // gammadot = Ca mu / eta   (paper eq. 17)
  EXPECT_NEAR(s.shear_rate_per_s, 0.05 * mu / 1e-3, 1e-12 * s.shear_rate_per_s);
  // Re_p = rho gammadot R^2 / eta, below the target 0.1: density raised to reach it
  EXPECT_NEAR(s.reynolds_number_physical, 1e3 * s.shear_rate_per_s * 36e-12 / 1e-3, 1e-12);
  EXPECT_LT(s.reynolds_number_physical, 0.1);
  EXPECT_NEAR(s.reynolds_number_simulated, 0.1, 1e-12);
  EXPECT_GT(s.simulated_density_kg_m3, 1e3);
  // lattice 10 x 15 x 5 radii at 4 cells per radius
  EXPECT_EQ(s.nx, 40);
  EXPECT_EQ(s.ny, 60);
  EXPECT_EQ(s.nz, 20);
  // u_wall = H gammadot / 2 with H = ny dx
  EXPECT_NEAR(s.wall_speed_m_per_s, 0.5 * 60 * (6e-6 / 4.0) * s.shear_rate_per_s,
              1e-12 * s.wall_speed_m_per_s);
  // gammadot_lb = Re nu_lb / cells_per_radius^2 = 0.1 (1/6) / 16
  EXPECT_NEAR(s.shear_rate_lattice, 0.1 / 6.0 / 16.0, 1e-12);
  EXPECT_NEAR(s.steps_per_strain, 960.0, 1e-6);
  // Ma = u_wall,lb sqrt(3) = (ny / 2) gammadot_lb sqrt(3)
  EXPECT_NEAR(s.mach_number, 30.0 * s.shear_rate_lattice * std::sqrt(3.0), 1e-12);
  EXPECT_GT(s.lattice_bytes, 40u * 60u * 20u * 19u * 4u);

  // Driving by the shear rate gives the same Ca.
  ShearFlowParams by_rate = p;
  by_rate.capillary_number = 0.0;
  by_rate.shear_rate_per_s = s.shear_rate_per_s;
  const StatusOr<ShearFlowSetup> plan2 = plan_shear_flow(by_rate);
  ASSERT_TRUE(plan2.ok()) << plan2.status().to_string();
  EXPECT_NEAR(plan2->capillary_number, 0.05, 1e-12);

  // target_reynolds_number = 0 keeps the physical density (and the tiny time step).
  ShearFlowParams physical = p;
  physical.numerics.target_reynolds_number = 0.0;
  const StatusOr<ShearFlowSetup> plan3 = plan_shear_flow(physical);
  ASSERT_TRUE(plan3.ok()) << plan3.status().to_string();
  EXPECT_DOUBLE_EQ(plan3->simulated_density_kg_m3, 1e3);
  EXPECT_NEAR(plan3->steps_per_strain / s.steps_per_strain, 0.1 / s.reynolds_number_physical, 1e-9);
}

TEST(ShearFlowPlan, RefusesNegativeViscosity) {
  ShearFlowParams p = base_params();
  p.fluid_viscosity_pa_s = -1e-3;
  expect_refused(p, StatusCode::kInvalidArgument, "shear_flow.fluid_viscosity_pa_s");
}

TEST(ShearFlowPlan, RefusesNegativeShearRateAndCapillaryNumber) {
  ShearFlowParams p = base_params();
  p.capillary_number = 0.0;
  p.shear_rate_per_s = -4.0;
  expect_refused(p, StatusCode::kInvalidArgument, "shear_flow.shear_rate_per_s");
  p.shear_rate_per_s = 0.0;
  p.capillary_number = -0.1;
  expect_refused(p, StatusCode::kInvalidArgument, "shear_flow.capillary_number");
  p.capillary_number = 0.0;
  expect_refused(p, StatusCode::kInvalidArgument, "set one of shear_flow.shear_rate_per_s");
  p.capillary_number = 0.1;
  p.shear_rate_per_s = 4.0;
  expect_refused(p, StatusCode::kInvalidArgument, "set only one of shear_flow.shear_rate_per_s");
}

TEST(ShearFlowPlan, RefusesBoxSmallerThanTheCell) {
  // At 4 cells per radius with peskin4 (4 nodes wide): periodic directions need
  // 2 + 4/4 = 3 radii, the wall direction 2 + 6/4 = 3.5.
  for (const char* field : {"box_x_radii", "box_y_radii", "box_z_radii"}) {
    ShearFlowParams p = base_params();
    double& box = std::string(field) == "box_x_radii"   ? p.numerics.box_x_radii
                  : std::string(field) == "box_y_radii" ? p.numerics.box_y_radii
                                                        : p.numerics.box_z_radii;
    box = 2.2;
    expect_refused(p, StatusCode::kInvalidArgument, std::string("shear_flow.numerics.") + field);
  }
  ShearFlowParams p = base_params();
  p.numerics.box_y_radii = 3.4;
  expect_refused(p, StatusCode::kInvalidArgument, "shear_flow.numerics.box_y_radii");
  p.numerics.box_y_radii = 3.5;
  EXPECT_TRUE(plan_shear_flow(p).ok());
}

TEST(ShearFlowPlan, RefusesLatticeAboveMemoryLimit) {
  ShearFlowParams p = base_params();
  p.numerics.cells_per_radius = 40.0;  // 400 x 600 x 200 nodes, ~3.5e9 bytes in float
  p.numerics.memory_limit_bytes = 1e9;
  p.numerics.target_reynolds_number = 0.01;  // keep the Mach number legal
  expect_refused(p, StatusCode::kResourceExhausted, "shear_flow.numerics.memory_limit_bytes");
}

TEST(ShearFlowPlan, RefusesMachNumberAboveLimit) {
  // Physical density at E = 1 kPa: Re_p = 0.6, u_wall / c_s = 0.33.
  ShearFlowParams p = base_params();
  p.cell.material.youngs_modulus_pa = 1000.0;
  p.numerics.target_reynolds_number = 0.0;
  expect_refused(p, StatusCode::kInvalidArgument, "shear_flow.numerics.max_mach");
  // With the density raised, the message also names the Reynolds target.
  ShearFlowParams q = base_params();
  q.numerics.target_reynolds_number = 1.0;  // Ma = 30 (1/6) / 16 sqrt(3) = 0.54
  expect_refused(q, StatusCode::kInvalidArgument, "shear_flow.numerics.target_reynolds_number");
}

TEST(ShearFlowPlan, ListsEveryViolation) {
  ShearFlowParams p = base_params();
  p.fluid_density_kg_m3 = 0.0;
  p.cell.radius_m = -1.0;
  p.cell.material.poisson_ratio = 0.5;
  p.numerics.relaxation_time = 0.5;
  p.numerics.sample_every_strain = 2.0;
  p.numerics.steady_tolerance = -1.0;
  const Status s = validate(p);
  ASSERT_EQ(s.code(), StatusCode::kInvalidArgument);
  for (const char* field :
       {"shear_flow.fluid_density_kg_m3", "shear_flow.cell.radius_m",
        "shear_flow.cell.material.poisson_ratio", "shear_flow.numerics.relaxation_time",
        "shear_flow.numerics.sample_every_strain", "shear_flow.numerics.steady_tolerance"}) {
    EXPECT_NE(s.message().find(field), std::string::npos) << field << " missing in: " << s.message();
  }
}

// The hydrodynamic radius offset: negative (down to -1) is the kernel's
// default, [0, 2] and at most half of cells_per_radius explicit; NaN, 2.5,
// -3 and 1.5 at 2 cells per radius are refused, naming the field.
TEST(ShearFlowPlan, HydrodynamicRadiusOffsetRange) {
  ShearFlowParams p = base_params();
  EXPECT_DOUBLE_EQ(radius_offset(p.numerics), default_radius_offset(p.numerics.ibm_kernel));
  EXPECT_DOUBLE_EQ(default_radius_offset(ibm::Kernel::kPeskin4), 0.4);
  for (const double ok : {-1.0, 0.0, 0.4, 2.0}) {
    p.numerics.hydrodynamic_radius_offset = ok;
    EXPECT_TRUE(validate(p).ok()) << ok << ": " << validate(p).to_string();
  }
  for (const double bad : {std::nan(""), 2.5, -3.0}) {
    p.numerics.hydrodynamic_radius_offset = bad;
    const Status s = validate(p);
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("shear_flow.numerics.hydrodynamic_radius_offset"), std::string::npos)
        << s.message();
  }
  p.numerics.hydrodynamic_radius_offset = 1.5;
  p.numerics.cells_per_radius = 2.0;
  EXPECT_NE(validate(p).message().find("shear_flow.numerics.hydrodynamic_radius_offset"), std::string::npos);
}

TEST(ShearFlowRun, RefusesACellTooStiffForTheExplicitUpdate) {
  ShearFlowParams p = base_params();
  p.capillary_number = 2e-4;  // k_max / (6 pi eta dx) ~ 50 at Ca = 2e-4, 4 cells per radius
  const ShearFlowResult r = run_shear_flow(p);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument) << r.status.to_string();
  EXPECT_NE(r.status.message().find("shear_flow.numerics.max_stiffness_ratio"), std::string::npos);
  EXPECT_NE(r.status.message().find("shear_flow.numerics.cells_per_radius"), std::string::npos);
  EXPECT_GT(r.stiffness_ratio, default_stiffness_limit(ibm::Kernel::kPeskin4));
  EXPECT_TRUE(r.samples.empty());
  // peskin4 is already in use: the message does not offer it as a remedy
  EXPECT_EQ(r.status.message().find("ibm_kernel"), std::string::npos) << r.status.message();
}

TEST(ShearFlowRun, RefusalOffersTheWidestKernelWhenANarrowerOneIsInUse) {
  ShearFlowParams p = base_params();
  p.numerics.ibm_kernel = ibm::Kernel::kTrilinear;
  p.capillary_number = 0.05;  // stiffness ratio ~0.24 at 4 cells per radius, trilinear's limit 0.05
  const ShearFlowResult r = run_shear_flow(p);
  EXPECT_EQ(r.status.code(), StatusCode::kInvalidArgument) << r.status.to_string();
  EXPECT_NE(r.status.message().find("shear_flow.numerics.ibm_kernel = peskin4"), std::string::npos)
      << r.status.message();
}

// Forcing the explicit update past its stability limit (ratio 8.2 at
// Ca = 0.001, allowed by max_stiffness_ratio = 100) must end as a numerical
// failure naming the time step and the cause, keep the samples, and hand
// back the last good state.
TEST(ShearFlowRun, BlowUpEndsAsNumericalFailureNamingTheStep) {
  ShearFlowParams p = base_params();
  p.cell.target_vertex_count = 1000;
  p.capillary_number = 0.001;
  p.numerics.max_stiffness_ratio = 100.0;
  p.numerics.max_strain = 2.0;
  int last_good_index = -1;
  ShearFlowCallbacks cb;
  cb.on_positions = [&](int index, double, std::span<const double> x) {
    last_good_index = index;
    for (double v : x) ASSERT_TRUE(std::isfinite(v));
  };
  const ShearFlowResult r = run_shear_flow(p, cb);
  EXPECT_EQ(r.status.code(), StatusCode::kNumericalFailure) << r.status.to_string();
  EXPECT_EQ(r.stop, ShearFlowStop::kFailed);
  EXPECT_NE(r.status.message().find("time step "), std::string::npos) << r.status.message();
  EXPECT_GT(r.stiffness_ratio, 5.0);
  EXPECT_FALSE(r.samples.empty());
  EXPECT_GT(r.time_steps, 0);
  EXPECT_GE(last_good_index, 1);  // t = 0 snapshot, then the last good state
}

// A tiny run (0.3 strain units at 4 cells per radius): callbacks in order,
// the fluid starting in the exact Couette profile, the stop reason.
TEST(ShearFlowRun, CallbacksAndCouetteStart) {
  ShearFlowParams p = base_params();
  p.numerics.box_x_radii = 4.0;
  p.numerics.box_y_radii = 5.0;
  p.numerics.box_z_radii = 4.0;
  p.numerics.max_strain = 0.3;
  p.numerics.snapshot_every_strain = 0.2;
  p.numerics.fluid_snapshots = true;
  int meshes = 0;
  std::vector<double> progress;
  std::vector<ShearFlowSample> samples;
  std::vector<double> snapshot_times;
  std::vector<double> first_positions;
  std::size_t mesh_vertices = 0;
  double max_couette_error = -1.0, wall_speed = 0.0;
  int fluid_snapshots = 0;
  ShearFlowCallbacks cb;
  cb.on_mesh = [&](const mesh::TetMesh& m) {
    ++meshes;
    mesh_vertices = m.num_vertices();
  };
  cb.on_progress = [&](double f) { progress.push_back(f); };
  cb.on_sample = [&](const ShearFlowSample& s) { samples.push_back(s); };
  cb.on_positions = [&](int index, double time_s, std::span<const double> x) {
    EXPECT_EQ(index, static_cast<int>(snapshot_times.size()));
    snapshot_times.push_back(time_s);
    if (first_positions.empty()) first_positions.assign(x.begin(), x.end());
  };
  const StatusOr<ShearFlowSetup> plan = plan_shear_flow(p);
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  cb.on_fluid_velocity = [&](const FluidVelocitySnapshot& f) {
    ++fluid_snapshots;
    if (f.index != 0) return;
    // u_x(y) = gammadot (y - H/2) at t = 0, nodes at y = (j + 1/2) dx; far from the cell (i = 0 column, z =
    // 0)
    const double h = f.ny * f.spacing_m;
    wall_speed = 0.5 * h * plan->shear_rate_per_s;
    max_couette_error = 0.0;
    for (int j = 0; j < f.ny; ++j) {
      const std::size_t n = static_cast<std::size_t>(f.nx) * j;
      const double expected = plan->shear_rate_per_s * ((j + 0.5) * f.spacing_m - 0.5 * h);
      max_couette_error = std::max(max_couette_error, std::abs(f.ux_m_per_s[n] - expected));
      max_couette_error = std::max(max_couette_error, std::abs(f.uy_m_per_s[n]));
    }
  };
  const ShearFlowResult r = run_shear_flow(p, cb);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  EXPECT_EQ(r.stop, ShearFlowStop::kMaxStrain);
  EXPECT_EQ(meshes, 1);
  EXPECT_EQ(samples.size(), r.samples.size());
  ASSERT_EQ(r.samples.size(), 4u);  // strain 0, 0.1, 0.2, 0.3
  for (std::size_t i = 0; i < r.samples.size(); ++i) {
    EXPECT_NEAR(r.samples[i].strain_units, 0.1 * i, 1e-9);
    EXPECT_NEAR(r.samples[i].time_s, r.samples[i].strain_units / plan->shear_rate_per_s, 1e-12);
  }
  EXPECT_GT(r.samples.back().taylor_deformation, r.samples.front().taylor_deformation);
  ASSERT_FALSE(progress.empty());
  EXPECT_DOUBLE_EQ(progress.back(), 1.0);
  EXPECT_EQ(snapshot_times.size(), 2u);  // strain 0 and 0.2
  EXPECT_EQ(fluid_snapshots, 2);
  // The fluid starts in the exact Couette profile (float storage: 1e-6 of u_wall).
  EXPECT_LT(max_couette_error, 1e-6 * wall_speed);
  // The cell starts centred in box coordinates.
  ASSERT_EQ(first_positions.size(), 3 * mesh_vertices);
  double mean_y = 0.0;
  for (std::size_t v = 0; v < mesh_vertices; ++v) mean_y += first_positions[3 * v + 1];
  mean_y /= static_cast<double>(mesh_vertices);
  EXPECT_NEAR(mean_y, 0.5 * plan->box_m[1], 0.02 * p.cell.radius_m);
}

TEST(ShearFlowRun, StopsOnRequestAndAtMaxTime) {
  ShearFlowParams p = base_params();
  p.numerics.box_x_radii = 4.0;
  p.numerics.box_y_radii = 5.0;
  p.numerics.box_z_radii = 4.0;
  ShearFlowCallbacks cb;
  int polls = 0;
  cb.should_stop = [&] { return ++polls >= 2; };
  const ShearFlowResult cancelled = run_shear_flow(p, cb);
  EXPECT_EQ(cancelled.status.code(), StatusCode::kCancelled);
  EXPECT_EQ(cancelled.stop, ShearFlowStop::kCancelled);
  EXPECT_LE(cancelled.time_steps, 2 * 256);

  const StatusOr<ShearFlowSetup> plan = plan_shear_flow(p);
  ASSERT_TRUE(plan.ok());
  p.numerics.max_time_s = 0.15 / plan->shear_rate_per_s;  // 0.15 strain units
  const ShearFlowResult timed = run_shear_flow(p);
  ASSERT_TRUE(timed.status.ok()) << timed.status.to_string();
  EXPECT_EQ(timed.stop, ShearFlowStop::kMaxTime);
  EXPECT_NEAR(timed.samples.back().strain_units, 0.15, 2.0 / plan->steps_per_strain);
}

}  // namespace
}  // namespace cellflow::scenes
