// Inside/outside marking of lattice nodes for N immersed cells (viscosity
// contrast, paper section 7: lambda = eta_in / eta_out per cell). Every node
// of the lattice gets the index of the cell whose closed surface encloses it,
// or -1 (the suspending fluid); lb::Fluid then relaxes each node with the
// relaxation time of its phase (FluidParams::phase_taus, set_phases).
//
// Two tests (lattice units, node (i, j, k) at (i + 1/2, j + 1/2, k + 1/2)):
//  - exact: the generalised winding number of the cell's surface triangles
//    around the node, sum of signed solid angles / 4 pi (van Oosterom and
//    Strackee 1983), inside when > 1/2. Robust for any closed, consistently
//    oriented surface, also for nodes on a vertex's ray.
//  - fast (update_marking): a node changes side only where the surface swept
//    through it, so only the nodes within the cell's largest vertex
//    displacement since its last marking (a thin shell around the surface)
//    are re-marked, by the sign of (x - q) . n with q the nearest surface
//    point and n the normal of its triangle (Lehmann et al. 2020); when q
//    lies on an edge or vertex, where that sign is ambiguous, the exact test
//    decides. A triangle is skipped for a node whose distance to its plane
//    exceeds the best so far. All other nodes keep their mark. When a cell
//    moved farther than `band_lattice` the update falls back to the full
//    marking of that cell, and every `full_every_updates`-th update is a full
//    one anyway (0: never).
//  - full (make_marking, the fallback): the same marks as the winding number
//    at every node of the cell's bounding box, with the winding number
//    evaluated only once per connected region of nodes farther than 1/2
//    from the surface (they share it) and the sign test near the surface.
//  The sign test equals the winding number for a closed, consistently
//  oriented surface that does not intersect itself (tests/marking compares
//  both with the winding number at every node).
//
// Periodic in x and z (and y when the fluid is): vertex positions may lie
// outside [0, n) before the wrap, as coupling keeps them; a cell must be
// smaller than the box. Cells must not overlap (a node inside two keeps the
// later one's index).
//
// Use (a suspension with per-cell lambda):
//   MarkingParams mp;                       // band, full-check period
//   auto marking = make_marking(cells, fluid, mp);   // exact marking of all cells (fluid: its size, walls)
//   std::vector<std::uint8_t> phase_of_cell = ...;   // cell c relaxes with phase_taus[phase_of_cell[c] - 1]
//   apply_phases(*marking, phase_of_cell, fluid);   // a Status
//   every marking_every_steps steps, after advect_cells:
//     update_marking(*marking, cells); apply_phases(*marking, phase_of_cell, fluid);
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "physics/core/status.h"
#include "physics/coupling/immersed_cell.h"
#include "physics/lb/fluid.h"

namespace cellflow::marking {

struct MarkingParams {
  // The largest vertex displacement since a cell's last marking that the
  // fast update handles (lattice units, in [0.5, 8]); a cell that moved
  // farther is marked in full. The fast update's cost grows with the actual
  // displacement, not with this bound. Also widens the periodic-box check.
  double band_lattice = 1.0;
  // Every n-th update_marking is the exact test of every cell; 0: only the
  // fallback when a cell moved beyond the band. In [0, 1e9].
  int full_every_updates = 0;
};

// Field names relative to the params ("band_lattice").
Status validate(const MarkingParams& params);

// Counters of the work done, for tests and benchmarks.
struct MarkingStats {
  std::int64_t updates = 0;        // update_marking calls
  std::int64_t full_markings = 0;  // exact markings of a whole cell (make_marking counts each cell)
  std::int64_t band_nodes = 0;     // nodes re-marked by the fast update (the shell swept by the surface)
  std::int64_t exact_node_tests =
      0;                 // winding-number evaluations (far regions of full markings, ambiguous nodes)
  double seconds = 0.0;  // wall time in make_marking / update_marking / apply_phases
};

class NodeMarking {
 public:
  int nx() const { return nx_; }
  int ny() const { return ny_; }
  int nz() const { return nz_; }
  // Per node (element i + nx (j + ny k)): the cell index enclosing it, or -1.
  std::span<const std::int32_t> owner() const { return owner_; }
  // Nodes marked inside cell c (its volume in lattice units cubed).
  std::size_t count_inside(int cell) const;
  const MarkingStats& stats() const { return stats_; }
  const MarkingParams& params() const { return params_; }
  // A resumed run sets the update count it stopped at, so that the periodic
  // full check falls on the same updates as in the uninterrupted run.
  void set_update_count(std::int64_t updates) { stats_.updates = updates; }

