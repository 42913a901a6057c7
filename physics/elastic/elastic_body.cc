#include "physics/elastic/elastic_body.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "physics/elastic/tet_kernel.h"

namespace cellflow::elastic {

namespace {

constexpr std::int64_t kNoTet = std::numeric_limits<std::int64_t>::max();

// Below this many tets per thread the fork/join (and for forces the private
// buffers) cost more than the work they share; a tangent tet is ~8x the work.
constexpr std::int64_t kMinForceTetsPerThread = 4096;
constexpr std::int64_t kMinTangentTetsPerThread = 512;

int team_size(int threads, std::int64_t num_tets, std::int64_t min_tets_per_thread) {
  const int requested = threads > 0 ? threads : omp_get_max_threads();
  const std::int64_t useful = std::max<std::int64_t>(1, num_tets / min_tets_per_thread);
  return static_cast<int>(std::min<std::int64_t>(requested, useful));
}

kernel::TetParams tet_params(const ElasticBody& body, std::int64_t t) {
  return {body.b_matrix.data() + 9 * t, body.ref_volume_m3[t], body.mu1_pa[t], body.mu2_pa[t],
          body.kappa_pa[t]};
}

// Energy (and, with kForces, the forces scattered into `forces`) of tets
// [begin, end). The first inverted tet of the range goes to first_inverted.
//
// The per-tet stages of tet_kernel.h run in blocks of kBlock tets, one stage
// at a time: the inverse cube root is a long dependency chain, and in a
// tet-after-tet loop it stalls everything after it; over a block its
// iterations are independent and overlap.
// With tet_pressure (kNodalAverage) the tets carry no kappa term; their
// stress gets tet_pressure[t] cof(F) instead, and the volumetric energy is
// summed per vertex by volumetric_pressures.
template <bool kMooneyRivlin, bool kForces>
double evaluate_range(const ElasticBody& body, const double* y, double* forces, std::int64_t begin,
                      std::int64_t end, std::int64_t& first_inverted, const double* tet_pressure) {
  constexpr int kBlock = 16;
  const std::int32_t* tets = body.tets.data();
  const double* b_matrix = body.b_matrix.data();
  const double* volume = body.ref_volume_m3.data();
  const double* mu1 = body.mu1_pa.data();
  const double* mu2 = body.mu2_pa.data();
  const double* kappa = body.kappa_pa.data();
  kernel::TetStress block[kBlock];
  double j_m13[kBlock];
  double block_forces[kBlock][12];
  double energy = 0.0;
  for (std::int64_t first = begin; first < end; first += kBlock) {
    const int size = static_cast<int>(std::min<std::int64_t>(kBlock, end - first));
    for (int lane = 0; lane < size; ++lane) {
      const std::int32_t* v = tets + 4 * (first + lane);
      kernel::TetStress& s = block[lane];
      s.det_f = kernel::deformation_gradient(
          b_matrix + 9 * (first + lane), y + 3 * static_cast<std::int64_t>(v[0]),
          y + 3 * static_cast<std::int64_t>(v[1]), y + 3 * static_cast<std::int64_t>(v[2]),
          y + 3 * static_cast<std::int64_t>(v[3]), s.f, s.cof);
    }
    // J^-1/3; an inverted lane (J <= 0) gets a harmless J = 1 and is skipped below.
    for (int lane = 0; lane < size; ++lane) {
      const double det_f = block[lane].det_f;
      j_m13[lane] = kernel::inverse_cube_root(det_f <= 0.0 ? 1.0 : det_f);
    }
    for (int lane = 0; lane < size; ++lane) {
      const std::int64_t t = first + lane;
      kernel::TetStress& s = block[lane];
      if (tet_pressure == nullptr) {
        kernel::stress_from_gradient<kMooneyRivlin>(mu1[t], kMooneyRivlin ? mu2[t] : 0.0, kappa[t],
                                                    j_m13[lane], s);
      } else {
        kernel::stress_from_gradient<kMooneyRivlin>(mu1[t], kMooneyRivlin ? mu2[t] : 0.0, 0.0, j_m13[lane], s,
                                                    tet_pressure[t]);
      }
      if constexpr (kForces) {
        kernel::forces_from_stress(b_matrix + 9 * t, volume[t], s.stress, block_forces[lane]);
      }
    }
    for (int lane = 0; lane < size; ++lane) {
      const std::int64_t t = first + lane;
      if (block[lane].det_f <= 0.0) {
        first_inverted = std::min(first_inverted, t);
        continue;
      }
      energy += volume[t] * block[lane].energy_density;
      if constexpr (kForces) {
        const std::int32_t* v = tets + 4 * t;
        for (int a = 0; a < 4; ++a) {
          double* out = forces + 3 * static_cast<std::int64_t>(v[a]);
          out[0] += block_forces[lane][3 * a];
          out[1] += block_forces[lane][3 * a + 1];
          out[2] += block_forces[lane][3 * a + 2];
        }
      }
    }
  }
  return energy;
}

// Deformed volume v = det[y1 - y4, y2 - y4, y3 - y4] / 6 of a tetrahedron.
double deformed_volume(const double* y, const std::int32_t* v) {
  const double* y3 = y + 3 * static_cast<std::int64_t>(v[3]);
  double d[9];
  for (int k = 0; k < 3; ++k) {
    const double* yk = y + 3 * static_cast<std::int64_t>(v[k]);
    for (int i = 0; i < 3; ++i) d[3 * i + k] = yk[i] - y3[i];
  }
  return (d[0] * (d[4] * d[8] - d[5] * d[7]) + d[1] * (d[5] * d[6] - d[3] * d[8]) +
          d[2] * (d[3] * d[7] - d[4] * d[6])) /
         6.0;
}

// kNodalAverage: the vertex pressures p_a = (kappa V)_a / V_a (Jbar_a - 1),
// Jbar_a = v_a / V_a with v_a = sum_{t at a} v_t / 4, and per tet the mean of
// its four vertices' pressures (tet_pressure, one per tet). Returns the
// volumetric energy sum_a (kappa V)_a / 2 (Jbar_a - 1)^2. Its gradient is
// sum_a p_a dv_a/dy = sum_t tet_pressure_t V0_t dJ_t/dy, so the tet stress
// takes tet_pressure_t cof(F) (dJ/dF = cof F).
double volumetric_pressures(const ElasticBody& body, const double* y, int team,
                            std::vector<double>& tet_pressure) {
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  const std::int64_t num_vertices = static_cast<std::int64_t>(body.num_vertices);
  const std::int32_t* tets = body.tets.data();
  std::vector<double> tet_volume(static_cast<std::size_t>(num_tets));
  std::vector<double> vertex_pressure(static_cast<std::size_t>(num_vertices), 0.0);
  tet_pressure.resize(static_cast<std::size_t>(num_tets));
  double energy = 0.0;
#pragma omp parallel num_threads(team) reduction(+ : energy)
  {
#pragma omp for schedule(static)
    for (std::int64_t t = 0; t < num_tets; ++t) tet_volume[t] = deformed_volume(y, tets + 4 * t);
#pragma omp for schedule(static)
    for (std::int64_t a = 0; a < num_vertices; ++a) {
      const double volume = body.vertex_volume_m3[a];
      if (volume <= 0.0) continue;  // a vertex of no tet
      double deformed = 0.0;
      for (std::int64_t k = body.vertex_tet_offsets[a]; k < body.vertex_tet_offsets[a + 1]; ++k)
        deformed += tet_volume[body.vertex_tets[k]];
      // Jbar_a - 1 = v_a / V_a - 1
      const double excess = 0.25 * deformed / volume - 1.0;
      vertex_pressure[a] = body.vertex_bulk_volume_j[a] / volume * excess;
      energy += 0.5 * body.vertex_bulk_volume_j[a] * excess * excess;
    }
#pragma omp for schedule(static)
    for (std::int64_t t = 0; t < num_tets; ++t) {
      const std::int32_t* v = tets + 4 * t;
      tet_pressure[t] = 0.25 * (vertex_pressure[v[0]] + vertex_pressure[v[1]] + vertex_pressure[v[2]] +
                                vertex_pressure[v[3]]);
    }
  }
  return energy;
}

// Tets are split into one contiguous range per thread. Thread 0 scatters into
// forces_n, the others into private buffers that are added afterwards: no two
// threads write the same memory, and every thread streams its tets in order
// (faster than colouring here, see bench/elastic).
template <bool kMooneyRivlin, bool kForces>
ElasticEvaluation evaluate(const ElasticBody& body, const double* y, double* forces, int threads) {
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  const std::int64_t num_dofs = 3 * static_cast<std::int64_t>(body.num_vertices);
  const int team = team_size(threads, num_tets, kMinForceTetsPerThread);
  ElasticEvaluation result;
  std::int64_t first_inverted = kNoTet;
  std::vector<double> pressure;
  double volumetric_energy = 0.0;
  if (body.volumetric == VolumetricTerm::kNodalAverage) {
    volumetric_energy = volumetric_pressures(body, y, team, pressure);
  }
  const double* tet_pressure = pressure.empty() ? nullptr : pressure.data();
  if (team == 1) {
    result.energy_j =
        evaluate_range<kMooneyRivlin, kForces>(body, y, forces, 0, num_tets, first_inverted, tet_pressure);
  } else {
    std::vector<double> buffers;
    if constexpr (kForces) buffers.assign(static_cast<std::size_t>((team - 1) * num_dofs), 0.0);
    double energy = 0.0;
#pragma omp parallel num_threads(team) reduction(+ : energy) reduction(min : first_inverted)
    {
      const int rank = omp_get_thread_num();
      const int size = omp_get_num_threads();
      double* out = nullptr;
      if constexpr (kForces) out = rank == 0 ? forces : buffers.data() + (rank - 1) * num_dofs;
      const std::int64_t begin = num_tets * rank / size;
      const std::int64_t end = num_tets * (rank + 1) / size;
      energy = evaluate_range<kMooneyRivlin, kForces>(body, y, out, begin, end, first_inverted, tet_pressure);
      if constexpr (kForces) {
        if (size > 1) {
#pragma omp barrier
#pragma omp for schedule(static)
          for (std::int64_t k = 0; k < num_dofs; ++k) {
            double sum = 0.0;
            for (int r = 1; r < size; ++r) sum += buffers[(r - 1) * num_dofs + k];
            forces[k] += sum;
          }
        }
      }
    }
    result.energy_j = energy;
  }
  result.energy_j += volumetric_energy;
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

// CSR lists of the tets around each vertex.
void vertex_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                 std::vector<std::int64_t>& offsets, std::vector<std::int32_t>& incident) {
  const std::int64_t num_tets = static_cast<std::int64_t>(tets.size() / 4);
  offsets.assign(num_vertices + 1, 0);
  for (const std::int32_t v : tets) ++offsets[v + 1];
  for (std::size_t v = 0; v < num_vertices; ++v) offsets[v + 1] += offsets[v];
  incident.resize(tets.size());
  std::vector<std::int64_t> next(offsets.begin(), offsets.end() - 1);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < 4; ++a) incident[next[tets[4 * t + a]]++] = static_cast<std::int32_t>(t);
  }
}

}  // namespace

