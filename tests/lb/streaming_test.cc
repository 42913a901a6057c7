// The two streaming schemes, the thread count and the fused velocity output
// must not change the result; parameter validation names the field.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "physics/lb/fluid.h"
#include "tests/lb/lb_test_support.h"

namespace cellflow::lb {
namespace {

using testing::make_or_die;

FluidParams sheared_box(Precision precision, Streaming streaming) {
  FluidParams p;
  p.nx = 9;  // not a multiple of the SIMD width
  p.ny = 7;
  p.nz = 5;
  p.tau = 0.7;
  p.lower_wall_velocity = {-0.03, 0.0, 0.01};
  p.upper_wall_velocity = {0.04, 0.0, 0.0};
  p.uniform_force = {1e-5, 2e-5, -1e-5};
  p.force_field = true;
  p.velocity_field = true;
  p.precision = precision;
  p.streaming = streaming;
  return p;
}

void perturb(Fluid& fluid, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> du(-0.02, 0.02);
  const std::size_t n = fluid.num_nodes();
  std::vector<double> rho(n), ux(n), uy(n), uz(n);
  for (std::size_t i = 0; i < n; ++i) {
    rho[i] = 1.0 + 0.5 * du(rng);
    ux[i] = du(rng);
    uy[i] = du(rng);
    uz[i] = du(rng);
  }
  set_equilibrium(fluid, rho, ux, uy, uz);
  const auto fill = [&](auto f) {
    using T = std::remove_reference_t<decltype(*f.x)>;
    for (std::size_t i = 0; i < n; ++i) {
      f.x[i] = static_cast<T>(1e-4 * du(rng));
      f.y[i] = static_cast<T>(1e-4 * du(rng));
      f.z[i] = static_cast<T>(1e-4 * du(rng));
    }
  };
  if (fluid.params().precision == Precision::kDouble)
    fill(fluid.force_field<double>());
  else
    fill(fluid.force_field<float>());
}

double max_population_difference(const Fluid& a, const Fluid& b) {
  double diff = 0.0;
  for (int k = 0; k < a.nz(); ++k)
    for (int j = 0; j < a.ny(); ++j)
      for (int i = 0; i < a.nx(); ++i) {
        const std::array<double, kQ> fa = populations(a, i, j, k), fb = populations(b, i, j, k);
        for (int q = 0; q < kQ; ++q) diff = std::max(diff, std::abs(fa[q] - fb[q]));
      }
  return diff;
}

// AA (in place, alternating phases) and two-array push perform the same
// arithmetic per node, so after odd and even step counts they agree to a few
// ulps of the populations (double 1e-15, float 1e-7; populations are O(0.1)).
TEST(Streaming, AaPatternMatchesTwoArrays) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    Fluid aa = make_or_die(sheared_box(precision, Streaming::kAA));
    Fluid two = make_or_die(sheared_box(precision, Streaming::kTwoArray));
    perturb(aa, 3);
    perturb(two, 3);
    const double tol = precision == Precision::kDouble ? 1e-15 : 1e-7;
    for (int s = 1; s <= 6; ++s) {
      collide_stream(aa);
      collide_stream(two);
      EXPECT_LE(max_population_difference(aa, two), tol) << "after step " << s;
    }
  }
}

// Rows are split between threads; each node's arithmetic does not depend on
// which thread does it, so one and two threads give bit-identical fields.
TEST(Streaming, ThreadCountDoesNotChangeResult) {
  for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
    FluidParams p = sheared_box(Precision::kDouble, streaming);
    p.nx = 40;  // above the serial threshold of 16384 nodes
    p.ny = 24;
    p.nz = 20;
    p.threads = 1;
    Fluid one = make_or_die(p);
    p.threads = 2;
    Fluid two = make_or_die(p);
    perturb(one, 5);
    perturb(two, 5);
    for (int s = 0; s < 3; ++s) {
      collide_stream(one);
      collide_stream(two);
    }
    EXPECT_EQ(max_population_difference(one, two), 0.0);
  }
}

// Every SIMD level of the row loops performs the same IEEE operations (no
// FMA contraction), so all levels this CPU has give bit-identical fields.
TEST(Streaming, SimdLevelsGiveIdenticalBits) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
      FluidParams p = sheared_box(precision, streaming);
      p.nx = 37;  // vector body and remainder
      p.simd = Simd::kGeneric;
      Fluid reference = make_or_die(p);
      perturb(reference, 17);
      for (int s = 0; s < 5; ++s) collide_stream(reference);
      for (Simd simd : {Simd::kAvx2, Simd::kAvx512}) {
        if (!simd_supported(simd)) continue;
        p.simd = simd;
        Fluid fluid = make_or_die(p);
        perturb(fluid, 17);
        for (int s = 0; s < 5; ++s) collide_stream(fluid);
        EXPECT_EQ(max_population_difference(reference, fluid), 0.0) << simd_name(simd);
      }
    }
  }
}

