#include "physics/contact/rigid_contact.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "physics/contact/triangle_distance.h"

namespace cellflow::contact {
namespace {

// Value, slope and curvature of the penalty potential at gap g.
struct PenaltyAtGap {
  double energy_j = 0.0;
  double force_n = 0.0;            // -phi'(g) >= 0, along the outward normal
  double curvature_n_per_m = 0.0;  // phi''(g) >= 0
};

// s = r - g;  0 < s <= r: phi = k s^3 / (3r), -phi' = k s^2 / r, phi'' = 2 k s / r
//             s > r:      phi = k (s^2 - r s + r^2/3), -phi' = k (2s - r), phi'' = 2 k
inline PenaltyAtGap penalty_of_gap(const PenaltyParams& p, double gap_m) {
  PenaltyAtGap out;
  const double r = p.range_m;
  const double k = p.stiffness_n_per_m;
  const double s = r - gap_m;
  if (!(s > 0.0)) return out;
  if (s <= r) {
    out.force_n = k * s * s / r;
    out.energy_j = out.force_n * s / 3.0;
    out.curvature_n_per_m = 2.0 * k * s / r;
  } else {
    out.force_n = k * (2.0 * s - r);
    out.energy_j = k * (s * s - r * s + r * r / 3.0);
    out.curvature_n_per_m = 2.0 * k;
  }
  return out;
}

double offset_at(std::span<const double> offsets, std::size_t k) {
  return offsets.empty() ? 0.0 : offsets[k];
}

double distance_to_probe(const Probe& pr, const double* yv, double* d) {
  for (int a = 0; a < 3; ++a) d[a] = yv[a] - pr.centre_m[a];
  return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

// The closest point of probe triangle t: its distance and where it lies.
TriangleDistance probe_triangle(const Probe& pr, std::span<const std::int32_t> triangles, std::size_t t,
                                const double* y, double* corners) {
  for (int i = 0; i < 3; ++i) {
    const double* yv = y + 3 * static_cast<std::size_t>(triangles[3 * t + i]);
    for (int a = 0; a < 3; ++a) corners[3 * i + a] = yv[a];
  }
  return triangle_distance(pr.centre_m.data(), corners);
}

// Visits every constraint with its true gap g and offset o:
//   visit(family, index, gap, offset) with family 0/1/2 = lower plate, upper plate, probe.
template <class Visit>
void for_each_constraint(const Obstacles& obstacles, std::span<const std::int32_t> vertices, const double* y,
                         Visit visit) {
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const double* yv = y + 3 * static_cast<std::size_t>(vertices[k]);
    if (obstacles.lower_plate_z_m)
      visit(0, k, yv[2] - *obstacles.lower_plate_z_m, offset_at(obstacles.lower_plate_offsets_m, k));
    if (obstacles.upper_plate_z_m)
      visit(1, k, *obstacles.upper_plate_z_m - yv[2], offset_at(obstacles.upper_plate_offsets_m, k));
    if (obstacles.probe && obstacles.probe_triangles.empty()) {
      double d[3];
      visit(2, k, distance_to_probe(*obstacles.probe, yv, d) - obstacles.probe->radius_m,
            offset_at(obstacles.probe_offsets_m, k));
    }
  }
  if (obstacles.probe && !obstacles.probe_triangles.empty()) {
    const std::size_t count = obstacles.probe_triangles.size() / 3;
    double corners[9];
    for (std::size_t t = 0; t < count; ++t) {
      const TriangleDistance td = probe_triangle(*obstacles.probe, obstacles.probe_triangles, t, y, corners);
      visit(2, t, td.distance_m - obstacles.probe->radius_m, offset_at(obstacles.probe_offsets_m, t));
    }
  }
}

// One pass over the constraints for energy, forces (if forces_n) and totals.
ContactEvaluation evaluate(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                           const double* y, double* forces_n) {
  ContactEvaluation total;
  const PenaltyParams& pen = obstacles.penalty;
  double max_pen = 0.0;
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const std::int32_t v = vertices[k];
    const double* yv = y + 3 * static_cast<std::size_t>(v);
    if (obstacles.lower_plate_z_m) {
      const double gap = yv[2] - *obstacles.lower_plate_z_m;
      const PenaltyAtGap c = penalty_of_gap(pen, gap - offset_at(obstacles.lower_plate_offsets_m, k));
      max_pen = std::max(max_pen, -gap);
      if (c.force_n > 0.0) {
        total.energy_j += c.energy_j;
        total.lower_plate_reaction_n -= c.force_n;  // vertex pushed +z, plate pushed -z
        if (forces_n) forces_n[3 * v + 2] += c.force_n;
        ++total.num_active;
      }
    }
    if (obstacles.upper_plate_z_m) {
      const double gap = *obstacles.upper_plate_z_m - yv[2];
      const PenaltyAtGap c = penalty_of_gap(pen, gap - offset_at(obstacles.upper_plate_offsets_m, k));
      max_pen = std::max(max_pen, -gap);
      if (c.force_n > 0.0) {
        total.energy_j += c.energy_j;
        total.upper_plate_reaction_n += c.force_n;  // vertex pushed -z, plate pushed +z
        if (forces_n) forces_n[3 * v + 2] -= c.force_n;
        ++total.num_active;
      }
    }
    if (obstacles.probe && obstacles.probe_triangles.empty()) {
      const Probe& pr = *obstacles.probe;
      double d[3];
      const double dist = distance_to_probe(pr, yv, d);
      const double gap = dist - pr.radius_m;
      const PenaltyAtGap c = penalty_of_gap(pen, gap - offset_at(obstacles.probe_offsets_m, k));
      max_pen = std::max(max_pen, -gap);
      if (c.force_n > 0.0 && dist > 0.0) {
        // force on the vertex along the outward normal n = (y - c) / |y - c|
        const double n[3] = {d[0] / dist, d[1] / dist, d[2] / dist};
        total.energy_j += c.energy_j;
        for (int a = 0; a < 3; ++a) {
          total.probe_reaction_n[a] -= c.force_n * n[a];
          if (forces_n) forces_n[3 * v + a] += c.force_n * n[a];
        }
        ++total.num_active;
      }
    }
  }
  if (obstacles.probe && !obstacles.probe_triangles.empty()) {
    const Probe& pr = *obstacles.probe;
    const std::span<const std::int32_t> tri = obstacles.probe_triangles;
    double corners[9];
    for (std::size_t t = 0; t < tri.size() / 3; ++t) {
      const TriangleDistance td = probe_triangle(pr, tri, t, y, corners);
      const double gap = td.distance_m - pr.radius_m;
      max_pen = std::max(max_pen, -gap);
      const PenaltyAtGap c = penalty_of_gap(pen, gap - offset_at(obstacles.probe_offsets_m, t));
      if (!(c.force_n > 0.0 && td.distance_m > 0.0)) continue;
      // d d / d y_i = -b_i n (n from the closest point to the centre): the
      // force F b_i pushes vertex i away from the probe, the probe gets F n.
      total.energy_j += c.energy_j;
      for (int a = 0; a < 3; ++a) total.probe_reaction_n[a] += c.force_n * td.normal[a];
      if (forces_n) {
        for (int i = 0; i < 3; ++i) {
          double* f = forces_n + 3 * static_cast<std::size_t>(tri[3 * t + i]);
          for (int a = 0; a < 3; ++a) f[a] -= c.force_n * td.barycentric[i] * td.normal[a];
        }
      }
      ++total.num_active;
    }
  }
  total.max_penetration_m = std::max(0.0, max_pen);
  return total;
}

}  // namespace