StatusOr<ElasticBody> make_elastic_body(const mesh::TetMesh& mesh, std::span<const Material> materials,
                                        VolumetricTerm volumetric) {
  const std::size_t num_vertices = mesh.num_vertices();
  const std::size_t num_tets = mesh.num_tets();
  if (mesh.positions_m.size() % 3 != 0 || mesh.tets.size() % 4 != 0) {
    return invalid_argument("mesh: positions_m must hold 3 and tets 4 entries per item");
  }
  if (!mesh.tet_region.empty() && mesh.tet_region.size() != num_tets) {
    return invalid_argument("mesh.tet_region has " + std::to_string(mesh.tet_region.size()) +
                            " entries, expected one per tetrahedron (" + std::to_string(num_tets) + ")");
  }
  std::vector<Moduli> moduli;
  for (std::size_t m = 0; m < materials.size(); ++m) {
    Status status = validate(materials[m], "materials[" + std::to_string(m) + "].");
    if (!status.ok()) return status;
    moduli.push_back(moduli_from(materials[m]));
  }

  ElasticBody body;
  body.num_vertices = num_vertices;
  body.tets = mesh.tets;
  body.b_matrix.resize(9 * num_tets);
  body.ref_volume_m3.resize(num_tets);
  body.mu1_pa.resize(num_tets);
  body.mu2_pa.resize(num_tets);
  body.kappa_pa.resize(num_tets);
  const double* x = mesh.positions_m.data();
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = mesh.tets.data() + 4 * t;
    for (int a = 0; a < 4; ++a) {
      if (v[a] < 0 || static_cast<std::size_t>(v[a]) >= num_vertices) {
        return invalid_argument("mesh.tets: tetrahedron " + std::to_string(t) + " names vertex " +
                                std::to_string(v[a]) + ", outside [0, " + std::to_string(num_vertices) + ")");
      }
    }
    const std::size_t region = mesh.tet_region.empty() ? 0 : static_cast<std::size_t>(mesh.tet_region[t]);
    if (region >= moduli.size()) {
      return invalid_argument("materials: tetrahedron " + std::to_string(t) + " is in region " +
                              std::to_string(region) + " but only " + std::to_string(moduli.size()) +
                              " materials were given");
    }
    // J_ik = x_i^k - x_i^4   (paper eq. 12)
    double jac[9];
    for (int i = 0; i < 3; ++i) {
      for (int k = 0; k < 3; ++k) jac[3 * i + k] = x[3 * v[k] + i] - x[3 * v[3] + i];
    }
    const double cof[9] = {jac[4] * jac[8] - jac[5] * jac[7], jac[5] * jac[6] - jac[3] * jac[8],
                           jac[3] * jac[7] - jac[4] * jac[6], jac[2] * jac[7] - jac[1] * jac[8],
                           jac[0] * jac[8] - jac[2] * jac[6], jac[1] * jac[6] - jac[0] * jac[7],
                           jac[1] * jac[5] - jac[2] * jac[4], jac[2] * jac[3] - jac[0] * jac[5],
                           jac[0] * jac[4] - jac[1] * jac[3]};
    const double det = jac[0] * cof[0] + jac[1] * cof[1] + jac[2] * cof[2];
    // V0 = det J / 6 must be positive: vertex order as in paper eq. 11-12
    if (!(det > 0.0)) {
      return Status(StatusCode::kFailedPrecondition,
                    "mesh: tetrahedron " + std::to_string(t) + " (vertices " + std::to_string(v[0]) + " " +
                        std::to_string(v[1]) + " " + std::to_string(v[2]) + " " + std::to_string(v[3]) +
                        ") has reference volume " + std::to_string(det / 6.0) +
                        " m^3; it must be > 0 (det[x1-x4, x2-x4, x3-x4] > 0)");
    }
    // B = J^-1 = cof(J)^T / det J   (paper eq. 12)
    for (int k = 0; k < 3; ++k) {
      for (int l = 0; l < 3; ++l) body.b_matrix[9 * t + 3 * k + l] = cof[3 * l + k] / det;
    }
    body.ref_volume_m3[t] = det / 6.0;
    body.mu1_pa[t] = moduli[region].mu1_pa;
    body.mu2_pa[t] = moduli[region].mu2_pa;
    body.kappa_pa[t] = moduli[region].kappa_pa;
  }
  body.neo_hookean =
      std::all_of(body.mu2_pa.begin(), body.mu2_pa.end(), [](double mu2) { return mu2 == 0.0; });
  body.volumetric = volumetric;
  if (volumetric == VolumetricTerm::kNodalAverage) {
    vertex_tets(body.tets, num_vertices, body.vertex_tet_offsets, body.vertex_tets);
    body.vertex_volume_m3.assign(num_vertices, 0.0);
    body.vertex_bulk_volume_j.assign(num_vertices, 0.0);
    for (std::size_t t = 0; t < num_tets; ++t) {
      for (int a = 0; a < 4; ++a) {
        const std::int32_t v = body.tets[4 * t + a];
        body.vertex_volume_m3[v] += 0.25 * body.ref_volume_m3[t];
        body.vertex_bulk_volume_j[v] += 0.25 * body.kappa_pa[t] * body.ref_volume_m3[t];
      }
    }
  }
  return body;
}

