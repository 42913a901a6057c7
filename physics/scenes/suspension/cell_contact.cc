// Cell-list search and repulsion forces between cells and with the walls (see
// cell_contact.h).
#include "physics/scenes/suspension/cell_contact.h"

#include <algorithm>
#include <cmath>

namespace cellflow::contact_repulsion {

double repulsion_force(double gap, double range, double strength) {
  if (gap >= range) return 0.0;
  const double s = 1.0 - std::max(gap, 0.0) / range;
  return strength * s * s;  // F = F0 (1 - d / r_c)^2
}

double repulsion_energy(double gap, double range, double strength) {
  if (gap >= range) return 0.0;
  if (gap < 0.0) return strength * (range / 3.0 - gap);  // continued linearly: F = F0 below zero gap
  const double s = 1.0 - gap / range;
  return strength * range / 3.0 * s * s * s;  // E = F0 r_c / 3 (1 - d / r_c)^3
}

RepulsionSearch::RepulsionSearch(const RepulsionParams& params) : params_(params) {
  if (!(params_.skin >= 0.0)) params_.skin = 0.0;  // also NaN
  const double cutoff = params_.range + params_.skin;
  for (int d = 0; d < 3; ++d) {
    bins_[d] = std::max(1, static_cast<int>(std::floor(params_.box[d] / cutoff)));
    bin_size_[d] = params_.box[d] / bins_[d];
  }
}

// The pairs (i, j > i) of vertices of different cells within range + skin,
// from the wrapped positions (cell list, counting sort).
void RepulsionSearch::build_list() {
  const double cutoff = params_.range + params_.skin;
  const double lx = params_.box[0], lz = params_.box[2];
  const std::size_t n = cell_of_.size();
  bin_of_.resize(n);
  const int nbins = bins_[0] * bins_[1] * bins_[2];
  bin_start_.assign(static_cast<std::size_t>(nbins) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    int b[3];
    for (int d = 0; d < 3; ++d)
      b[d] = std::clamp(static_cast<int>(std::floor(wrapped_[3 * i + d] / bin_size_[d])), 0, bins_[d] - 1);
    const int bin = b[0] + bins_[0] * (b[1] + bins_[1] * b[2]);
    bin_of_[i] = bin;
    bin_start_[bin + 1]++;
  }
  for (int b = 0; b < nbins; ++b) bin_start_[b + 1] += bin_start_[b];
  sorted_.resize(n);
  fill_.assign(bin_start_.begin(), bin_start_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) sorted_[fill_[bin_of_[i]]++] = static_cast<int>(i);
  pair_start_.resize(n + 1);
  pair_j_.clear();
  int neighbour_bins[27];
  const bool distinct = bins_[0] >= 3 && bins_[2] >= 3;
  for (std::size_t i = 0; i < n; ++i) {
    pair_start_[i] = static_cast<int>(pair_j_.size());
    const int ci = cell_of_[i];
    const double* xi = &wrapped_[3 * i];
    const int bin = bin_of_[i];
    const int b[3] = {bin % bins_[0], (bin / bins_[0]) % bins_[1], bin / (bins_[0] * bins_[1])};
    int count = 0;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int by = b[1] + dy;
          if (by < 0 || by >= bins_[1]) continue;
          const int bx = (b[0] + dx + bins_[0]) % bins_[0];
          const int bz = (b[2] + dz + bins_[2]) % bins_[2];
          const int nb = bx + bins_[0] * (by + bins_[1] * bz);
          // Fewer than 3 bins along x or z: the wrap visits a bin twice.
          if (distinct || std::find(neighbour_bins, neighbour_bins + count, nb) == neighbour_bins + count) {
            neighbour_bins[count++] = nb;
          }
        }
      }
    }
    for (int k = 0; k < count; ++k) {
      const int nb = neighbour_bins[k];
      for (int s = bin_start_[nb]; s < bin_start_[nb + 1]; ++s) {
        const int j = sorted_[s];
        if (j <= static_cast<int>(i) || cell_of_[j] == ci) continue;
        const double* xj = &wrapped_[3 * j];
        double r[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
        if (r[0] > 0.5 * lx) r[0] -= lx;
        if (r[0] < -0.5 * lx) r[0] += lx;
        if (r[2] > 0.5 * lz) r[2] -= lz;
        if (r[2] < -0.5 * lz) r[2] += lz;
        if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] < cutoff * cutoff) pair_j_.push_back(j);
      }
    }
  }
  pair_start_[n] = static_cast<int>(pair_j_.size());
  valid_ = true;
  ++builds_;
}

