// Inside/outside marking of lattice nodes (see marking.h): the exact
// winding-number test, the full marking, the update of the nodes the surface
// swept by the sign of the distance to the nearest surface triangle, and the
// phase field written into the fluid.
#include "physics/marking/marking.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "physics/contact/surface_triangles.h"
#include "physics/contact/triangle_distance.h"

namespace cellflow::marking {

namespace {

constexpr double kPi = 3.14159265358979323846;
// Band nodes closer than this to the surface (lattice units) are decided by
// the exact test: there the sign of a rounded distance is not trusted.
constexpr double kAmbiguousDistance = 1e-6;
// Added to the largest vertex displacement when choosing the nodes to
// re-mark (lattice units; positions are O(100), their rounding O(1e-14)).
constexpr double kDisplacementSlack = 1e-9;
// Nodes at least this far from the surface (lattice units) share the mark of
// a far neighbour in the full marking (see mark_cell_full).
constexpr double kFarDistance = 0.5;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int wrap_index(int i, int n) {
  const int r = i % n;
  return r < 0 ? r + n : r;
}

struct Bounds {
  double lo[3], hi[3];
};

Bounds vertex_bounds(const std::vector<double>& x) {
  Bounds b{};
  for (int d = 0; d < 3; ++d) {
    b.lo[d] = std::numeric_limits<double>::infinity();
    b.hi[d] = -std::numeric_limits<double>::infinity();
  }
  for (std::size_t i = 0; i + 2 < x.size(); i += 3) {
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = std::min(b.lo[d], x[i + d]);
      b.hi[d] = std::max(b.hi[d], x[i + d]);
    }
  }
  return b;
}

// Unwrapped node indices whose centre i + 1/2 lies in [lo - pad, hi + pad].
void node_range(double lo, double hi, double pad, int& first, int& last) {
  first = static_cast<int>(std::ceil(lo - pad - 0.5));
  last = static_cast<int>(std::floor(hi + pad - 0.5));
}

// Signed solid angle of triangle (a, b, c) seen from p (van Oosterom and
// Strackee 1983): tan(Omega / 2) = A.(B x C) / (|A||B||C| + (A.B)|C| + (A.C)|B| + (B.C)|A|).
double solid_angle(const double* a, const double* b, const double* c, const double* p) {
  const double A[3] = {a[0] - p[0], a[1] - p[1], a[2] - p[2]};
  const double B[3] = {b[0] - p[0], b[1] - p[1], b[2] - p[2]};
  const double C[3] = {c[0] - p[0], c[1] - p[1], c[2] - p[2]};
  const double la = std::sqrt(A[0] * A[0] + A[1] * A[1] + A[2] * A[2]);
  const double lb = std::sqrt(B[0] * B[0] + B[1] * B[1] + B[2] * B[2]);
  const double lc = std::sqrt(C[0] * C[0] + C[1] * C[1] + C[2] * C[2]);
  const double det = A[0] * (B[1] * C[2] - B[2] * C[1]) - A[1] * (B[0] * C[2] - B[2] * C[0]) +
                     A[2] * (B[0] * C[1] - B[1] * C[0]);
  const double ab = A[0] * B[0] + A[1] * B[1] + A[2] * B[2];
  const double ac = A[0] * C[0] + A[1] * C[1] + A[2] * C[2];
  const double bc = B[0] * C[0] + B[1] * C[1] + B[2] * C[2];
  return 2.0 * std::atan2(det, la * lb * lc + ab * lc + ac * lb + bc * la);
}

// Marks (or unmarks) the node of unwrapped index (i, j, k) for `cell`; a
// node outside leaves another cell's mark alone.
void set_owner(std::vector<std::int32_t>& owner, int i, int j, int k, int nx, int ny, int nz,
               std::int32_t cell, bool inside) {
  const std::size_t n = static_cast<std::size_t>(wrap_index(i, nx)) +
                        static_cast<std::size_t>(nx) * (static_cast<std::size_t>(wrap_index(j, ny)) +
                                                        static_cast<std::size_t>(ny) * wrap_index(k, nz));
  if (inside)
    owner[n] = cell;
  else if (owner[n] == cell)
    owner[n] = -1;
}

}  // namespace

Status validate(const MarkingParams& p) {
  if (!(p.band_lattice >= 0.5 && p.band_lattice <= 8.0)) {
    return invalid_argument("band_lattice = " + std::to_string(p.band_lattice) + " must lie in [0.5, 8]");
  }
  if (p.full_every_updates < 0 || p.full_every_updates > 1000000000) {
    return invalid_argument("full_every_updates = " + std::to_string(p.full_every_updates) +
                            " must lie in [0, 1e9]");
  }
  return Status::ok_status();
}