ElasticEvaluation add_elastic_forces(const ElasticBody& body, const double* positions_m, double* forces_n,
                                     int threads) {
  if (body.neo_hookean) return evaluate<false, true>(body, positions_m, forces_n, threads);
  return evaluate<true, true>(body, positions_m, forces_n, threads);
}

ElasticEvaluation add_elastic_forces_of_range(const ElasticBody& body, const double* positions_m,
                                              double* forces_n, std::int64_t begin_tet,
                                              std::int64_t end_tet) {
  std::int64_t first_inverted = kNoTet;
  ElasticEvaluation result;
  // kNodalAverage: the pressures need every tet; the energy is then the
  // range's isochoric part plus the whole volumetric energy.
  std::vector<double> pressure;
  if (body.volumetric == VolumetricTerm::kNodalAverage) {
    result.energy_j = volumetric_pressures(body, positions_m, 1, pressure);
  }
  const double* tet_pressure = pressure.empty() ? nullptr : pressure.data();
  if (body.neo_hookean) {
    result.energy_j += evaluate_range<false, true>(body, positions_m, forces_n, begin_tet, end_tet,
                                                   first_inverted, tet_pressure);
  } else {
    result.energy_j += evaluate_range<true, true>(body, positions_m, forces_n, begin_tet, end_tet,
                                                  first_inverted, tet_pressure);
  }
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m, int threads) {
  if (body.neo_hookean) return evaluate<false, false>(body, positions_m, nullptr, threads);
  return evaluate<true, false>(body, positions_m, nullptr, threads);
}

ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m) {
  return elastic_energy(body, positions_m, 0);
}