bool RepulsionSearch::restore(std::span<const ContactCell> cells, std::span<const double> built_at,
                              long long builds) {
  std::size_t n = 0;
  for (const ContactCell& cell : cells) n += cell.surface_vertices.size();
  if (built_at.size() != 3 * n) return false;
  const double lx = params_.box[0], lz = params_.box[2];
  cell_of_.resize(n);
  vertex_of_.resize(n);
  std::size_t i = 0;
  for (std::size_t c = 0; c < cells.size(); ++c) {
    for (int v : cells[c].surface_vertices) {
      cell_of_[i] = static_cast<int>(c);
      vertex_of_[i] = v;
      ++i;
    }
  }
  // The wrapping of add_forces, applied to the build positions.
  wrapped_.resize(3 * n);
  built_at_.assign(built_at.begin(), built_at.end());
  for (std::size_t k = 0; k < n; ++k) {
    const double* x = &built_at_[3 * k];
    wrapped_[3 * k] = x[0] - lx * std::floor(x[0] / lx);
    wrapped_[3 * k + 1] = x[1];
    wrapped_[3 * k + 2] = x[2] - lz * std::floor(x[2] / lz);
  }
  build_list();
  builds_ = builds;
  return true;
}

RepulsionReport RepulsionSearch::add_forces(std::span<const ContactCell> cells) {
  RepulsionReport report;
  report.min_gap = params_.range;
  const double rc = params_.range, f0 = params_.strength;
  const double lx = params_.box[0], ly = params_.box[1], lz = params_.box[2];
  // The flattened vertices; a different layout invalidates the list.
  std::size_t n = 0;
  for (const ContactCell& cell : cells) n += cell.surface_vertices.size();
  if (n != cell_of_.size()) {
    cell_of_.resize(n);
    vertex_of_.resize(n);
    valid_ = false;
  }
  {
    std::size_t i = 0;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      for (int v : cells[c].surface_vertices) {
        if (cell_of_[i] != static_cast<int>(c) || vertex_of_[i] != v) {
          cell_of_[i] = static_cast<int>(c);
          vertex_of_[i] = v;
          valid_ = false;
        }
        ++i;
      }
    }
  }
  // Wrapped positions (x and z into [0, L); y stays) and the largest
  // displacement since the list was built.
  wrapped_.resize(3 * n);
  built_at_.resize(3 * n);
  const double half_skin = 0.5 * params_.skin;
  double max_move2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double* x = cells[cell_of_[i]].positions + 3 * vertex_of_[i];
    wrapped_[3 * i] = x[0] - lx * std::floor(x[0] / lx);
    wrapped_[3 * i + 1] = x[1];
    wrapped_[3 * i + 2] = x[2] - lz * std::floor(x[2] / lz);
    const double* x0 = &built_at_[3 * i];
    const double d[3] = {x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]};
    max_move2 = std::max(max_move2, d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  }
  // A pair now within r_c was within r_c + skin at the build when neither
  // vertex moved more than skin / 2 since.
  if (!valid_ || !(max_move2 <= half_skin * half_skin) || params_.skin <= 0.0) {
    build_list();
    for (std::size_t i = 0; i < n; ++i) {
      const double* x = cells[cell_of_[i]].positions + 3 * vertex_of_[i];
      for (int d = 0; d < 3; ++d) built_at_[3 * i + d] = x[d];
    }
  }
  pairs_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const int ci = cell_of_[i];
    const double* xi = &wrapped_[3 * i];
    double* fi = cells[ci].forces + 3 * vertex_of_[i];
    for (int s = pair_start_[i]; s < pair_start_[i + 1]; ++s) {
      const int j = pair_j_[s];
      const double* xj = &wrapped_[3 * j];
      double r[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
      // Minimum image (both positions wrapped into [0, L), so |r| < L).
      if (r[0] > 0.5 * lx) r[0] -= lx;
      if (r[0] < -0.5 * lx) r[0] += lx;
      if (r[2] > 0.5 * lz) r[2] -= lz;
      if (r[2] < -0.5 * lz) r[2] += lz;
      const double d2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
      if (d2 >= rc * rc) continue;
      const int cj = cell_of_[j];
      const double d = std::sqrt(d2);
      report.vertex_pairs++;
      report.min_gap = std::min(report.min_gap, d);
      report.energy += repulsion_energy(d, rc, f0);
      pairs_.emplace_back(std::min(ci, cj), std::max(ci, cj));
      if (d <= 0.0) continue;  // coincident: no direction (measure zero)
      const double f = repulsion_force(d, rc, f0) / d;
      double* fj = cells[cj].forces + 3 * vertex_of_[j];
      for (int a = 0; a < 3; ++a) {
        fi[a] += f * r[a];
        fj[a] -= f * r[a];
      }
    }
    if (params_.walls) {
      // Gaps to the lower and upper wall planes.
      const double lo = xi[1] - params_.wall_offset, hi = ly - params_.wall_offset - xi[1];
      if (lo < rc) {
        fi[1] += repulsion_force(lo, rc, f0);
        report.energy += repulsion_energy(lo, rc, f0);
        report.wall_vertices++;
      }
      if (hi < rc) {
        fi[1] -= repulsion_force(hi, rc, f0);
        report.energy += repulsion_energy(hi, rc, f0);
        report.wall_vertices++;
      }
    }
  }
  std::sort(pairs_.begin(), pairs_.end());
  report.contact_pairs = static_cast<int>(std::unique(pairs_.begin(), pairs_.end()) - pairs_.begin());
  return report;
}

}  // namespace cellflow::contact_repulsion