ContactEvaluation add_contact_forces(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                                     const double* positions_m, double* forces_n) {
  return evaluate(obstacles, vertices, positions_m, forces_n);
}

ContactEvaluation contact_energy(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                                 const double* positions_m) {
  return evaluate(obstacles, vertices, positions_m, nullptr);
}

void add_contact_hessian_blocks(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                                const double* positions_m, double* blocks, bool positive_semidefinite) {
  const PenaltyParams& pen = obstacles.penalty;
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const double* yv = positions_m + 3 * static_cast<std::size_t>(vertices[k]);
    double* block = blocks + 9 * k;
    // Plates: gap is linear in y_z, so d^2 phi / dy_z^2 = phi''.
    if (obstacles.lower_plate_z_m) {
      block[8] += penalty_of_gap(
                      pen, yv[2] - *obstacles.lower_plate_z_m - offset_at(obstacles.lower_plate_offsets_m, k))
                      .curvature_n_per_m;
    }
    if (obstacles.upper_plate_z_m) {
      block[8] += penalty_of_gap(
                      pen, *obstacles.upper_plate_z_m - yv[2] - offset_at(obstacles.upper_plate_offsets_m, k))
                      .curvature_n_per_m;
    }
    if (obstacles.probe && obstacles.probe_triangles.empty()) {
      const Probe& pr = *obstacles.probe;
      const double d[3] = {yv[0] - pr.centre_m[0], yv[1] - pr.centre_m[1], yv[2] - pr.centre_m[2]};
      const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      const PenaltyAtGap c =
          penalty_of_gap(pen, dist - pr.radius_m - offset_at(obstacles.probe_offsets_m, k));
      if (c.force_n > 0.0 && dist > 0.0) {
        // H = phi'' n n^T + (phi'/d) (I - n n^T), phi' = -force
        const double n[3] = {d[0] / dist, d[1] / dist, d[2] / dist};
        const double tangential = positive_semidefinite ? 0.0 : -c.force_n / dist;
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) {
            const double nn = n[a] * n[b];
            block[3 * a + b] += c.curvature_n_per_m * nn + tangential * ((a == b ? 1.0 : 0.0) - nn);
          }
        }
      }
    }
  }
}

