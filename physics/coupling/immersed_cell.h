// The immersed-boundary coupling of N tetrahedral cells to a lattice-
// Boltzmann fluid (paper section 7; several cells as in section 7.3, which
// interact only through the fluid here): the building blocks of one time step of
// the flow scenes, exposed so that tests and benchmarks exercise the same code.
//
// One time step (lattice units, dt = 1), for every cell of an ImmersedCells:
//   compute_elastic_forces   f = elastic forces at the vertices   (paper eq. 9-10)
//   spread_forces            force field = sum_cells sum_p f_p delta(x - X_p)   (Guo forcing in the LB step)
//   lb::collide_stream       u(t) written into the velocity field
//   advect_cells             U_p = sum_x u(x) delta(x - X_p);  X_p += U_p
// For one cell the arithmetic is that of the single-cell coupling it replaces.
#pragma once

#include <cstddef>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/ibm/ibm.h"
#include "physics/lb/fluid.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/units/units.h"

namespace cellflow::coupling {

// Lattice nodes [lo, hi] (inclusive, before periodic wrap) per direction.
struct NodeBox {
  int lo[3] = {0, 0, 0};
  int hi[3] = {-1, -1, -1};  // hi < lo: empty
};

// One immersed cell: its mesh and body (not owned; they must outlive it) and
// its interpolation/spreading state.
struct ImmersedCell {
  const mesh::TetMesh* mesh = nullptr;
  const elastic::ElasticBody* body = nullptr;
  // Vertex state, 3 per vertex, interleaved.
  std::vector<double> positions_lattice;   // box coordinates, lattice units
  std::vector<double> forces_lattice;      // elastic forces of the last compute_elastic_forces
  std::vector<double> velocities_lattice;  // fluid velocity of the last advect
  // SI scratch for the elastic law: positions relative to `origin_lattice`
  // (keeps the deformation gradient free of the box offset's round-off).
  std::vector<double> positions_m;
  std::vector<double> forces_n;
  double origin_lattice[3] = {0, 0, 0};
  // Immersed-boundary markers at c + s (X - c), c the vertex centroid, s this
  // scale in (0, 1]; forces F / s are spread there and the vertices move
  // with U_c + (U_marker - U_c) / s, U_c the mean marker velocity. The first
  // moment of the spread forces (the stresslet) and the power F . U equal
  // those of the vertices (the elastic forces sum to zero); the point cloud,
  // which acts on the fluid like a sphere a fraction of dx larger than the
  // mesh, is shrunk by that fraction. 1: markers on the vertices (plain IBM).
  double marker_scale = 1.0;
  std::vector<double> markers_lattice;  // marker positions of the last spread / advect (scale != 1)
  double spacing_m = 0.0;               // dx
  double newton_to_lattice = 0.0;       // F_lb = F dt^2 / (m dx) per newton
  // Arithmetic of the elastic force loop (elastic_body.h); the flow scene
  // and the suspension set it from ShearFlowNumerics::elastic_single_precision
  // (the suspension's numerics.flow).
  elastic::ForcePrecision elastic_precision = elastic::ForcePrecision::kDouble;
  NodeBox last_support;  // nodes this cell's last spread touched
};

struct AdvectReport {
  double max_speed_lattice = 0.0;  // NaN if a velocity is NaN
  double lo[3] = {0, 0, 0};        // bounding box of the moved vertices, lattice units
  double hi[3] = {0, 0, 0};
};

// Scratch of the coupling of all cells, reused every step (no allocation once
// sized): the coupled points (vertices or markers) of every cell in one
// array, cell after cell, their forces and interpolated velocities, and the
// kernel stencils of the last spread. advect_cells reuses those stencils when
// the points are bit for bit those of the spread (the flow step spreads at
// X(t) and interpolates u(t) at the same X(t)), else it builds new ones.
struct CouplingWorkspace {
  std::vector<double> points;               // of the last spread (stencils are built for these)
  std::vector<double> forces;               // of the last spread
  std::vector<double> renormalised_forces;  // of the last phase-weighted spread
  std::vector<double> query;                // of the last advect
  std::vector<double> velocities;           // interpolated at `query`
  ibm::StencilSet stencils;
  bool stencils_valid = false;
  std::vector<elastic::ElasticEvaluation> evaluations;
  std::vector<AdvectReport> reports;
};

// The cells immersed in one fluid, in a fixed order (the order of spreading
// and of every per-cell result). No cell-cell contact: cells interact only
// through the fluid.
struct ImmersedCells {
  std::vector<ImmersedCell> cells;
  CouplingWorkspace workspace;
  // Viscosity contrast: the relative spreading weight of a node by its phase
  // (index = the fluid's phase, 0 the suspending fluid; phases past the end
  // weigh 1). When set and the fluid has a phase field, each point's kernel
  // weights are multiplied by the weight of their node's phase and the
  // stencil renormalised to its mass in the fluid, F(x) = f w(x) g(x) sum_y
  // w(y) / sum_y w(y) g(y): the point's force is kept and its share in the
  // inside of a cell is scaled by g (docs/accuracy/viscosity_contrast.md).
  // Empty: the plain kernel (ibm::spread) alone.
  std::vector<double> phase_spread_weights;