// The velocity field written inside the fused step equals the on-demand
// velocity (with the half-force shift) of the state before that step, in both
// AA phases and both schemes.
TEST(Streaming, FusedVelocityEqualsOnDemandVelocity) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
      Fluid fluid = make_or_die(sheared_box(precision, streaming));
      perturb(fluid, 11);
      for (int s = 0; s < 3; ++s) {
        const testing::Velocity before = testing::velocity(fluid);
        collide_stream(fluid);
        double diff = 0.0, scale = 0.0;
        const auto compare = [&](auto u) {
          for (std::size_t i = 0; i < fluid.num_nodes(); ++i) {
            diff = std::max({diff, std::abs(u.x[i] - before.ux[i]), std::abs(u.y[i] - before.uy[i]),
                             std::abs(u.z[i] - before.uz[i])});
            scale = std::max(scale, std::abs(before.ux[i]));
          }
        };
        if (precision == Precision::kDouble)
          compare(fluid.velocity_field<double>());
        else
          compare(fluid.velocity_field<float>());
        // float: the kernel computes in float (eps 6e-8 on rho ~ 1 and j)
        EXPECT_LT(diff, (precision == Precision::kDouble ? 1e-14 : 1e-6) * scale) << "step " << s;
      }
    }
  }
}

TEST(Streaming, UpdateVelocityFieldFillsField) {
  Fluid fluid = make_or_die(sheared_box(Precision::kDouble, Streaming::kAA));
  perturb(fluid, 13);
  collide_stream(fluid);  // odd phase: populations are stored swapped
  const testing::Velocity v = testing::velocity(fluid);
  update_velocity_field(fluid);
  const VectorField<const double> u = fluid.velocity_field<double>();
  for (std::size_t i = 0; i < fluid.num_nodes(); ++i) {
    ASSERT_EQ(u.x[i], v.ux[i]);
    ASSERT_EQ(u.y[i], v.uy[i]);
    ASSERT_EQ(u.z[i], v.uz[i]);
  }
}

TEST(Streaming, EquilibriumRoundTrip) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    FluidParams p = sheared_box(precision, Streaming::kAA);
    p.force_field = false;
    p.uniform_force = {0, 0, 0};
    Fluid fluid = make_or_die(p);
    const std::size_t n = fluid.num_nodes();
    std::vector<double> rho(n), ux(n), uy(n), uz(n);
    for (std::size_t i = 0; i < n; ++i) {
      rho[i] = 1.0 + 1e-3 * static_cast<double>(i % 7);
      ux[i] = 0.01 * std::sin(0.1 * static_cast<double>(i));
      uy[i] = -0.02;
      uz[i] = 0.005 * static_cast<double>(i % 3);
    }
    set_equilibrium(fluid, rho, ux, uy, uz);
    const testing::Velocity v = testing::velocity(fluid);
    const double tol = precision == Precision::kDouble ? 1e-15 : 1e-7;
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_NEAR(v.density[i], rho[i], tol);
      ASSERT_NEAR(v.ux[i], ux[i], tol);
      ASSERT_NEAR(v.uy[i], uy[i], tol);
      ASSERT_NEAR(v.uz[i], uz[i], tol);
    }
  }
}

TEST(Validate, RejectsBadParamsNamingTheField) {
  FluidParams p;
  p.nx = p.ny = p.nz = 4;
  EXPECT_TRUE(validate(p).ok());
  FluidParams bad = p;
  bad.tau = 0.5;
  Status s = validate(bad);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("tau"), std::string::npos) << s.message();
  bad = p;
  bad.ny = 0;
  EXPECT_EQ(validate(bad).code(), StatusCode::kInvalidArgument);
  bad = p;
  bad.upper_wall_velocity = {0.0, 0.01, 0.0};
  s = validate(bad);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("tangential"), std::string::npos) << s.message();
  bad = p;
  bad.trt_magic = 0.0;
  EXPECT_NE(validate(bad).message().find("trt_magic"), std::string::npos);
  EXPECT_FALSE(make_fluid(bad).ok());
}

TEST(Validate, MemoryBytesCountsEveryArray) {
  FluidParams p;
  p.nx = 16;
  p.ny = 16;
  p.nz = 16;  // 4096 nodes; each direction array holds 4096 + 16 (alignment and anti-aliasing padding)
  p.walls_y = false;
  const std::size_t stride = 4096 + 16;
  EXPECT_EQ(memory_bytes(p), 19u * stride * 8u);
  p.streaming = Streaming::kTwoArray;
  p.precision = Precision::kFloat;
  p.force_field = true;
  p.velocity_field = true;
  EXPECT_EQ(memory_bytes(p), (38u + 6u) * stride * 4u);
  p.streaming = Streaming::kAA;
  p.walls_y = true;  // AA keeps the density of the two wall layers
  EXPECT_EQ(memory_bytes(p), (19u + 6u) * stride * 4u + 2u * 16u * 16u * 4u);
}

}  // namespace
}  // namespace cellflow::lb
