// Shared helpers of the elastic tests: meshes, deformations, finite differences.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/elastic/material.h"
#include "physics/mesh/tet_mesh.h"
#include "tests/elastic/box_mesh.h"

namespace cellflow::elastic::testing {

// A cell-sized box: 10 um, E = 2 kPa.
constexpr double kBoxSize = 10e-6;
constexpr double kYoungsModulus = 2e3;

inline Material material(double w, double nu) {
  return {kYoungsModulus, nu, w};
}

inline ElasticBody make_body(const mesh::TetMesh& mesh, const Material& m,
                             VolumetricTerm volumetric = VolumetricTerm::kPerTet) {
  const Material materials[] = {m};
  StatusOr<ElasticBody> body = make_elastic_body(mesh, materials, volumetric);
  EXPECT_TRUE(body.ok()) << body.status().to_string();
  return std::move(body).value();
}

// `count` disjoint random tetrahedra in a cube of side kBoxSize, positively
// oriented and not slivers (volume > 1 % of the cube of the longest edge).
inline mesh::TetMesh random_tets(int count, std::mt19937& rng) {
  std::uniform_real_distribution<double> coordinate(0.0, kBoxSize);
  mesh::TetMesh mesh;
  while (static_cast<int>(mesh.num_tets()) < count) {
    double x[4][3];
    for (auto& vertex : x) {
      for (double& c : vertex) c = coordinate(rng);
    }
    double e[3][3];
    double longest = 0.0;
    for (int a = 0; a < 3; ++a) {
      for (int d = 0; d < 3; ++d) e[a][d] = x[a][d] - x[3][d];
      longest = std::max(longest, std::sqrt(e[a][0] * e[a][0] + e[a][1] * e[a][1] + e[a][2] * e[a][2]));
    }
    double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                 e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                 e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    if (std::abs(det) / 6.0 < 0.01 * longest * longest * longest) continue;
    if (det < 0.0) std::swap(x[0], x[1]);
    const auto first = static_cast<std::int32_t>(mesh.num_vertices());
    for (const auto& vertex : x) {
      mesh.positions_m.insert(mesh.positions_m.end(), {vertex[0], vertex[1], vertex[2]});
      mesh.on_surface.push_back(1);
    }
    mesh.tets.insert(mesh.tets.end(), {first, first + 1, first + 2, first + 3});
    mesh.tet_region.push_back(mesh::Region::kCytoplasm);
  }
  return mesh;
}

// y = G X + smooth field + per-vertex noise: a large, non-affine deformation
// (G = 1 + entries in [-0.25, 0.25]); no element inverts for these amplitudes.
inline std::vector<double> random_deformation(const mesh::TetMesh& mesh, std::mt19937& rng, double noise_m) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  double g[9];
  for (int k = 0; k < 9; ++k) g[k] = (k % 4 == 0 ? 1.0 : 0.0) + 0.25 * unit(rng);
  const double phase = unit(rng);
  std::vector<double> y(mesh.positions_m.size());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double* x = mesh.positions_m.data() + 3 * v;
    for (int i = 0; i < 3; ++i) {
      y[3 * v + i] = g[3 * i] * x[0] + g[3 * i + 1] * x[1] + g[3 * i + 2] * x[2] +
                     0.05 * kBoxSize * std::sin(2.0 * x[(i + 1) % 3] / kBoxSize + phase) +
                     noise_m * unit(rng);
    }
  }
  return y;
}

inline double max_abs(const std::vector<double>& v) {
  double m = 0.0;
  for (const double x : v) m = std::max(m, std::abs(x));
  return m;
}

// max_k |a_k - b_k| / max_k |b_k|
inline double relative_error(const std::vector<double>& a, const std::vector<double>& b) {
  double diff = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k) diff = std::max(diff, std::abs(a[k] - b[k]));
  return diff / max_abs(b);
}

inline std::vector<double> forces_at(const ElasticBody& body, const std::vector<double>& y, int threads = 1) {
  std::vector<double> f(y.size(), 0.0);
  const ElasticEvaluation eval = add_elastic_forces(body, y.data(), f.data(), threads);
  EXPECT_EQ(eval.first_inverted_tet, -1);
  return f;
}

// -dE/dy by central differences of elastic_energy with step h.
inline std::vector<double> finite_difference_forces(const ElasticBody& body, std::vector<double> y,
                                                    double h) {
  std::vector<double> f(y.size());
  for (std::size_t k = 0; k < y.size(); ++k) {
    const double saved = y[k];
    y[k] = saved + h;
    const double plus = elastic_energy(body, y.data(), 1).energy_j;
    y[k] = saved - h;
    const double minus = elastic_energy(body, y.data(), 1).energy_j;
    y[k] = saved;
    f[k] = -(plus - minus) / (2.0 * h);
  }
  return f;
}

// Edge length of the mesh's first tet: the scale for finite-difference steps.
inline double first_edge_m(const mesh::TetMesh& mesh) {
  const double* x = mesh.positions_m.data();
  const std::int32_t a = mesh.tets[0], b = mesh.tets[3];
  return std::sqrt((x[3 * a] - x[3 * b]) * (x[3 * a] - x[3 * b]) +
                   (x[3 * a + 1] - x[3 * b + 1]) * (x[3 * a + 1] - x[3 * b + 1]) +
                   (x[3 * a + 2] - x[3 * b + 2]) * (x[3 * a + 2] - x[3 * b + 2]));
}

// The material cases of the brief: w = 1, 0.5, 0.25 and nu = 0.3, 0.48, with
// the paper's per-tet volumetric term, and the nearly incompressible ones
// (plus one at nu = 0.3) again with the nodal-averaged term.
struct MaterialCase {
  double w;
  double nu;
  VolumetricTerm volumetric = VolumetricTerm::kPerTet;
};
inline const MaterialCase kMaterialCases[] = {{1.0, 0.3},
                                              {0.5, 0.3},
                                              {0.25, 0.3},
                                              {1.0, 0.48},
                                              {0.5, 0.48},
                                              {0.25, 0.48},
                                              {0.5, 0.3, VolumetricTerm::kNodalAverage},
                                              {1.0, 0.48, VolumetricTerm::kNodalAverage},
                                              {0.5, 0.48, VolumetricTerm::kNodalAverage},
                                              {0.25, 0.48, VolumetricTerm::kNodalAverage}};

inline std::string case_name(const ::testing::TestParamInfo<MaterialCase>& info) {
  char name[32];
  std::snprintf(name, sizeof(name), "w%03ld_nu%03ld%s", std::lround(info.param.w * 100),
                std::lround(info.param.nu * 100),
                info.param.volumetric == VolumetricTerm::kNodalAverage ? "_nodal" : "");
  return name;
}

}  // namespace cellflow::elastic::testing