VolumeRatioMinimum min_volume_ratio(const ElasticBody& body, const double* positions_m) {
  VolumeRatioMinimum minimum;
  for (std::size_t t = 0; t < body.num_tets(); ++t) {
    const double ratio = deformed_volume(positions_m, body.tets.data() + 4 * t) / body.ref_volume_m3[t];
    if (ratio < minimum.volume_ratio) minimum = {ratio, static_cast<std::int64_t>(t)};
  }
  return minimum;
}

TetColouring colour_tets(std::span<const std::int32_t> tets, std::size_t num_vertices,
                         std::int64_t group_size) {
  const std::int64_t num_tets = static_cast<std::int64_t>(tets.size() / 4);
  group_size = std::max<std::int64_t>(1, group_size);
  const std::int64_t num_groups = (num_tets + group_size - 1) / group_size;
  // Groups around each vertex (CSR, each group once per vertex).
  std::vector<std::int64_t> offsets(num_vertices + 1, 0);
  std::vector<std::int64_t> last_group(num_vertices, -1);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < 4; ++a) {
      const std::int32_t v = tets[4 * t + a];
      if (last_group[v] != t / group_size) {
        last_group[v] = t / group_size;
        ++offsets[v + 1];
      }
    }
  }
  for (std::size_t v = 0; v < num_vertices; ++v) offsets[v + 1] += offsets[v];
  std::vector<std::int32_t> incident(static_cast<std::size_t>(offsets[num_vertices]));
  std::vector<std::int64_t> next(offsets.begin(), offsets.end() - 1);
  std::fill(last_group.begin(), last_group.end(), -1);
  for (std::int64_t t = 0; t < num_tets; ++t) {
    for (int a = 0; a < 4; ++a) {
      const std::int32_t v = tets[4 * t + a];
      if (last_group[v] != t / group_size) {
        last_group[v] = t / group_size;
        incident[next[v]++] = static_cast<std::int32_t>(t / group_size);
      }
    }
  }
  // Greedy: each group takes the lowest colour not used by a group sharing a vertex.
  std::vector<std::int32_t> colour(num_groups, -1);
  std::vector<std::int64_t> blocked_by;  // per colour: the last group it was blocked for
  for (std::int64_t g = 0; g < num_groups; ++g) {
    const std::int64_t end = std::min(num_tets, (g + 1) * group_size);
    for (std::int64_t t = g * group_size; t < end; ++t) {
      for (int a = 0; a < 4; ++a) {
        const std::int32_t v = tets[4 * t + a];
        for (std::int64_t k = offsets[v]; k < offsets[v + 1]; ++k) {
          const std::int32_t other = colour[incident[k]];
          if (other >= 0) blocked_by[other] = g;
        }
      }
    }
    std::size_t c = 0;
    while (c < blocked_by.size() && blocked_by[c] == g) ++c;
    if (c == blocked_by.size()) blocked_by.push_back(-1);
    colour[g] = static_cast<std::int32_t>(c);
  }
  TetColouring result;
  result.group_size = group_size;
  result.offsets.assign(blocked_by.size() + 1, 0);
  for (const std::int32_t c : colour) ++result.offsets[c + 1];
  for (std::size_t c = 0; c < blocked_by.size(); ++c) result.offsets[c + 1] += result.offsets[c];
  result.order.resize(num_groups);
  std::vector<std::int64_t> next_slot(result.offsets.begin(), result.offsets.end() - 1);
  for (std::int64_t g = 0; g < num_groups; ++g)
    result.order[next_slot[colour[g]]++] = static_cast<std::int32_t>(g);
  return result;
}

