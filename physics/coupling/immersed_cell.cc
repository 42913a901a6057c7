#include "physics/coupling/immersed_cell.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>

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
  if (span_x <= 0 || span_z <= 0 || j_lo > j_hi) return;
  // The x range as at most two contiguous pieces [i0, i0 + n0) and [0, n1).
  const int i0 = ((box.lo[0] % nx) + nx) % nx;
  const int n0 = std::min(span_x, nx - i0), n1 = span_x - n0;
  int k = ((box.lo[2] % nz) + nz) % nz;
  for (int kk = 0; kk < span_z; ++kk, k = k + 1 == nz ? 0 : k + 1) {
    for (int j = j_lo; j <= j_hi; ++j) {
      const std::size_t row = fluid.node(0, j, k);
      for (const auto [first, count] : {std::pair{i0, n0}, std::pair{0, n1}}) {
        std::fill_n(f.x + row + first, count, T(0));
        std::fill_n(f.y + row + first, count, T(0));
        std::fill_n(f.z + row + first, count, T(0));
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
  const elastic::ElasticEvaluation eval = elastic::add_elastic_forces(
      *cell.body, cell.positions_m.data(), cell.forces_n.data(), threads, cell.elastic_precision);
  // F_lb = F dt^2 / (m dx)
  for (std::size_t i = 0; i < n; ++i) cell.forces_lattice[i] = cell.forces_n[i] * cell.newton_to_lattice;
  return eval;
}

const std::vector<elastic::ElasticEvaluation>& compute_elastic_forces(ImmersedCells& cells, int threads) {
  std::vector<elastic::ElasticEvaluation>& evaluations = cells.workspace.evaluations;
  evaluations.resize(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) evaluations[i] = compute_elastic_forces(cells[i], threads);
  return evaluations;
}

namespace {

// The points a cell couples at: its vertices, or its markers (placed here)
// where marker_scale != 1.
const std::vector<double>& coupled_points(ImmersedCell& cell) {
  if (!scaled_markers(cell)) return cell.positions_lattice;
  place_markers(cell);
  return cell.markers_lattice;
}

// F(x) = g(x) sum_p (f_p sum_y w_p(y) / sum_y w_p(y) g(y)) w_p(x), g the
// weight of the node's phase (ImmersedCells::phase_spread_weights), sums over
// the stencil's nodes in the fluid. g depends on the node only, so this is
// the plain (parallel) spread of the renormalised forces, then each node of
// a weighted phase scaled by its g: the nodes inside a cell lie within the
// supports just zeroed and spread, so nothing else in the field is scaled.
template <class T>
void spread_phase_weighted(ImmersedCells& cells, lb::Fluid& fluid, int width, int threads) {
  CouplingWorkspace& ws = cells.workspace;
  const std::span<const std::uint8_t> phases = fluid.phases();
  const std::vector<double>& weight_of_phase = cells.phase_spread_weights;
  auto weight = [&](std::uint8_t phase) {
    return phase < weight_of_phase.size() ? weight_of_phase[phase] : 1.0;
  };
  ws.renormalised_forces.resize(ws.forces.size());
  for (std::size_t p = 0; p < ws.stencils.points.size(); ++p) {
    const ibm::PointStencil& st = ws.stencils.points[p];
    double mass = 0.0, weighted = 0.0;
    if (st.finite) {
      for (int c = 0; c < width; ++c) {
        for (int b = st.y_begin; b < st.y_end; ++b) {
          for (int a = 0; a < width; ++a) {
            const double w = st.wx[a] * st.wy[b] * st.wz[c];
            mass += w;
            weighted += w * weight(phases[fluid.node(st.x[a], st.y[b], st.z[c])]);
          }
        }
      }
    }
    const double norm = weighted > 0.0 ? mass / weighted : 0.0;
    for (int d = 0; d < 3; ++d) ws.renormalised_forces[3 * p + d] = norm * ws.forces[3 * p + d];
  }
  lb::VectorField<T> field = fluid.force_field<T>();
  ibm::spread<T>(ws.stencils, ws.renormalised_forces, field, threads);
  for (std::size_t node = 0; node < phases.size(); ++node) {
    if (phases[node] == 0) continue;
    const T g = static_cast<T>(weight(phases[node]));
    field.x[node] *= g;
    field.y[node] *= g;
    field.z[node] *= g;
  }
}

// Zeroes the union of the previous supports, then spreads the points of all
// cells in one pass.
template <class T>
void spread_all(ImmersedCells& cells, lb::Fluid& fluid, ibm::Kernel kernel, int threads) {
  const ibm::Grid grid = ibm::grid_of(fluid);
  const int width = ibm::kernel_width(kernel);
  CouplingWorkspace& ws = cells.workspace;
  for (const ImmersedCell& cell : cells.cells) zero_force_box<T>(fluid, cell.last_support);
  std::size_t total = 0;
  for (const ImmersedCell& cell : cells.cells) total += cell.positions_lattice.size();
  ws.points.resize(total);
  ws.forces.resize(total);
  std::size_t at = 0;
  for (ImmersedCell& cell : cells.cells) {
    const std::vector<double>& points = coupled_points(cell);
    const std::size_t n = points.size();
    std::copy(points.begin(), points.end(), ws.points.begin() + static_cast<std::ptrdiff_t>(at));
    if (scaled_markers(cell)) {
      // F_m = F / s at X_m = c + s (X - c): the same first moment sum F (X - c).
      for (std::size_t i = 0; i < n; ++i) ws.forces[at + i] = cell.forces_lattice[i] / cell.marker_scale;
    } else {
      std::copy(cell.forces_lattice.begin(), cell.forces_lattice.end(),
                ws.forces.begin() + static_cast<std::ptrdiff_t>(at));
    }
    cell.last_support = support_of(points, width);
    at += n;
  }
  ibm::build_stencils(kernel, grid, ws.points, ws.stencils, threads);
  ws.stencils_valid = true;
  if (!cells.phase_spread_weights.empty() && !fluid.phases().empty()) {
    spread_phase_weighted<T>(cells, fluid, width, threads);
  } else {
    ibm::spread<T>(ws.stencils, ws.forces, fluid.force_field<T>(), threads);
  }
}

// After the velocities of the coupled points are in cell.velocities_lattice:
// undo the marker scaling, move the vertices (X += U dt) and report.
AdvectReport move_cell(ImmersedCell& cell) {
  if (scaled_markers(cell)) {
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

template <class T>
void interpolate_all(ImmersedCells& cells, const lb::Fluid& fluid, ibm::Kernel kernel, int threads) {
  CouplingWorkspace& ws = cells.workspace;
  const ibm::Grid grid = ibm::grid_of(fluid);
  std::size_t total = 0;
  for (const ImmersedCell& cell : cells.cells) total += cell.positions_lattice.size();
  ws.query.resize(total);
  std::size_t at = 0;
  for (ImmersedCell& cell : cells.cells) {
    const std::vector<double>& points = coupled_points(cell);
    std::copy(points.begin(), points.end(), ws.query.begin() + static_cast<std::ptrdiff_t>(at));
    at += points.size();
  }
  const ibm::Grid& built = ws.stencils.grid;
  const bool reuse = ws.stencils_valid && ws.stencils.kernel == kernel && built.nx == grid.nx &&
                     built.ny == grid.ny && built.nz == grid.nz && built.walls_y == grid.walls_y &&
                     ws.query == ws.points;
  if (!reuse) {
    ibm::build_stencils(kernel, grid, ws.query, ws.stencils, threads);
    ws.points = ws.query;
    ws.stencils_valid = true;
  }
  ws.velocities.resize(total);
  ibm::interpolate<T>(ws.stencils, fluid.velocity_field<T>(), ws.velocities, threads);
  at = 0;
  for (ImmersedCell& cell : cells.cells) {
    const std::size_t n = cell.velocities_lattice.size();
    std::copy_n(ws.velocities.begin() + static_cast<std::ptrdiff_t>(at), n, cell.velocities_lattice.begin());
    at += n;
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
  const std::vector<double>& at = coupled_points(cell);
  if (fluid.params().precision == lb::Precision::kFloat) {
    ibm::interpolate<float>(kernel, grid, fluid.velocity_field<float>(), at, cell.velocities_lattice,
                            threads);
  } else {
    ibm::interpolate<double>(kernel, grid, fluid.velocity_field<double>(), at, cell.velocities_lattice,
                             threads);
  }
  return move_cell(cell);
}

// U_p = sum_x u(x) delta_h(x - X_p);  X_p += U_p dt   (interpolation, paper section 7)
const std::vector<AdvectReport>& advect_cells(ImmersedCells& cells, const lb::Fluid& fluid,
                                              ibm::Kernel kernel, int threads) {
  if (fluid.params().precision == lb::Precision::kFloat) {
    interpolate_all<float>(cells, fluid, kernel, threads);
  } else {
    interpolate_all<double>(cells, fluid, kernel, threads);
  }
  std::vector<AdvectReport>& reports = cells.workspace.reports;
  reports.resize(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) reports[i] = move_cell(cells[i]);
  return reports;
}

// x = X dx
std::vector<double> box_positions_m(const ImmersedCell& cell) {
  std::vector<double> out(cell.positions_lattice.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = cell.positions_lattice[i] * cell.spacing_m;
  return out;
}

}  // namespace cellflow::coupling