std::size_t NodeMarking::count_inside(int cell) const {
  return static_cast<std::size_t>(std::count(owner_.begin(), owner_.end(), cell));
}

std::vector<std::int32_t> surface_triangles(const coupling::ImmersedCell& cell) {
  if (cell.mesh == nullptr) return {};
  return contact::boundary_triangles(cell.mesh->tets, cell.mesh->positions_m.data());
}

// Generalised winding number w = sum Omega_t / (4 pi); inside when w > 1/2.
bool inside_exact(const coupling::ImmersedCell& cell, std::span<const std::int32_t> triangles,
                  const double p[3]) {
  const double* x = cell.positions_lattice.data();
  double omega = 0.0;
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    omega += solid_angle(x + 3 * static_cast<std::size_t>(triangles[t]),
                         x + 3 * static_cast<std::size_t>(triangles[t + 1]),
                         x + 3 * static_cast<std::size_t>(triangles[t + 2]), p);
  }
  return omega > 2.0 * kPi;
}

void mark_cell_exact(NodeMarking& m, const coupling::ImmersedCells& cells, std::size_t c) {
  const auto t0 = std::chrono::steady_clock::now();
  mark_cell_exact_untimed(m, cells, c);
  m.stats_.seconds += seconds_since(t0);
}

void mark_cell_exact_untimed(NodeMarking& m, const coupling::ImmersedCells& cells, std::size_t c) {
  m.mark_cell_full(cells[c], c);
}

// The marks of the winding-number test without evaluating it at every node:
// the nodes within kFarDistance of the surface get theirs as in the fast
// update (sign test, winding number where ambiguous). Two neighbouring nodes
// both farther than that lie in one ball free of surface (every point of the
// segment between them is within 1/2 of one end), so they share their
// winding number; a far node takes the mark of a far neighbour already
// decided (i-1, j-1 or k-1), and the winding number is evaluated once for
// each region of far nodes so connected.
void NodeMarking::mark_cell_full(const coupling::ImmersedCell& cell, std::size_t c) {
  const std::int32_t id = static_cast<std::int32_t>(c);
  for (std::int32_t& o : owner_)
    if (o == id) o = -1;
  const Bounds b = vertex_bounds(cell.positions_lattice);
  int first[3], last[3];
  for (int d = 0; d < 3; ++d) node_range(b.lo[d], b.hi[d], 0.0, first[d], last[d]);
  if (!periodic_y_) {
    first[1] = std::max(first[1], 0);
    last[1] = std::min(last[1], ny_ - 1);
  }
  collect_near_surface(cell, c, kFarDistance + kDisplacementSlack);
  const int bx = last[0] - first[0] + 1, by = last[1] - first[1] + 1, bz = last[2] - first[2] + 1;
  const std::span<const std::int32_t> tris = triangles_[c];
  std::int64_t tests = 0;
  if (bx > 0 && by > 0 && bz > 0) {
    // Per box node: 0 outside, 1 inside (far nodes decided), 2 not decided or near.
    far_mark_.assign(static_cast<std::size_t>(bx) * by * static_cast<std::size_t>(bz), 2);
    for (int k = first[2]; k <= last[2]; ++k) {
      const std::size_t wk = static_cast<std::size_t>(wrap_index(k, nz_));
      for (int j = first[1]; j <= last[1]; ++j) {
        const std::size_t wjk =
            static_cast<std::size_t>(nx_) * (static_cast<std::size_t>(wrap_index(j, ny_)) + ny_ * wk);
        const std::size_t row =
            static_cast<std::size_t>(bx) *
            (static_cast<std::size_t>(j - first[1]) + static_cast<std::size_t>(by) * (k - first[2]));
        for (int i = first[0]; i <= last[0]; ++i) {
          const std::size_t node = static_cast<std::size_t>(wrap_index(i, nx_)) + wjk;
          const std::int32_t at = near_slot_[node];
          bool inside;
          if (at >= 0) {
            inside = near_[static_cast<std::size_t>(at)].side < 0;
          } else {
            const std::size_t here = row + static_cast<std::size_t>(i - first[0]);
            std::uint8_t mark = 2;
            if (i > first[0]) mark = far_mark_[here - 1];
            if (mark == 2 && j > first[1]) mark = far_mark_[here - static_cast<std::size_t>(bx)];
            if (mark == 2 && k > first[2]) mark = far_mark_[here - static_cast<std::size_t>(bx) * by];
            if (mark == 2) {
              const double p[3] = {i + 0.5, j + 0.5, k + 0.5};
              mark = inside_exact(cell, tris, p) ? 1 : 0;
              ++tests;
            }
            far_mark_[here] = mark;
            inside = mark == 1;
          }
          if (inside) owner_[node] = id;
        }
      }
    }
  }
  for (const NearNode& nn : near_) near_slot_[nn.node] = -1;
  marked_positions_[c] = cell.positions_lattice;
  stats_.full_markings += 1;
  stats_.exact_node_tests += tests;
}