void nearest_obstacle(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                      const double* positions_m, double* gaps_m, double* normals_out) {
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const double* yv = positions_m + 3 * static_cast<std::size_t>(vertices[k]);
    double best = std::numeric_limits<double>::infinity();
    double normal[3] = {0.0, 0.0, 0.0};
    auto consider = [&](double gap, double nx, double ny, double nz) {
      if (gap < best) {
        best = gap;
        normal[0] = nx;
        normal[1] = ny;
        normal[2] = nz;
      }
    };
    if (obstacles.lower_plate_z_m)
      consider(yv[2] - *obstacles.lower_plate_z_m - offset_at(obstacles.lower_plate_offsets_m, k), 0.0, 0.0,
               1.0);
    if (obstacles.upper_plate_z_m)
      consider(*obstacles.upper_plate_z_m - yv[2] - offset_at(obstacles.upper_plate_offsets_m, k), 0.0, 0.0,
               -1.0);
    if (obstacles.probe && obstacles.probe_triangles.empty()) {
      const Probe& pr = *obstacles.probe;
      const double d[3] = {yv[0] - pr.centre_m[0], yv[1] - pr.centre_m[1], yv[2] - pr.centre_m[2]};
      const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (dist > 0.0)
        consider(dist - pr.radius_m - offset_at(obstacles.probe_offsets_m, k), d[0] / dist, d[1] / dist,
                 d[2] / dist);
    }
    gaps_m[k] = best;
    for (int a = 0; a < 3; ++a) normals_out[3 * k + a] = normal[a];
  }
}

void add_probe_triangle_hessian(const Obstacles& obstacles, const double* positions_m, double* blocks,
                                bool positive_semidefinite) {
  if (!obstacles.probe || obstacles.probe_triangles.empty()) return;
  const Probe& pr = *obstacles.probe;
  const std::span<const std::int32_t> tri = obstacles.probe_triangles;
  double corners[9], hessian[81];
  for (std::size_t t = 0; t < tri.size() / 3; ++t) {
    const TriangleDistance td = probe_triangle(pr, tri, t, positions_m, corners);
    const PenaltyAtGap c = penalty_of_gap(
        obstacles.penalty, td.distance_m - pr.radius_m - offset_at(obstacles.probe_offsets_m, t));
    if (!(c.force_n > 0.0 && td.distance_m > 0.0)) continue;
    // E = phi(d - Rp - o):  d2E = phi'' grad d grad d^T + phi' hess d,  phi' = -F,
    // grad_{i a} d = -b_i n_a
    double grad[9];
    for (int i = 0; i < 3; ++i) {
      for (int a = 0; a < 3; ++a) grad[3 * i + a] = -td.barycentric[i] * td.normal[a];
    }
    if (!positive_semidefinite) triangle_distance_hessian(pr.centre_m.data(), corners, td, hessian);
    double* out = blocks + 81 * t;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) {
            const int r = 3 * i + a, s = 3 * j + b;
            double value = c.curvature_n_per_m * grad[r] * grad[s];
            if (!positive_semidefinite) value -= c.force_n * hessian[9 * r + s];
            out[9 * (3 * i + j) + 3 * a + b] += value;
          }
        }
      }
    }
  }
}

void probe_triangle_gaps(const Obstacles& obstacles, const double* positions_m, double* gaps_m,
                         double* normals_out, double* barycentric_out) {
  if (!obstacles.probe || obstacles.probe_triangles.empty()) return;
  const Probe& pr = *obstacles.probe;
  const std::span<const std::int32_t> tri = obstacles.probe_triangles;
  double corners[9];
  for (std::size_t t = 0; t < tri.size() / 3; ++t) {
    const TriangleDistance td = probe_triangle(pr, tri, t, positions_m, corners);
    gaps_m[t] = td.distance_m - pr.radius_m - offset_at(obstacles.probe_offsets_m, t);
    for (int a = 0; a < 3; ++a) {
      normals_out[3 * t + a] = -td.normal[a];  // the probe's outward normal at the closest point
      barycentric_out[3 * t + a] = td.barycentric[a];
    }
  }
}

