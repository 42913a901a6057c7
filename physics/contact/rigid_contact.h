// Frictionless contact of cell vertices with rigid obstacles: two flat plates
// normal to z and a spherical probe (paper section 4.2: "a repulsive force
// prevents the cell vertices from penetrating the plates or the spherical
// indenter").
//
// Each listed vertex feels a repulsive penalty potential of its gap g to each
// obstacle (g = signed distance from the obstacle surface, positive outside;
// s = r - g is how far the vertex is inside the range r):
//   phi(s) = k s^3 / (3 r)              for 0 <= s <= r  (0 <= g <= r)
//   phi(s) = k (s^2 - r s + r^2 / 3)    for s > r        (g < 0, penetration)
// so the force magnitude is -phi'(g) = k s^2 / r, then k (2 s - r) = k (r - 2 g):
// a quadratic onset over the range and a linear spring of stiffness 2 k once
// the vertex penetrates. phi, phi' and phi'' are continuous (C2): Newton's
// method stays well behaved when vertices enter or leave contact, and in
// contact the force is linear, so a Newton step is exact for a vertex that
// stays inside. A vertex carrying force f > k r penetrates by (f - k r) / (2 k).
//
// Energy, forces and the Hessian come from the one helper `penalty_of_gap`.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

namespace cellflow::contact {

// Penalty law shared by every obstacle.
struct PenaltyParams {
  double stiffness_n_per_m = 0.0;  // k > 0
  double range_m = 0.0;            // r > 0: the force starts at gap r
};

// A rigid sphere (colloidal probe).
struct Probe {
  std::array<double, 3> centre_m{};
  double radius_m = 0.0;
};

// The rigid obstacles of one load step. Unset obstacles are absent.
struct Obstacles {
  PenaltyParams penalty;
  std::optional<double> lower_plate_z_m;  // vertices are pushed up (+z), gap = y_z - z_lower
  std::optional<double> upper_plate_z_m;  // vertices are pushed down (-z), gap = z_upper - y_z
  std::optional<Probe> probe;             // vertices are pushed out radially, gap = |y - c| - Rp
};

// Totals of one evaluation. Reactions are the forces the cell exerts on each
// obstacle: minus the sum of the contact forces on the vertices.
struct ContactEvaluation {
  double energy_j = 0.0;
  double lower_plate_reaction_n = 0.0;       // z component; < 0 when the cell presses down on it
  double upper_plate_reaction_n = 0.0;       // z component; > 0 when the cell pushes the plate up
  std::array<double, 3> probe_reaction_n{};  // vector
  double max_penetration_m = 0.0;            // max over vertices and obstacles of max(0, -gap)
  int num_active = 0;                        // vertex-obstacle pairs with gap < r
};

// Adds the contact forces on `vertices` (indices into the flat position array,
// 3 per vertex) into forces_n and returns energy, reactions and penetration.
ContactEvaluation add_contact_forces(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                                     const double* positions_m, double* forces_n);

// Same totals without forces (line searches).
ContactEvaluation contact_energy(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                                 const double* positions_m);

// Adds the contact Hessian d^2 E / dy dy into per-vertex 3x3 blocks: 9 doubles
// (row-major) per entry of `vertices`, blocks[9 * k + 3 * a + b] for vertex
// vertices[k]. The contact energy couples no two vertices, so these blocks are
// the whole Hessian. For the probe the exact Hessian is
//   phi'' n n^T + phi' / d (I - n n^T)
// whose second term is negative (phi' < 0); with `positive_semidefinite` that
// term is dropped, which keeps a Newton tangent positive definite at the cost
// of a relative error s / (2 Rp) (s = r - g) in the curvature.
void add_contact_hessian_blocks(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                                const double* positions_m, double* blocks,
                                bool positive_semidefinite = false);

// Smallest gap of each listed vertex over all obstacles, gaps_m[k] for
// vertices[k], and the outward unit normal of that obstacle at the vertex
// (3 per vertex, normals_out[3 k + a]); +infinity and a zero normal with no
// obstacle. Used by predictors to place vertices relative to the surfaces.
void nearest_obstacle(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                      const double* positions_m, double* gaps_m, double* normals_out);

// Defaults of the penalty law for a cell of radius R, Young's modulus E and
// mean edge length h (see the .cc for the derivation): r = 5e-3 R and k such
// that a vertex carrying the expected largest contact force (at 90 %
// compression) penetrates by 1e-3 R, a fifth of the 0.5 % bound.
PenaltyParams default_penalty(double youngs_modulus_pa, double radius_m, double mean_edge_length_m);

}  // namespace cellflow::contact