StatusOr<NodeMarking> make_marking(const coupling::ImmersedCells& cells, const lb::Fluid& fluid,
                                   const MarkingParams& params) {
  if (Status s = validate(params); !s.ok()) return invalid_argument("marking: " + s.message());
  NodeMarking m;
  m.nx_ = fluid.nx();
  m.ny_ = fluid.ny();
  m.nz_ = fluid.nz();
  m.periodic_y_ = !fluid.params().walls_y;
  m.params_ = params;
  m.owner_.assign(fluid.num_nodes(), -1);
  const int n[3] = {m.nx_, m.ny_, m.nz_};
  for (std::size_t c = 0; c < cells.size(); ++c) {
    std::vector<std::int32_t> tris = surface_triangles(cells[c]);
    if (tris.empty() || cells[c].positions_lattice.size() != 3 * cells[c].mesh->num_vertices()) {
      return invalid_argument("marking: cell " + std::to_string(c) + " has no surface triangles");
    }
    const Bounds b = vertex_bounds(cells[c].positions_lattice);
    for (int d = 0; d < 3; ++d) {
      if (!std::isfinite(b.lo[d]) || !std::isfinite(b.hi[d])) {
        return invalid_argument("marking: cell " + std::to_string(c) + " has non-finite positions");
      }
      const bool periodic = d != 1 || m.periodic_y_;
      // A periodic image of the band must not reach the cell's other side.
      if (periodic && b.hi[d] - b.lo[d] + 2.0 * params.band_lattice + 2.0 >= n[d]) {
        return invalid_argument("marking: cell " + std::to_string(c) + " is wider than the box along axis " +
                                std::to_string(d));
      }
    }
    m.triangles_.push_back(std::move(tris));
    m.marked_positions_.emplace_back();
  }
  for (std::size_t c = 0; c < cells.size(); ++c) mark_cell_exact(m, cells, c);
  return m;
}

void NodeMarking::collect_near_surface(const coupling::ImmersedCell& cell, std::size_t c, double pad) {
  NodeMarking& m = *this;
  if (m.near_slot_.size() != m.owner_.size()) m.near_slot_.assign(m.owner_.size(), -1);
  const std::vector<double>& x = cell.positions_lattice;
  const std::vector<std::int32_t>& tris = m.triangles_[c];
  std::vector<NearNode>& near = m.near_;
  std::vector<std::int32_t>& slot = m.near_slot_;
  near.clear();
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
    double p[9];
    for (int v = 0; v < 3; ++v)
      for (int d = 0; d < 3; ++d) p[3 * v + d] = x[3 * static_cast<std::size_t>(tris[t + v]) + d];
    const double e1[3] = {p[3] - p[0], p[4] - p[1], p[5] - p[2]};
    const double e2[3] = {p[6] - p[0], p[7] - p[1], p[8] - p[2]};
    const double normal[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                              e1[0] * e2[1] - e1[1] * e2[0]};
    const double area2 = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    // The distance to the triangle's plane bounds the distance to the
    // triangle from below: a node whose plane distance exceeds its best
    // distance so far (by more than rounding) cannot take this triangle.
    const double inv_area2 = area2 > 0.0 ? 1.0 / area2 : 0.0;
    int lo[3], hi[3];
    for (int d = 0; d < 3; ++d) {
      const double tlo = std::min({p[d], p[3 + d], p[6 + d]}), thi = std::max({p[d], p[3 + d], p[6 + d]});
      node_range(tlo, thi, pad, lo[d], hi[d]);
    }
    if (!m.periodic_y_) {
      lo[1] = std::max(lo[1], 0);
      hi[1] = std::min(hi[1], m.ny_ - 1);
    }
    for (int k = lo[2]; k <= hi[2]; ++k) {
      const std::size_t wk = static_cast<std::size_t>(wrap_index(k, m.nz_));
      for (int j = lo[1]; j <= hi[1]; ++j) {
        const std::size_t wjk =
            static_cast<std::size_t>(m.nx_) * (static_cast<std::size_t>(wrap_index(j, m.ny_)) + m.ny_ * wk);
        for (int i = lo[0]; i <= hi[0]; ++i) {
          const double q[3] = {i + 0.5, j + 0.5, k + 0.5};
          const std::size_t node = static_cast<std::size_t>(wrap_index(i, m.nx_)) + wjk;
          const std::int32_t at = slot[node];
          const double best = at < 0 ? pad : near[static_cast<std::size_t>(at)].distance;
          if (area2 > 0.0) {
            const double plane =
                std::abs((q[0] - p[0]) * normal[0] + (q[1] - p[1]) * normal[1] + (q[2] - p[2]) * normal[2]) *
                inv_area2;
            if (plane - 1e-9 >= best) continue;
          }
          const contact::TriangleDistance td = contact::triangle_distance(q, p);
          if (!(td.distance_m < best)) continue;
          std::int8_t side;
          if (td.feature != contact::ClosestFeature::kFace || td.distance_m < kAmbiguousDistance) {
            side = 0;
          } else {
            const double s = td.normal[0] * normal[0] + td.normal[1] * normal[1] + td.normal[2] * normal[2];
            side = s > 0.0 ? 1 : -1;
          }
          if (at < 0) {
            slot[node] = static_cast<std::int32_t>(near.size());
            near.push_back({{i, j, k}, node, td.distance_m, side});
          } else {
            near[static_cast<std::size_t>(at)].distance = td.distance_m;
            near[static_cast<std::size_t>(at)].side = side;
          }
        }
      }
    }
  }
  // The side of every near node: the sign test, or the exact test where it is ambiguous.
  for (NearNode& nn : near) {
    if (nn.side == 0) {
      const double q[3] = {nn.ijk[0] + 0.5, nn.ijk[1] + 0.5, nn.ijk[2] + 0.5};
      nn.side = inside_exact(cell, tris, q) ? -1 : 1;
      m.stats_.exact_node_tests += 1;
    }
  }
}

