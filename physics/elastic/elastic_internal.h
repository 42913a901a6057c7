// Internal to cellflow::elastic, shared by its sources (elastic_body.cc,
// elastic_forces.cc, tangent_assembler.cc) and not part of the public API
// (physics/elastic/elastic_body.h): the "no inverted tet" marker, the size of
// the thread team of a tet loop, the CSR lists of the tets around each vertex
// and the nodal-averaged volumetric pressures.
#pragma once

#include <omp.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "physics/elastic/elastic_body.h"

namespace cellflow::elastic::detail {

constexpr std::int64_t kNoTet = std::numeric_limits<std::int64_t>::max();

// Below this many tets per thread the fork/join (and for forces the private
// buffers) cost more than the work they share; a tangent tet is ~8x the work.
constexpr std::int64_t kMinForceTetsPerThread = 4096;
constexpr std::int64_t kMinTangentTetsPerThread = 512;

inline int team_size(int threads, std::int64_t num_tets, std::int64_t min_tets_per_thread) {
  const int requested = threads > 0 ? threads : omp_get_max_threads();
  const std::int64_t useful = std::max<std::int64_t>(1, num_tets / min_tets_per_thread);
  return static_cast<int>(std::min<std::int64_t>(requested, useful));
}

// CSR lists of the tets around each vertex (defined in elastic_body.cc);
// `tets` holds nodes_per_tet indices per tet.
void vertex_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                 std::vector<std::int64_t>& offsets, std::vector<std::int32_t>& incident,
                 int nodes_per_tet = 4);

// Element::kQuadraticTet (defined in quadratic_tet.cc): the quadrature data
// of body.quadratic_tets at the reference positions x (fails on a point with
// det dX/dxi <= 0); energy and forces (forces may be null) of the tets
// [begin, end); the smallest J over the quadrature points.
Status build_quadratic_tets(ElasticBody& body, const double* x);
ElasticEvaluation quadratic_forces(const ElasticBody& body, const double* y, double* forces,
                                   std::int64_t begin, std::int64_t end);
VolumeRatioMinimum quadratic_min_volume_ratio(const ElasticBody& body, const double* y);

// kNodalAverage: the per-tet mean of the vertex pressures and the volumetric
// energy (defined in elastic_forces.cc, where its equations are).
double volumetric_pressures(const ElasticBody& body, const double* y, int team,
                            std::vector<double>& tet_pressure);

}  // namespace cellflow::elastic::detail
