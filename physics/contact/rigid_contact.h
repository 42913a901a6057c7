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
//
// Where the law acts. The plates act on the surface vertices: the closest
// point of a surface triangle to a plane is one of its vertices, so a
// surface (closest-point) contact with a plate is the vertex contact. The
// probe acts on the surface triangles (`probe_triangles`): the gap of each
// triangle is the distance of its closest point to the probe centre minus Rp
// (physics/contact/triangle_distance.h), its force goes to the triangle's
// vertices with the barycentric weights of that point, so a probe of any
// radius meets a continuous surface (on the vertices alone a probe narrower
// than the mesh spacing slips between them). Without triangles the probe acts
// on the vertices, as the plates do.
//
// Augmented Lagrangian. Each constraint j (a vertex and a plate, or a probe
// triangle or vertex) may carry an offset o_j: its law acts on g_j - o_j, so
// the zero-force gap is r + o_j and the force at contact (g_j = 0) is the
// law's at -o_j, the multiplier lambda_j. Uzawa's update o_j <- max(o_j - g_j,
// -r) after each equilibrium (update_offsets) moves the law until every
// constraint that carries force sits at g_j = 0 and every other one carries
// none (o = -r: no force at any g >= 0): the gap vanishes whatever k, and k
// only sets how fast the updates converge (for the linear part of the law,
// lambda <- lambda - 2k g, the classical update).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

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
  // The probe acts on these triangles (3 vertex indices each, outward
  // oriented; surface_triangles.h) at their closest points; empty: on the
  // contact vertices.
  std::span<const std::int32_t> probe_triangles;
  // Augmented-Lagrangian offsets o_j (metres), one per contact vertex for each
  // plate and one per probe constraint (triangle, or vertex without
  // triangles); empty: all zero (the plain penalty).
  std::span<const double> lower_plate_offsets_m;
  std::span<const double> upper_plate_offsets_m;
  std::span<const double> probe_offsets_m;
};

// Totals of one evaluation. Reactions are the forces the cell exerts on each
// obstacle: minus the sum of the contact forces on the vertices.
struct ContactEvaluation {
  double energy_j = 0.0;
  double lower_plate_reaction_n = 0.0;       // z component; < 0 when the cell presses down on it
  double upper_plate_reaction_n = 0.0;       // z component; > 0 when the cell pushes the plate up
  std::array<double, 3> probe_reaction_n{};  // vector
  double max_penetration_m = 0.0;            // max over constraints of max(0, -gap) (the true gap, no offset)
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

// The Hessian of the probe's triangle constraints: 81 doubles per triangle
// of obstacles.probe_triangles, blocks[81 t + 9 (3 a + b) + 3 i + j] =
// d^2 E / dy_{v_a, i} dy_{v_b, j} for its vertices v_0 v_1 v_2: the exact
//   phi'' grad d grad d^T + phi' hess d
// (d the distance of the closest point, triangle_distance.h), or without
// the second term with `positive_semidefinite`. Adds nothing without a probe
// or triangles.
void add_probe_triangle_hessian(const Obstacles& obstacles, const double* positions_m, double* blocks,
                                bool positive_semidefinite = false);

// Per probe triangle: the gap the law sees (g - o), the outward normal of
// the probe at the closest point (3 per triangle) and its barycentric
// coordinates (3 per triangle). For the Newton step limit.
void probe_triangle_gaps(const Obstacles& obstacles, const double* positions_m, double* gaps_m,
                         double* normals_out, double* barycentric_out);

// Smallest gap of each listed vertex over all obstacles, gaps_m[k] for
// vertices[k], and the outward unit normal of that obstacle at the vertex
// (3 per vertex, normals_out[3 k + a]); +infinity and a zero normal with no
// obstacle. The gaps are those the law sees (g - o with offsets); the probe
// counts only when it acts on the vertices (no probe_triangles). Used by
// predictors and the Newton step limit.
void nearest_obstacle(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                      const double* positions_m, double* gaps_m, double* normals_out);

// Augmented-Lagrangian offsets of every constraint (Obstacles' spans point
// into them).
struct ContactOffsets {
  std::vector<double> lower_plate, upper_plate, probe;
  // Per constraint: the step of its update (1, halved each time its gap
  // changes sign between updates) and its gap at the last update.
  struct Family {
    std::vector<double> relaxation, last_gap_m;
  };
  Family lower_plate_state, upper_plate_state, probe_state;
};

// Offsets for `vertex_count` contact vertices and `probe_constraints` probe
// constraints, all at -r: hard contact, no force at any gap >= 0.
ContactOffsets hard_contact_offsets(const PenaltyParams& penalty, std::size_t vertex_count,
                                    std::size_t probe_constraints);

// Points the obstacles' offset spans at `offsets` (only the obstacles present).
void attach_offsets(const ContactOffsets& offsets, Obstacles& obstacles);

// The largest gap error of the state: |g_j| of each constraint that carries
// force, max(0, -g_j) of one that does not; 0 without obstacles.
double gap_error(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                 const double* positions_m);

// One Uzawa update of `offsets` (those `obstacles` point at):
// o_j <- max(o_j - beta_j g_j, -r) for a constraint that carries force
// (beta_j its relaxation), max(o_j - g_j, -r) for any other. Returns the gap
// error before the update.
double update_offsets(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                      const double* positions_m, ContactOffsets& offsets);

// Defaults of the penalty law for a cell of radius R, Young's modulus E and
// mean edge length h (see the .cc for the derivation): r = 5e-3 R and k such
// that a vertex carrying the expected largest contact force (at 90 %
// compression) penetrates by 1e-3 R, a fifth of the 0.5 % bound.
PenaltyParams default_penalty(double youngs_modulus_pa, double radius_m, double mean_edge_length_m);

}  // namespace cellflow::contact