void NodeMarking::remark_near_surface(const coupling::ImmersedCell& cell, std::size_t c, double pad) {
  collect_near_surface(cell, c, pad);
  const std::int32_t id = static_cast<std::int32_t>(c);
  for (const NearNode& nn : near_) {
    near_slot_[nn.node] = -1;
    if (nn.side < 0)
      owner_[nn.node] = id;
    else if (owner_[nn.node] == id)
      owner_[nn.node] = -1;
  }
  stats_.band_nodes += static_cast<std::int64_t>(near_.size());
}

void update_marking(NodeMarking& m, const coupling::ImmersedCells& cells) {
  const auto t0 = std::chrono::steady_clock::now();
  m.stats_.updates += 1;
  const bool all_full =
      m.params_.full_every_updates > 0 && m.stats_.updates % m.params_.full_every_updates == 0;
  const double band = m.params_.band_lattice;
  for (std::size_t c = 0; c < cells.size(); ++c) {
    const coupling::ImmersedCell& cell = cells[c];
    const std::vector<double>& x = cell.positions_lattice;
    std::vector<double>& x0 = m.marked_positions_[c];
    // Every point of a triangle moves by at most its vertices' largest
    // displacement (it is their convex combination). Along the straight
    // motion from the marked to the current positions the mark of a node
    // changes only where the surface passes through it, so a node that
    // changed side lies within that displacement of the current surface.
    double max_move2 = 0.0;
    for (std::size_t i = 0; i + 2 < x.size(); i += 3) {
      const double dx = x[i] - x0[i], dy = x[i + 1] - x0[i + 1], dz = x[i + 2] - x0[i + 2];
      max_move2 = std::max(max_move2, dx * dx + dy * dy + dz * dz);
    }
    if (all_full || !(max_move2 < band * band)) {
      mark_cell_exact_untimed(m, cells, c);
      continue;
    }
    if (max_move2 == 0.0) continue;  // nothing moved: every mark holds
    // The slack covers the rounding of the distances (lattice units).
    m.remark_near_surface(cell, c, std::sqrt(max_move2) + kDisplacementSlack);
    std::copy(x.begin(), x.end(), x0.begin());
  }
  m.stats_.seconds += seconds_since(t0);
}

Status apply_phases(NodeMarking& m, std::span<const std::uint8_t> phase_of_cell, lb::Fluid& fluid) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::uint8_t>& phases = m.phases_;
  phases.assign(m.owner_.size(), 0);
  for (std::size_t n = 0; n < m.owner_.size(); ++n) {
    const std::int32_t o = m.owner_[n];
    if (o >= 0 && static_cast<std::size_t>(o) < phase_of_cell.size()) phases[n] = phase_of_cell[o];
  }
  Status s = lb::set_phases(fluid, phases);
  m.stats_.seconds += seconds_since(t0);
  return s;
}

}  // namespace cellflow::marking