 private:
  friend StatusOr<NodeMarking> make_marking(const coupling::ImmersedCells& cells, const lb::Fluid& fluid,
                                            const MarkingParams& params);
  friend void update_marking(NodeMarking& marking, const coupling::ImmersedCells& cells);
  friend void mark_cell_exact(NodeMarking& marking, const coupling::ImmersedCells& cells, std::size_t c);
  friend void mark_cell_exact_untimed(NodeMarking& marking, const coupling::ImmersedCells& cells,
                                      std::size_t c);
  friend Status apply_phases(NodeMarking& marking, std::span<const std::uint8_t> phase_of_cell,
                             lb::Fluid& fluid);
  int nx_ = 0, ny_ = 0, nz_ = 0;
  bool periodic_y_ = false;
  MarkingParams params_;
  std::vector<std::int32_t> owner_;
  // Per cell: vertex positions at its last marking (for the displacement
  // check) and its surface triangles (3 vertex indices each, outward).
  std::vector<std::vector<double>> marked_positions_;
  std::vector<std::vector<std::int32_t>> triangles_;
  MarkingStats stats_;
  // Scratch of the fast update (kept between calls: no allocation per step):
  // the nodes near one cell's surface with their best distance and side, and
  // per lattice node its index in near_ (-1 when not near).
  struct NearNode {
    int ijk[3];        // unwrapped node indices
    std::size_t node;  // wrapped lattice index
    double distance;   // to the nearest surface triangle found so far
    std::int8_t side;  // +1 outside, -1 inside, 0 ambiguous (the exact test decides)
  };
  std::vector<NearNode> near_;
  std::vector<std::int32_t> near_slot_;
  // Re-marks every node within `pad` of cell c's current surface by the
  // nearest-triangle sign test (the exact test where that is ambiguous).
  void remark_near_surface(const coupling::ImmersedCell& cell, std::size_t c, double pad);
  // Fills near_ (and near_slot_) with the nodes within `pad` of cell c's
  // surface and their sides; the caller clears near_slot_ again.
  void collect_near_surface(const coupling::ImmersedCell& cell, std::size_t c, double pad);
  // The exact marking of cell c (winding number), see marking.cc.
  void mark_cell_full(const coupling::ImmersedCell& cell, std::size_t c);
  std::vector<std::uint8_t> far_mark_;  // scratch of mark_cell_full, one cell's box
  std::vector<std::uint8_t> phases_;    // scratch of apply_phases, one per node
};

// Exact marking of every cell on the fluid's lattice (its size; periodic in
// y unless it has walls). kInvalidArgument for bad params, a cell without
// surface triangles, or a cell (plus twice the band) wider than the box.
StatusOr<NodeMarking> make_marking(const coupling::ImmersedCells& cells, const lb::Fluid& fluid,
                                   const MarkingParams& params);

// The fast update of every cell after its vertices moved (see above).
// The cells must be those of make_marking, in the same order.
void update_marking(NodeMarking& marking, const coupling::ImmersedCells& cells);

// (Internal: mark_cell_exact without the timing.)
void mark_cell_exact_untimed(NodeMarking& marking, const coupling::ImmersedCells& cells, std::size_t c);

// Full re-marking of cell c: its old marks are cleared, every node of its
// bounding box gets the winding-number mark (see above).
void mark_cell_exact(NodeMarking& marking, const coupling::ImmersedCells& cells, std::size_t c);

// Exact test of one point (lattice units, box coordinates; the periodic
// image nearest the cell's centroid is not searched: pass the point as it
// lies relative to the vertex positions). Generalised winding number > 1/2.
bool inside_exact(const coupling::ImmersedCell& cell, std::span<const std::int32_t> triangles,
                  const double p[3]);

// Outward surface triangles of a cell's mesh (3 indices each).
std::vector<std::int32_t> surface_triangles(const coupling::ImmersedCell& cell);

// Writes the lattice phases: node n gets 0 where owner < 0, else
// phase_of_cell[owner[n]] (0 = the fluid's own tau; p >= 1 relaxes with
// FluidParams::phase_taus[p - 1]). The fluid must have been made with
// phase_taus (a phase field) and the same size; the errors of lb::set_phases
// otherwise (a phase above phase_taus.size()).
Status apply_phases(NodeMarking& marking, std::span<const std::uint8_t> phase_of_cell, lb::Fluid& fluid);

}  // namespace cellflow::marking