TangentAssembler::TangentAssembler(const ElasticBody& body) : body_(&body) {
  const std::size_t num_vertices = body.num_vertices;
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  std::vector<std::int64_t> offsets;
  std::vector<std::int32_t> incident;
  vertex_tets(body.tets, num_vertices, offsets, incident);
  // Sorted patch (itself and its neighbours) of every vertex.
  std::vector<std::int64_t> patch_offsets(num_vertices + 1, 0);
  std::vector<std::int32_t> patches;
  std::vector<std::int32_t> seen(num_vertices, -1);
  for (std::size_t v = 0; v < num_vertices; ++v) {
    const std::size_t first = patches.size();
    for (std::int64_t k = offsets[v]; k < offsets[v + 1]; ++k) {
      for (int a = 0; a < 4; ++a) {
        const std::int32_t w = body.tets[4 * static_cast<std::int64_t>(incident[k]) + a];
        if (seen[w] != static_cast<std::int32_t>(v)) {
          seen[w] = static_cast<std::int32_t>(v);
          patches.push_back(w);
        }
      }
    }
    std::sort(patches.begin() + static_cast<std::ptrdiff_t>(first), patches.end());
    patch_offsets[v + 1] = static_cast<std::int64_t>(patches.size());
  }
  // The 3x3 blocks of column v: the patch of v.
  const std::vector<std::int64_t>& neighbour_offsets = patch_offsets;
  const std::vector<std::int32_t>& neighbours = patches;
  // Column 3 v + j holds rows 3 w, 3 w + 1, 3 w + 2 for every neighbour w of v.
  using Index = Eigen::SparseMatrix<double>::StorageIndex;
  const Index size = static_cast<Index>(3 * num_vertices);
  stiffness_.resize(size, size);
  stiffness_.resizeNonZeros(static_cast<Index>(9 * neighbours.size()));
  Index* outer = stiffness_.outerIndexPtr();
  Index* inner = stiffness_.innerIndexPtr();
  Index nonzero = 0;
  for (std::size_t v = 0; v < num_vertices; ++v) {
    for (int j = 0; j < 3; ++j) {
      outer[3 * v + j] = nonzero;
      for (std::int64_t k = neighbour_offsets[v]; k < neighbour_offsets[v + 1]; ++k) {
        for (int i = 0; i < 3; ++i) inner[nonzero++] = static_cast<Index>(3 * neighbours[k] + i);
      }
    }
  }
  outer[size] = nonzero;
  std::fill_n(stiffness_.valuePtr(), nonzero, 0.0);

  slot_.resize(48 * static_cast<std::size_t>(num_tets));
  for (std::int64_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = body.tets.data() + 4 * t;
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        const auto begin = neighbours.begin() + neighbour_offsets[v[b]];
        const auto end = neighbours.begin() + neighbour_offsets[v[b] + 1];
        const std::int64_t rank = std::lower_bound(begin, end, v[a]) - begin;
        for (int j = 0; j < 3; ++j) {
          slot_[3 * (16 * t + 4 * a + b) + j] = outer[3 * static_cast<std::int64_t>(v[b]) + j] + 3 * rank;
        }
      }
    }
  }
  if (body.volumetric == VolumetricTerm::kNodalAverage) {
    patch_offsets_ = patch_offsets;
    patches_ = patches;
    patch_local_.resize(4 * body.vertex_tets.size());
    for (std::size_t a = 0; a < num_vertices; ++a) {
      const auto begin = patches.begin() + patch_offsets[a];
      const auto end = patches.begin() + patch_offsets[a + 1];
      for (std::int64_t k = body.vertex_tet_offsets[a]; k < body.vertex_tet_offsets[a + 1]; ++k) {
        const std::int32_t* v = body.tets.data() + 4 * static_cast<std::int64_t>(body.vertex_tets[k]);
        for (int c = 0; c < 4; ++c)
          patch_local_[4 * k + c] = static_cast<std::int32_t>(std::lower_bound(begin, end, v[c]) - begin);
      }
    }
    mirror_entry_.resize(patches.size());
    for (std::size_t a = 0; a < num_vertices; ++a) {
      for (std::int64_t k = patch_offsets[a]; k < patch_offsets[a + 1]; ++k) {
        const std::int32_t w = patches[k];
        const auto begin = patches.begin() + patch_offsets[w];
        const auto end = patches.begin() + patch_offsets[w + 1];
        mirror_entry_[k] = std::lower_bound(begin, end, static_cast<std::int32_t>(a)) - patches.begin();
      }
    }
    g_rows_.assign(3 * patches.size(), 0.0);
    vertex_coefficient_.assign(num_vertices, 0.0);
    vertex_scratch_.resize(num_vertices);
  }
  // Groups of consecutive tets: few colours (barriers) and streaming access;
  // about 256 groups so that each colour still has work for several threads.
  colouring_ = colour_tets(body.tets, num_vertices, std::clamp<std::int64_t>(num_tets / 256, 8, 512));
}