ContactOffsets hard_contact_offsets(const PenaltyParams& penalty, std::size_t vertex_count,
                                    std::size_t probe_constraints) {
  ContactOffsets o;
  o.lower_plate.assign(vertex_count, -penalty.range_m);
  o.upper_plate.assign(vertex_count, -penalty.range_m);
  o.probe.assign(probe_constraints, -penalty.range_m);
  for (auto [family, count] :
       {std::pair{&o.lower_plate_state, vertex_count}, std::pair{&o.upper_plate_state, vertex_count},
        std::pair{&o.probe_state, probe_constraints}}) {
    family->relaxation.assign(count, 1.0);
    family->last_gap_m.assign(count, 0.0);
  }
  return o;
}

void attach_offsets(const ContactOffsets& offsets, Obstacles& obstacles) {
  if (obstacles.lower_plate_z_m) obstacles.lower_plate_offsets_m = offsets.lower_plate;
  if (obstacles.upper_plate_z_m) obstacles.upper_plate_offsets_m = offsets.upper_plate;
  if (obstacles.probe) obstacles.probe_offsets_m = offsets.probe;
}

double gap_error(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                 const double* positions_m) {
  const double range = obstacles.penalty.range_m;
  double error = 0.0;
  for_each_constraint(obstacles, vertices, positions_m, [&](int, std::size_t, double gap, double offset) {
    const bool carries_force = gap - offset < range;
    error = std::max(error, carries_force ? std::abs(gap) : -gap);
  });
  return error;
}

double update_offsets(const Obstacles& obstacles, std::span<const std::int32_t> vertices,
                      const double* positions_m, ContactOffsets& offsets) {
  const double range = obstacles.penalty.range_m;
  double error = 0.0;
  // the gaps are read through `obstacles` (whose spans may be `offsets`):
  // collect the new values first, then write
  std::vector<std::pair<double*, double>> updates;
  ContactOffsets::Family* family[3] = {&offsets.lower_plate_state, &offsets.upper_plate_state,
                                       &offsets.probe_state};
  std::vector<double>* values[3] = {&offsets.lower_plate, &offsets.upper_plate, &offsets.probe};
  for_each_constraint(obstacles, vertices, positions_m, [&](int f, std::size_t k, double gap, double offset) {
    const bool carries_force = gap - offset < range;
    error = std::max(error, carries_force ? std::abs(gap) : -gap);
    std::vector<double>& target = *values[f];
    ContactOffsets::Family& state = *family[f];
    if (k >= target.size() || k >= state.relaxation.size()) return;
    double& beta = state.relaxation[k];
    double& last = state.last_gap_m[k];
    // A loaded constraint whose gap changes sign from one update to the next
    // sits on a mode the contact alone holds (a rim folding onto the plate:
    // negative elastic stiffness there), where the full update overshoots
    // and the oscillation grows; halving its step makes it contract.
    if (carries_force && gap * last < 0.0) {
      beta *= 0.5;
    } else {
      beta = std::min(1.0, 1.5 * beta);
    }
    last = carries_force ? gap : 0.0;
    updates.emplace_back(&target[k], std::max(offset - (carries_force ? beta : 1.0) * gap, -range));
  });
  for (const auto& [slot, value] : updates) *slot = value;
  return error;
}

PenaltyParams default_penalty(double youngs_modulus_pa, double radius_m, double mean_edge_length_m) {
  PenaltyParams p;
  // The range is the smoothing layer of the onset: thin against the
  // compression of a typical first load point (2 % of R per plate), thick
  // enough that a Newton step rarely carries a vertex across it (with
  // 5e-4 R a curve needs 25 % more Newton iterations; the plates start at the
  // zero-force distance, so the range itself shifts nothing).
  p.range_m = 5e-3 * radius_m;
  // Largest force per surface vertex: the contact pressure at 90 % compression
  // stays below about kDesignPressure E on a tributary area of about h^2.
  // Measured: at 80 % compression (w = 0.25, the most strain-hardening cell
  // of the paper) no vertex force reaches k r, i.e. no vertex penetrates at
  // all (tests/scenes Compression.PenetrationStaysBelowHalfAPercentOfTheRadius);
  // at 88 % (w = 0.5) the deepest vertex penetrates 1.2e-3 R.
  constexpr double kDesignPressure = 20.0;
  const double max_vertex_force_n =
      kDesignPressure * youngs_modulus_pa * mean_edge_length_m * mean_edge_length_m;
  // That force penetrates by p = 1e-3 R:  f = k r + 2 k p  ->  k = f / (r + 2 p)
  const double penetration_m = 1e-3 * radius_m;
  p.stiffness_n_per_m = max_vertex_force_n / (p.range_m + 2.0 * penetration_m);
  return p;
}

}  // namespace cellflow::contact