  std::size_t size() const { return cells.size(); }
  ImmersedCell& operator[](std::size_t i) { return cells[i]; }
  const ImmersedCell& operator[](std::size_t i) const { return cells[i]; }
};

// X = origin + x / dx: places the mesh (reference positions in metres, about
// its own origin) with its origin at `origin_lattice` (box coordinates,
// lattice units). Keeps pointers to `mesh` and `body`.
ImmersedCell make_immersed_cell(const mesh::TetMesh& mesh, const elastic::ElasticBody& body,
                                const units::Units& units, const double origin_lattice[3]);

// Appends make_immersed_cell(...) to `cells`; returns it (references to
// earlier cells may be invalidated).
ImmersedCell& add_cell(ImmersedCells& cells, const mesh::TetMesh& mesh, const elastic::ElasticBody& body,
                       const units::Units& units, const double origin_lattice[3]);

// f = -dW/dx at the current positions (paper eq. 9-10), computed in SI,
// stored in lattice units (F_lb = F dt^2 / (m dx)). Returns the elastic
// energy (J) and the first inverted tetrahedron.
elastic::ElasticEvaluation compute_elastic_forces(ImmersedCell& cell, int threads);

// compute_elastic_forces of every cell; one evaluation per cell, in order
// (held in cells.workspace until the next call).
const std::vector<elastic::ElasticEvaluation>& compute_elastic_forces(ImmersedCells& cells, int threads);

// F(x) = sum_cells sum_p f_p delta_h(x - X_p)   (spreading, paper section 7; no equation number).
// Clears the force field on the union of the nodes the previous spreads of
// all cells touched (and only there), then spreads the forces_lattice of all
// cells in one pass (ibm::spread over the points of every cell; the order of
// additions at a node is fixed and independent of the thread count) and
// records each cell's new support. The fluid must have a force field, zero
// elsewhere (as make_fluid leaves it).
void spread_forces(ImmersedCells& cells, lb::Fluid& fluid, ibm::Kernel kernel, int threads);

// U_p = sum_x u(x) delta_h(x - X_p), then X_p += U_p dt   (interpolation, paper section 7)
// (explicit Euler, dt = 1): interpolates the fluid's velocity field at the
// cell's vertices and moves them by one time step.
AdvectReport advect_cell(ImmersedCell& cell, const lb::Fluid& fluid, ibm::Kernel kernel, int threads);

// advect_cell of every cell, each by its own interpolated velocity, in one
// interpolation pass over the points of all cells (with the stencils of the
// last spread_forces where the points have not moved since); one report per
// cell, in order (held in cells.workspace until the next call).
const std::vector<AdvectReport>& advect_cells(ImmersedCells& cells, const lb::Fluid& fluid,
                                              ibm::Kernel kernel, int threads);

// x = X dx: positions in metres in box coordinates (walls at y = 0 and H).
std::vector<double> box_positions_m(const ImmersedCell& cell);

}  // namespace cellflow::coupling
