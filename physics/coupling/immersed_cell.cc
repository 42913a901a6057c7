#include "physics/coupling/immersed_cell.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace cellflow::coupling {

namespace {

// Nodes a spread of the points can touch: the bounding box widened by the
// kernel width (a generous bound on the stencil reach).
NodeBox support_of(const std::vector<double>& points, int width) {
  NodeBox box;
  const std::size_t n = points.size() / 3;
  if (n == 0) return box;
  double lo[3] = {points[0], points[1], points[2]};
  double hi[3] = {points[0], points[1], points[2]};
  for (std::size_t p = 1; p < n; ++p) {
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], points[3 * p + d]);
      hi[d] = std::max(hi[d], points[3 * p + d]);
    }
  }
  for (int d = 0; d < 3; ++d) {
    if (!std::isfinite(lo[d]) || !std::isfinite(hi[d])) return NodeBox{};
    box.lo[d] = static_cast<int>(std::floor(lo[d])) - width;
    box.hi[d] = static_cast<int>(std::ceil(hi[d])) + width;
  }
  return box;
}

// Zeroes the force field on `box` (x and z wrapped periodically, y clipped).
template <class T>
void zero_force_box(lb::Fluid& fluid, const NodeBox& box) {
  lb::VectorField<T> f = fluid.force_field<T>();
  const int nx = fluid.nx(), ny = fluid.ny(), nz = fluid.nz();
  const int span_x = std::min(box.hi[0] - box.lo[0] + 1, nx);
  const int span_z = std::min(box.hi[2] - box.lo[2] + 1, nz);
  const int j_lo = std::max(box.lo[1], 0), j_hi = std::min(box.hi[1], ny - 1);
  for (int kk = 0; kk < span_z; ++kk) {
    const int k = ((box.lo[2] + kk) % nz + nz) % nz;
    for (int j = j_lo; j <= j_hi; ++j) {
      for (int ii = 0; ii < span_x; ++ii) {
        const int i = ((box.lo[0] + ii) % nx + nx) % nx;
        const std::size_t node = fluid.node(i, j, k);
        f.x[node] = T(0);
        f.y[node] = T(0);
        f.z[node] = T(0);
      }
    }
  }
}

// X_m = c + s (X - c), c the vertex centroid; returns c.
std::array<double, 3> place_markers(ImmersedCell& cell) {
  const std::size_t nv = cell.positions_lattice.size() / 3;
  std::array<double, 3> c{0.0, 0.0, 0.0};
  for (std::size_t v = 0; v < nv; ++v) {
    for (int d = 0; d < 3; ++d) c[d] += cell.positions_lattice[3 * v + d];
  }
  for (int d = 0; d < 3; ++d) c[d] /= static_cast<double>(std::max<std::size_t>(nv, 1));
  cell.markers_lattice.resize(cell.positions_lattice.size());
  const double s = cell.marker_scale;
  for (std::size_t i = 0; i < cell.positions_lattice.size(); ++i) {
    cell.markers_lattice[i] = c[i % 3] + s * (cell.positions_lattice[i] - c[i % 3]);
  }
  return c;
}

bool scaled_markers(const ImmersedCell& cell) {
  return cell.marker_scale != 1.0;
}

}  // namespace

// X = origin + x / dx
ImmersedCell make_immersed_cell(const mesh::TetMesh& mesh, const elastic::ElasticBody& body,
                                const units::Units& units, const double origin_lattice[3]) {
  ImmersedCell cell;
  cell.mesh = &mesh;
  cell.body = &body;
  const std::size_t n = 3 * mesh.num_vertices();
  cell.spacing_m = units.dx_m();
  cell.newton_to_lattice = units.force_to_lattice(1.0);
  for (int d = 0; d < 3; ++d) cell.origin_lattice[d] = origin_lattice[d];
  cell.positions_lattice.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    cell.positions_lattice[i] = origin_lattice[i % 3] + units.length_to_lattice(mesh.positions_m[i]);
  }
  cell.forces_lattice.assign(n, 0.0);
  cell.velocities_lattice.assign(n, 0.0);
  cell.positions_m.assign(n, 0.0);
  cell.forces_n.assign(n, 0.0);
  return cell;
}

ImmersedCell& add_cell(ImmersedCells& cells, const mesh::TetMesh& mesh, const elastic::ElasticBody& body,
                       const units::Units& units, const double origin_lattice[3]) {
  cells.cells.push_back(make_immersed_cell(mesh, body, units, origin_lattice));
  return cells.cells.back();
}

// f = -dW/dx   (paper eq. 9-10)
elastic::ElasticEvaluation compute_elastic_forces(ImmersedCell& cell, int threads) {
  const std::size_t n = cell.positions_lattice.size();
  const double dx = cell.spacing_m;
  for (std::size_t i = 0; i < n; ++i) {
    // x_SI = (X - origin) dx
    cell.positions_m[i] = (cell.positions_lattice[i] - cell.origin_lattice[i % 3]) * dx;
  }
  std::fill(cell.forces_n.begin(), cell.forces_n.end(), 0.0);
  const elastic::ElasticEvaluation eval =
      elastic::add_elastic_forces(*cell.body, cell.positions_m.data(), cell.forces_n.data(), threads);
  // F_lb = F dt^2 / (m dx)
  for (std::size_t i = 0; i < n; ++i) cell.forces_lattice[i] = cell.forces_n[i] * cell.newton_to_lattice;
  return eval;
}

