// TangentAssembler: the sparsity pattern of the tangent stiffness K and the
// slot of every tet block in it, the colouring of the tet groups
// (physics/mesh/tet_colouring.h), the assembly of K with the energy and
// forces (serial, or colour by colour in parallel), and the applied
// nodal-averaged volumetric part G^T C G with its diagonal blocks.
#include <Eigen/SparseCore>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/elastic/elastic_internal.h"
#include "physics/elastic/tet_kernel.h"
#include "physics/mesh/tet_colouring.h"

namespace cellflow::elastic {

namespace {

using detail::kMinForceTetsPerThread;
using detail::kMinTangentTetsPerThread;
using detail::kNoTet;
using detail::team_size;
using detail::vertex_tets;
using detail::volumetric_pressures;

kernel::TetParams tet_params(const ElasticBody& body, std::int64_t t) {
  return {body.b_matrix.data() + 9 * t, body.ref_volume_m3[t], body.mu1_pa[t], body.mu2_pa[t],
          body.kappa_pa[t]};
}

}  // namespace

TangentAssembler::TangentAssembler(const ElasticBody& body) : body_(&body) {
  const std::size_t num_vertices = body.num_vertices;
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  // The element's nodes: 4 per tet, or 10 for the quadratic tet.
  const int npe = body.quadratic() ? 10 : 4;
  const std::vector<std::int32_t>& elements = body.quadratic() ? body.quadratic_tets : body.tets;
  std::vector<std::int64_t> offsets;
  std::vector<std::int32_t> incident;
  vertex_tets(elements, num_vertices, offsets, incident, npe);
  // Sorted patch (itself and its neighbours) of every vertex.
  std::vector<std::int64_t> patch_offsets(num_vertices + 1, 0);
  std::vector<std::int32_t> patches;
  std::vector<std::int32_t> seen(num_vertices, -1);
  for (std::size_t v = 0; v < num_vertices; ++v) {
    const std::size_t first = patches.size();
    for (std::int64_t k = offsets[v]; k < offsets[v + 1]; ++k) {
      for (int a = 0; a < npe; ++a) {
        const std::int32_t w = elements[npe * static_cast<std::int64_t>(incident[k]) + a];
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

  slot_.resize(3 * npe * npe * static_cast<std::size_t>(num_tets));
  for (std::int64_t t = 0; t < num_tets; ++t) {
    const std::int32_t* v = elements.data() + npe * t;
    for (int a = 0; a < npe; ++a) {
      for (int b = 0; b < npe; ++b) {
        const auto begin = neighbours.begin() + neighbour_offsets[v[b]];
        const auto end = neighbours.begin() + neighbour_offsets[v[b] + 1];
        const std::int64_t rank = std::lower_bound(begin, end, v[a]) - begin;
        for (int j = 0; j < 3; ++j) {
          slot_[3 * (npe * npe * t + npe * a + b) + j] =
              outer[3 * static_cast<std::int64_t>(v[b]) + j] + 3 * rank;
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
    g_columns_.assign(3 * patches.size(), 0.0);
    vertex_coefficient_.assign(num_vertices, 0.0);
    vertex_scratch_.resize(num_vertices);
  }
  // The quadratic tet is assembled serially: no colouring.
  if (body.quadratic()) return;
  // Groups of consecutive tets: few colours (barriers) and streaming access;
  // about 256 groups so that each colour still has work for several threads.
  colouring_ = mesh::colour_tets(body.tets, num_vertices, std::clamp<std::int64_t>(num_tets / 256, 8, 512));
}

template <bool kMooneyRivlin>
ElasticEvaluation TangentAssembler::assemble_impl(const double* y, double* forces) {
  const ElasticBody& body = *body_;
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  double* values = stiffness_.valuePtr();
  const std::int64_t num_values = stiffness_.nonZeros();
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
    std::fill_n(values, num_values, 0.0);
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
    {
#pragma omp for schedule(static)
      for (std::int64_t s = 0; s < num_values; ++s) values[s] = 0.0;
      for (std::int64_t c = 0; c < num_colours; ++c) {
#pragma omp for schedule(dynamic, 1)
        for (std::int64_t k = colour_offsets[c]; k < colour_offsets[c + 1]; ++k) {
          const std::int64_t group = order[k];
          const std::int64_t end = std::min(num_tets, (group + 1) * group_size);
          for (std::int64_t t = group * group_size; t < end; ++t)
            add_tet(t, group_energy[group], first_inverted);
        }
      }
    }
    for (const double e : group_energy_) energy += e;
  }
  if (nodal && first_inverted == kNoTet) update_volumetric_operator(y, team);
  ElasticEvaluation result;
  result.energy_j = energy;
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

void TangentAssembler::update_volumetric_operator(const double* y, int team) {
  const ElasticBody& body = *body_;
  const std::int32_t* tets = body.tets.data();
  const std::int64_t num_vertices = static_cast<std::int64_t>(body.num_vertices);
  const std::int64_t num_entries = static_cast<std::int64_t>(patches_.size());
  // Row a is written by the thread of a alone; G^T is copied once every row is done.
#pragma omp parallel num_threads(team)
  {
#pragma omp for schedule(static)
    for (std::int64_t a = 0; a < num_vertices; ++a) {
      double* row = g_rows_.data() + 3 * patch_offsets_[a];
      std::fill(row, g_rows_.data() + 3 * patch_offsets_[a + 1], 0.0);
      // g_a = sum_{t at a} (1/4) dv_t/dy; with D the deformed edge matrix
      // (columns y_k - y_4), dv_t/dy_i^k = cof(D)_ik / 6 (k = 1..3) and
      // dv_t/dy^4 = -sum_k dv_t/dy^k.
      for (std::int64_t k = body.vertex_tet_offsets[a]; k < body.vertex_tet_offsets[a + 1]; ++k) {
        const std::int32_t* v = tets + 4 * static_cast<std::int64_t>(body.vertex_tets[k]);
        const double* y3 = y + 3 * static_cast<std::int64_t>(v[3]);
        double d[9];
        for (int c = 0; c < 3; ++c) {
          const double* yc = y + 3 * static_cast<std::int64_t>(v[c]);
          for (int i = 0; i < 3; ++i) d[3 * i + c] = yc[i] - y3[i];
        }
        const double cof[9] = {
            d[4] * d[8] - d[5] * d[7], d[5] * d[6] - d[3] * d[8], d[3] * d[7] - d[4] * d[6],
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
#pragma omp for schedule(static)
    for (std::int64_t k = 0; k < num_entries; ++k) {
      const double* gab = g_rows_.data() + 3 * mirror_entry_[k];
      for (int i = 0; i < 3; ++i) g_columns_[3 * k + i] = gab[i];
    }
  }
}

void TangentAssembler::volumetric_gather(const double* x, std::int64_t begin, std::int64_t end,
                                         double* z) const {
  const std::int64_t* offsets = patch_offsets_.data();
  const std::int32_t* patches = patches_.data();
  const double* g = g_rows_.data();
  for (std::int64_t a = begin; a < end; ++a) {
    double sum = 0.0;
    for (std::int64_t k = offsets[a]; k < offsets[a + 1]; ++k) {
      const double* xw = x + 3 * static_cast<std::int64_t>(patches[k]);
      sum += g[3 * k] * xw[0] + g[3 * k + 1] * xw[1] + g[3 * k + 2] * xw[2];
    }
    z[a] = vertex_coefficient_[a] * sum;
  }
}

void TangentAssembler::add_volumetric_scatter(const double* z, std::int64_t begin, std::int64_t end,
                                              double* out) const {
  const std::int64_t* offsets = patch_offsets_.data();
  const std::int32_t* patches = patches_.data();
  const double* gt = g_columns_.data();
  for (std::int64_t b = begin; b < end; ++b) {
    double o0 = 0.0, o1 = 0.0, o2 = 0.0;
    for (std::int64_t k = offsets[b]; k < offsets[b + 1]; ++k) {
      const double za = z[patches[k]];
      o0 += za * gt[3 * k];  // g_a[b], a = patches[k]
      o1 += za * gt[3 * k + 1];
      o2 += za * gt[3 * k + 2];
    }
    out[3 * b] += o0;
    out[3 * b + 1] += o1;
    out[3 * b + 2] += o2;
  }
}

void TangentAssembler::add_volumetric_product(const double* x, double* out) const {
  if (!has_volumetric_operator()) return;
  const std::int64_t num_vertices = static_cast<std::int64_t>(body_->num_vertices);
  double* z = vertex_scratch_.data();
  // G^T (C (G x)): two row-wise passes, the second over the stored rows of
  // G^T (any thread count, same numbers).
  const int team = team_size(threads_, 5 * num_vertices, kMinForceTetsPerThread);
  if (team == 1) {
    volumetric_gather(x, 0, num_vertices, z);
    add_volumetric_scatter(z, 0, num_vertices, out);
    return;
  }
#pragma omp parallel num_threads(team)
  {
    const std::int64_t rank = omp_get_thread_num(), size = omp_get_num_threads();
    const std::int64_t begin = num_vertices * rank / size, end = num_vertices * (rank + 1) / size;
    volumetric_gather(x, begin, end, z);
#pragma omp barrier
    add_volumetric_scatter(z, begin, end, out);
  }
}

void TangentAssembler::add_volumetric_diagonal_blocks(double* blocks) const {
  if (!has_volumetric_operator()) return;
  // block_b = sum_{a in patch of b} C_a g_a[b] g_a[b]^T
  const std::int64_t num_vertices = static_cast<std::int64_t>(body_->num_vertices);
  const int team = team_size(threads_, 5 * num_vertices, kMinForceTetsPerThread);
#pragma omp parallel for num_threads(team) schedule(static)
  for (std::int64_t b = 0; b < num_vertices; ++b) {
    double* block = blocks + 9 * b;
    for (std::int64_t k = patch_offsets_[b]; k < patch_offsets_[b + 1]; ++k) {
      const double c = vertex_coefficient_[patches_[k]];
      const double* gab = g_columns_.data() + 3 * k;  // g_a[b], a = patches_[k]
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
  if (body_->quadratic()) {
    if (body_->neo_hookean) return assemble_quadratic<false>(positions_m, forces_n);
    return assemble_quadratic<true>(positions_m, forces_n);
  }
  if (body_->neo_hookean) return assemble_impl<false>(positions_m, forces_n);
  return assemble_impl<true>(positions_m, forces_n);
}

ElasticEvaluation TangentAssembler::assemble(const double* positions_m) {
  return assemble(positions_m, nullptr);
}

}  // namespace cellflow::elastic