template <bool kMooneyRivlin>
ElasticEvaluation TangentAssembler::assemble_impl(const double* y, double* forces) {
  const ElasticBody& body = *body_;
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  double* values = stiffness_.valuePtr();
  std::fill_n(values, stiffness_.nonZeros(), 0.0);
  const std::int32_t* tets = body.tets.data();
  const std::int64_t* slots = slot_.data();
  const int team = team_size(threads_, num_tets, kMinTangentTetsPerThread);
  const bool nodal = body.volumetric == VolumetricTerm::kNodalAverage;
  const double volumetric_energy = nodal ? volumetric_pressures(body, y, team, tet_pressure_) : 0.0;
  // Scatter of tet t's energy, forces and 12x12 block.
  auto add_tet = [&](std::int64_t t, double& energy, std::int64_t& first_inverted) {
    const std::int32_t* v = tets + 4 * t;
    const double* yv[4];
    for (int a = 0; a < 4; ++a) yv[a] = y + 3 * static_cast<std::int64_t>(v[a]);
    double f[12];
    double block[144];
    double tet_energy;
    kernel::TetParams params = tet_params(body, t);
    if (nodal) {
      params.kappa_pa = 0.0;
      params.pressure_pa = tet_pressure_[t];
    }
    if (!kernel::tet_tangent<kMooneyRivlin>(params, yv[0], yv[1], yv[2], yv[3], f, block, tet_energy)) {
      first_inverted = std::min(first_inverted, t);
      return;
    }
    energy += tet_energy;
    if (forces != nullptr) {
      for (int a = 0; a < 4; ++a) {
        for (int i = 0; i < 3; ++i) forces[3 * static_cast<std::int64_t>(v[a]) + i] += f[3 * a + i];
      }
    }
    const std::int64_t* tet_slots = slots + 48 * t;
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        for (int j = 0; j < 3; ++j) {
          double* column = values + tet_slots[3 * (4 * a + b) + j];
          for (int i = 0; i < 3; ++i) column[i] += block[12 * (3 * a + i) + 3 * b + j];
        }
      }
    }
  };

  double energy = volumetric_energy;
  std::int64_t first_inverted = kNoTet;
  if (team == 1) {
    for (std::int64_t t = 0; t < num_tets; ++t) add_tet(t, energy, first_inverted);
  } else {
    // Groups of one colour share no vertex: they scatter in parallel without races.
    const std::int32_t* order = colouring_.order.data();
    const std::int64_t* colour_offsets = colouring_.offsets.data();
    const std::int64_t num_colours = static_cast<std::int64_t>(colouring_.num_colours());
    const std::int64_t group_size = colouring_.group_size;
    // Energy per group, summed in group order afterwards: the result does not
    // depend on which thread took which group (the matrix and forces do not
    // either: each entry receives its terms in colour order).
    group_energy_.assign(colouring_.order.size(), 0.0);
    double* group_energy = group_energy_.data();
#pragma omp parallel num_threads(team) reduction(min : first_inverted)
    for (std::int64_t c = 0; c < num_colours; ++c) {
#pragma omp for schedule(dynamic, 1)
      for (std::int64_t k = colour_offsets[c]; k < colour_offsets[c + 1]; ++k) {
        const std::int64_t group = order[k];
        const std::int64_t end = std::min(num_tets, (group + 1) * group_size);
        for (std::int64_t t = group * group_size; t < end; ++t)
          add_tet(t, group_energy[group], first_inverted);
      }
    }
    for (const double e : group_energy_) energy += e;
  }
  if (nodal && first_inverted == kNoTet) update_volumetric_operator(y);
  ElasticEvaluation result;
  result.energy_j = energy;
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

