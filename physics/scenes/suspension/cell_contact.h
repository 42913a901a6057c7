// Short-range repulsion between the surface vertices of different cells and
// between surface vertices and the walls (issue 15, item 2), in lattice units.
//
// Force law, for a gap d below the range r_c (d the vertex-vertex distance,
// or the distance of a vertex from the wall plane):
//   E(d) = F0 r_c / 3 (1 - d / r_c)^3,   F(d) = -dE/dd = F0 (1 - d / r_c)^2,
// zero beyond r_c, and F = F0 (E continued linearly) at a negative gap (a
// vertex past a wall plane). F0 is the force at zero gap: the force and its first
// derivative vanish at r_c (no impulse when a pair enters the range), and the
// force grows quadratically to F0 as the gap closes. The pair force acts
// along the line between the two vertices, equal and opposite (momentum
// conserved: the spread forces of a pair cancel in the fluid's total
// momentum); the wall force along the wall normal.
//
// Search: a Verlet list. The surface vertices of all cells are binned into a
// cell list of bins at least r_c + skin wide over the box (periodic in x and
// z; counting sort, linear in the vertex count), and each vertex looks at the
// 27 bins around its own for vertices of other cells within r_c + skin. The
// list is kept until a vertex has moved more than skin / 2 since it was
// built (then every pair now within r_c is still in it); in between, a call
// costs a pass over the vertices and the listed pairs. Both grow linearly
// with the number of vertices at a fixed density. skin = 0 rebuilds at every
// call.
#pragma once

#include <cstddef>
#include <span>
#include <utility>
#include <vector>

namespace cellflow::contact_repulsion {

struct RepulsionParams {
  double range = 1.0;         // r_c, lattice spacings, > 0
  double strength = 0.0;      // F0, lattice force units, >= 0
  double box[3] = {0, 0, 0};  // periodic lengths in x and z, wall distance H in y (lattice units)
  // The wall planes the gap is measured from: y = wall_offset and y = H - wall_offset.
  double wall_offset = 0.0;
  bool walls = true;
  // Verlet skin (lattice units, >= 0): pairs within range + skin are listed;
  // the list is rebuilt when a vertex moved more than skin / 2. Below 0 (or
  // NaN) counts as 0.
  double skin = 0.5;
};

// The force magnitude F(d) and energy E(d) of the law above (0 beyond range).
double repulsion_force(double gap, double range, double strength);
double repulsion_energy(double gap, double range, double strength);

// One cell's vertex state: positions and forces (3 per vertex, interleaved,
// lattice units; forces are added to) and the vertices that take part.
struct ContactCell {
  const double* positions = nullptr;
  double* forces = nullptr;
  std::span<const int> surface_vertices;
};

struct RepulsionReport {
  int contact_pairs = 0;  // cell pairs with at least one vertex pair in range
  int vertex_pairs = 0;   // vertex pairs in range
  int wall_vertices = 0;  // vertices within range of a wall
  double energy = 0.0;    // total repulsion energy (lattice units)
  double min_gap =
      0.0;  // smallest vertex-vertex distance between different cells seen in range (range if none)
};

// Adds the repulsion forces to every cell's forces. Keeps its bins and the
// pair list between calls (no allocation after the first at a fixed vertex
// count, except when the list grows). A change of the cells or of their
// surface vertex lists rebuilds the list.
class RepulsionSearch {
 public:
  explicit RepulsionSearch(const RepulsionParams& params);
  RepulsionReport add_forces(std::span<const ContactCell> cells);
  const RepulsionParams& params() const { return params_; }
  // The next add_forces rebuilds the list (benchmarks of the search itself).
  void invalidate() { valid_ = false; }
  // How many times the list was built.
  long long builds() const { return builds_; }
  // Checkpoints: the positions (as given, 3 per listed vertex in the cells'
  // order) at which the list was last built, and the list rebuilt from them
  // for these cells (the same pairs in the same order as the list that was
  // built there, so a resumed run sums the forces in the same order); the
  // build count is set to `builds`. false (nothing changed): the positions
  // do not fit the cells' surface vertices.
  const std::vector<double>& built_positions() const { return built_at_; }
  bool restore(std::span<const ContactCell> cells, std::span<const double> built_at, long long builds);

 private:
  void build_list();
  RepulsionParams params_;
  int bins_[3] = {1, 1, 1};
  double bin_size_[3] = {1, 1, 1};
  std::vector<int> bin_start_;            // counting sort offsets, bins + 1
  std::vector<int> bin_of_;               // per flattened vertex
  std::vector<int> fill_;                 // counting sort cursors
  std::vector<int> sorted_;               // flattened vertex indices in bin order
  std::vector<int> cell_of_, vertex_of_;  // (cell, vertex) of each flattened vertex, input order
  std::vector<double> wrapped_;           // wrapped positions, 3 per flattened vertex
  std::vector<double> built_at_;          // positions (as given) at the last build
  std::vector<int> pair_start_;           // per flattened vertex i: its listed j > i, CSR
  std::vector<int> pair_j_;
  std::vector<std::pair<int, int>> pairs_;  // touching cell pairs of one call
  bool valid_ = false;
  long long builds_ = 0;
};

}  // namespace cellflow::contact_repulsion