std::vector<elastic::ElasticEvaluation> compute_elastic_forces(ImmersedCells& cells, int threads) {
  std::vector<elastic::ElasticEvaluation> evaluations;
  evaluations.reserve(cells.size());
  for (ImmersedCell& cell : cells.cells) evaluations.push_back(compute_elastic_forces(cell, threads));
  return evaluations;
}

namespace {

// Zeroes the union of the previous supports, then spreads each cell in order.
template <class T>
void spread_all(ImmersedCells& cells, lb::Fluid& fluid, ibm::Kernel kernel, int threads) {
  const ibm::Grid grid = ibm::grid_of(fluid);
  const int width = ibm::kernel_width(kernel);
  for (const ImmersedCell& cell : cells.cells) zero_force_box<T>(fluid, cell.last_support);
  for (ImmersedCell& cell : cells.cells) {
    if (scaled_markers(cell)) {
      // F_m = F / s at X_m = c + s (X - c): the same first moment sum F (X - c).
      place_markers(cell);
      cell.marker_forces.resize(cell.forces_lattice.size());
      for (std::size_t i = 0; i < cell.forces_lattice.size(); ++i) {
        cell.marker_forces[i] = cell.forces_lattice[i] / cell.marker_scale;
      }
      cell.last_support = support_of(cell.markers_lattice, width);
      ibm::spread<T>(kernel, grid, cell.markers_lattice, cell.marker_forces, fluid.force_field<T>(), threads);
      continue;
    }
    cell.last_support = support_of(cell.positions_lattice, width);
    ibm::spread<T>(kernel, grid, cell.positions_lattice, cell.forces_lattice, fluid.force_field<T>(),
                   threads);
  }
}

}  // namespace

// F(x) = sum_cells sum_p f_p delta_h(x - X_p)   (spreading, paper section 7)
void spread_forces(ImmersedCells& cells, lb::Fluid& fluid, ibm::Kernel kernel, int threads) {
  if (fluid.params().precision == lb::Precision::kFloat) {
    spread_all<float>(cells, fluid, kernel, threads);
  } else {
    spread_all<double>(cells, fluid, kernel, threads);
  }
}

// U_p = sum_x u(x) delta_h(x - X_p);  X_p += U_p dt   (interpolation, paper section 7)
AdvectReport advect_cell(ImmersedCell& cell, const lb::Fluid& fluid, ibm::Kernel kernel, int threads) {
  const ibm::Grid grid = ibm::grid_of(fluid);
  const bool scaled = scaled_markers(cell);
  if (scaled) place_markers(cell);
  const std::vector<double>& at = scaled ? cell.markers_lattice : cell.positions_lattice;
  if (fluid.params().precision == lb::Precision::kFloat) {
    ibm::interpolate<float>(kernel, grid, fluid.velocity_field<float>(), at, cell.velocities_lattice,
                            threads);
  } else {
    ibm::interpolate<double>(kernel, grid, fluid.velocity_field<double>(), at, cell.velocities_lattice,
                             threads);
  }
  if (scaled) {
    // U = U_c + (U_m - U_c) / s, U_c the mean marker velocity.
    const std::size_t nv = cell.velocities_lattice.size() / 3;
    double uc[3] = {0.0, 0.0, 0.0};
    for (std::size_t v = 0; v < nv; ++v) {
      for (int d = 0; d < 3; ++d) uc[d] += cell.velocities_lattice[3 * v + d];
    }
    for (int d = 0; d < 3; ++d) uc[d] /= static_cast<double>(std::max<std::size_t>(nv, 1));
    const double inv = 1.0 / cell.marker_scale;
    for (std::size_t i = 0; i < cell.velocities_lattice.size(); ++i) {
      cell.velocities_lattice[i] = uc[i % 3] + (cell.velocities_lattice[i] - uc[i % 3]) * inv;
    }
  }
  AdvectReport report;
  for (int d = 0; d < 3; ++d) {
    report.lo[d] = std::numeric_limits<double>::max();
    report.hi[d] = -std::numeric_limits<double>::max();
  }
  double max_speed_sq = 0.0;
  bool finite = true;
  const std::size_t nv = cell.positions_lattice.size() / 3;
  for (std::size_t v = 0; v < nv; ++v) {
    double speed_sq = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double u = cell.velocities_lattice[3 * v + d];
      speed_sq += u * u;
      // X += U dt, dt = 1
      double& x = cell.positions_lattice[3 * v + d];
      x += u;
      report.lo[d] = std::min(report.lo[d], x);
      report.hi[d] = std::max(report.hi[d], x);
    }
    finite = finite && std::isfinite(speed_sq);
    max_speed_sq = std::max(max_speed_sq, speed_sq);
  }
  report.max_speed_lattice = finite ? std::sqrt(max_speed_sq) : std::numeric_limits<double>::quiet_NaN();
  return report;
}

std::vector<AdvectReport> advect_cells(ImmersedCells& cells, const lb::Fluid& fluid, ibm::Kernel kernel,
                                       int threads) {
  std::vector<AdvectReport> reports;
  reports.reserve(cells.size());
  for (ImmersedCell& cell : cells.cells) reports.push_back(advect_cell(cell, fluid, kernel, threads));
  return reports;
}

// x = X dx
std::vector<double> box_positions_m(const ImmersedCell& cell) {
  std::vector<double> out(cell.positions_lattice.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = cell.positions_lattice[i] * cell.spacing_m;
  return out;
}

}  // namespace cellflow::coupling