void TangentAssembler::update_volumetric_operator(const double* y) {
  const ElasticBody& body = *body_;
  const std::int32_t* tets = body.tets.data();
  std::fill(g_rows_.begin(), g_rows_.end(), 0.0);
  for (std::size_t a = 0; a < body.num_vertices; ++a) {
    // g_a = sum_{t at a} (1/4) dv_t/dy; with D the deformed edge matrix
    // (columns y_k - y_4), dv_t/dy_i^k = cof(D)_ik / 6 (k = 1..3) and
    // dv_t/dy^4 = -sum_k dv_t/dy^k.
    double* row = g_rows_.data() + 3 * patch_offsets_[a];
    for (std::int64_t k = body.vertex_tet_offsets[a]; k < body.vertex_tet_offsets[a + 1]; ++k) {
      const std::int32_t* v = tets + 4 * static_cast<std::int64_t>(body.vertex_tets[k]);
      const double* y3 = y + 3 * static_cast<std::int64_t>(v[3]);
      double d[9];
      for (int c = 0; c < 3; ++c) {
        const double* yc = y + 3 * static_cast<std::int64_t>(v[c]);
        for (int i = 0; i < 3; ++i) d[3 * i + c] = yc[i] - y3[i];
      }
      const double cof[9] = {d[4] * d[8] - d[5] * d[7], d[5] * d[6] - d[3] * d[8], d[3] * d[7] - d[4] * d[6],
                             d[2] * d[7] - d[1] * d[8], d[0] * d[8] - d[2] * d[6], d[1] * d[6] - d[0] * d[7],
                             d[1] * d[5] - d[2] * d[4], d[2] * d[3] - d[0] * d[5], d[0] * d[4] - d[1] * d[3]};
      const std::int32_t* local = patch_local_.data() + 4 * k;
      constexpr double kScale = 1.0 / 24.0;  // 1/4 (vertex share) x 1/6 (tet volume)
      for (int i = 0; i < 3; ++i) {
        const double h0 = kScale * cof[3 * i], h1 = kScale * cof[3 * i + 1], h2 = kScale * cof[3 * i + 2];
        row[3 * local[0] + i] += h0;
        row[3 * local[1] + i] += h1;
        row[3 * local[2] + i] += h2;
        row[3 * local[3] + i] -= h0 + h1 + h2;
      }
    }
    // C_a = (kappa V)_a / V_a^2: d^2/dv_a^2 of (kappa V)_a / 2 (v_a / V_a - 1)^2
    const double volume = body.vertex_volume_m3[a];
    vertex_coefficient_[a] = volume > 0.0 ? body.vertex_bulk_volume_j[a] / (volume * volume) : 0.0;
  }
}

