// The immersed-boundary coupling of one tetrahedral cell to a lattice-
// Boltzmann fluid: the building blocks of one time step of the shear-flow
// scene, exposed so that tests and benchmarks exercise the same code.
//
// One time step (lattice units, dt = 1):
//   compute_elastic_forces   f = elastic forces at the vertices   (paper eq. 9-10)
//   spread_cell_forces       force field = sum_p f_p delta(x - X_p)   (Guo forcing in the LB step)
//   lb::collide_stream       u(t) written into the velocity field
//   advect_cell              U_p = sum_x u(x) delta(x - X_p);  X_p += U_p
#pragma once

#include <cstddef>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/ibm/ibm.h"
#include "physics/lb/fluid.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

// Lattice nodes [lo, hi] (inclusive, before periodic wrap) per direction.
struct NodeBox {
  int lo[3] = {0, 0, 0};
  int hi[3] = {-1, -1, -1};  // hi < lo: empty
};

struct ImmersedCell {
  // Vertex state, 3 per vertex, interleaved.
  std::vector<double> positions_lattice;   // box coordinates, lattice units
  std::vector<double> forces_lattice;      // elastic forces of the last compute_elastic_forces
  std::vector<double> velocities_lattice;  // fluid velocity of the last advect_cell
  // SI scratch for the elastic law: positions relative to `origin_lattice`
  // (keeps the deformation gradient free of the box offset's round-off).
  std::vector<double> positions_m;
  std::vector<double> forces_n;
  double origin_lattice[3] = {0, 0, 0};
  double spacing_m = 0.0;          // dx
  double newton_to_lattice = 0.0;  // F_lb = F dt^2 / (m dx) per newton
  NodeBox last_support;            // nodes the last spread touched
};

// Places the mesh (reference positions in metres, about its own origin) with
// its origin at `origin_lattice` (box coordinates, lattice units).
ImmersedCell make_immersed_cell(const mesh::TetMesh& mesh, const units::Units& units,
                                const double origin_lattice[3]);

// Elastic forces at the current positions (computed in SI, stored in lattice
// units). Returns the elastic energy (J) and the first inverted tetrahedron.
elastic::ElasticEvaluation compute_elastic_forces(ImmersedCell& cell, const elastic::ElasticBody& body,
                                                  int threads);

// Clears the force field on the nodes the previous spread touched (and only
// there), then spreads forces_lattice. The fluid must have a force field.
// The force field must be zero elsewhere (as make_fluid leaves it).
void spread_cell_forces(ImmersedCell& cell, lb::Fluid& fluid, ibm::Kernel kernel, int threads);

struct AdvectReport {
  double max_speed_lattice = 0.0;  // NaN if a velocity is NaN
  double lo[3] = {0, 0, 0};        // bounding box of the moved vertices, lattice units
  double hi[3] = {0, 0, 0};
};

// Interpolates the fluid's velocity field at the vertices and moves them by
// one time step: X += U dt   (explicit Euler, dt = 1).
AdvectReport advect_cell(ImmersedCell& cell, const lb::Fluid& fluid, ibm::Kernel kernel, int threads);

// Positions in metres in box coordinates (walls at y = 0 and H).
std::vector<double> box_positions_m(const ImmersedCell& cell);

}  // namespace cellflow::scenes