void TangentAssembler::add_volumetric_product(const double* x, double* out) const {
  if (!has_volumetric_operator()) return;
  const std::int64_t num_vertices = static_cast<std::int64_t>(body_->num_vertices);
  const std::int64_t* offsets = patch_offsets_.data();
  const std::int32_t* patches = patches_.data();
  const double* g = g_rows_.data();
  double* z = vertex_scratch_.data();
  // G^T (C (G x)): two row-wise gathers; the rows of G^T are the entries
  // g_a[b] read through mirror_entry_ (any thread count, same numbers).
  const int team = team_size(threads_, 5 * num_vertices, kMinForceTetsPerThread);
#pragma omp parallel num_threads(team)
  {
#pragma omp for schedule(static)
    for (std::int64_t a = 0; a < num_vertices; ++a) {
      double sum = 0.0;
      for (std::int64_t k = offsets[a]; k < offsets[a + 1]; ++k) {
        const double* xw = x + 3 * static_cast<std::int64_t>(patches[k]);
        sum += g[3 * k] * xw[0] + g[3 * k + 1] * xw[1] + g[3 * k + 2] * xw[2];
      }
      z[a] = vertex_coefficient_[a] * sum;
    }
#pragma omp for schedule(static)
    for (std::int64_t b = 0; b < num_vertices; ++b) {
      double o0 = 0.0, o1 = 0.0, o2 = 0.0;
      for (std::int64_t k = offsets[b]; k < offsets[b + 1]; ++k) {
        const double za = z[patches[k]];
        const double* gab = g + 3 * mirror_entry_[k];  // g_a[b], a = patches[k]
        o0 += za * gab[0];
        o1 += za * gab[1];
        o2 += za * gab[2];
      }
      out[3 * b] += o0;
      out[3 * b + 1] += o1;
      out[3 * b + 2] += o2;
    }
  }
}

void TangentAssembler::add_volumetric_diagonal_blocks(double* blocks) const {
  if (!has_volumetric_operator()) return;
  // block_b = sum_{a in patch of b} C_a g_a[b] g_a[b]^T
  for (std::size_t b = 0; b < body_->num_vertices; ++b) {
    double* block = blocks + 9 * b;
    for (std::int64_t k = patch_offsets_[b]; k < patch_offsets_[b + 1]; ++k) {
      const double c = vertex_coefficient_[patches_[k]];
      const double* gab = g_rows_.data() + 3 * mirror_entry_[k];
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) block[3 * i + j] += c * gab[i] * gab[j];
      }
    }
  }
}

void TangentAssembler::multiply(const double* x, double* out) const {
  const Eigen::Index n = stiffness_.cols();
  Eigen::Map<Eigen::VectorXd>(out, n) = stiffness_ * Eigen::Map<const Eigen::VectorXd>(x, n);
  add_volumetric_product(x, out);
}

ElasticEvaluation TangentAssembler::assemble(const double* positions_m, double* forces_n) {
  if (body_->neo_hookean) return assemble_impl<false>(positions_m, forces_n);
  return assemble_impl<true>(positions_m, forces_n);
}

ElasticEvaluation TangentAssembler::assemble(const double* positions_m) {
  return assemble(positions_m, nullptr);
}

}  // namespace cellflow::elastic
