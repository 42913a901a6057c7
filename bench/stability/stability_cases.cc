// The cases of the stability matrix (issue 5, item 2): compression to
// deformation 0.9 over w x nu, very soft and very stiff cells, poor meshes,
// indentation extremes, and shear flow over Ca, the explicit-update
// stability limit, the time step (relaxation time, Reynolds target), kernels,
// materials and meshes. Flow cases use coarse lattices (3-4 cells per radius,
// small boxes, ~200-500 vertices, a few strain units) so that each takes
// seconds.
#include <signal.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <span>
#include <thread>

#include "bench/stability/stability_harness.h"
#include "physics/core/violations.h"
#include "physics/elastic/material.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"

namespace cellflow::stability {

namespace {

constexpr double kCompressionRadius = 8.6e-6;  // the paper's cell (issue 2 benchmark)
constexpr double kFlowRadius = 6e-6;
constexpr double kDefaultE = 1000.0;
// Flow cells are soft so that Ca up to 4 keeps the physical Reynolds number
// below the target (Re_p = rho Ca mu R^2 / eta^2 = 0.05 at Ca 4): otherwise the
// physical density is simulated and the Mach limit refuses the job.
constexpr double kFlowE = 1.0;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

CaseResult failed_or_converged(const Status& status, std::string detail) {
  CaseResult r;
  if (status.ok()) {
    r.outcome = Outcome::kConverged;
  } else {
    r.outcome = Outcome::kFailed;
    r.cause = failure_cause(status);
    detail = status.to_string() + "; " + detail;
  }
  r.detail = std::move(detail);
  return r;
}

CaseResult wrong(std::string check, std::string detail) {
  CaseResult r;
  r.outcome = Outcome::kWrong;
  r.cause = std::move(check);
  r.detail = std::move(detail);
  return r;
}

// ---- Meshes of poor quality ----------------------------------------------

// A TetGen sphere whose interior vertices are pushed towards the opposite
// face of one of their tetrahedra until that tet is nearly flat (volume down
// to kSliverVolume of the mean): caps and slivers with dihedral angles near
// 0 and 180 degrees, all still positively oriented. Written as Gmsh .msh v4.
constexpr double kSliverVolume = 2e-3;

StatusOr<mesh::MeshQuality> write_sliver_mesh(const std::string& path, double radius_m, int vertices,
                                              unsigned seed) {
  mesh::SphereMeshOptions options;
  options.radius_m = radius_m;
  options.target_vertex_count = vertices;
  StatusOr<mesh::TetMesh> made = mesh::make_sphere_mesh(options);
  if (!made.ok()) return made.status();
  mesh::TetMesh m = std::move(*made);
  if (m.on_surface.size() != m.num_vertices()) mesh::mark_surface_vertices(m);
  const std::size_t nv = m.num_vertices(), nt = m.num_tets();
  std::vector<std::vector<int>> incident(nv);
  double mean_volume = 0.0;
  for (std::size_t t = 0; t < nt; ++t) {
    for (int a = 0; a < 4; ++a) incident[m.tets[4 * t + a]].push_back(static_cast<int>(t));
    mean_volume += mesh::tet_signed_volume(m.positions_m.data(), &m.tets[4 * t]);
  }
  mean_volume /= static_cast<double>(nt);
  const double min_volume = kSliverVolume * mean_volume;
  std::mt19937 rng(seed);
  double* x = m.positions_m.data();
  auto all_positive = [&](std::size_t v) {
    for (int t : incident[v]) {
      if (!(mesh::tet_signed_volume(x, &m.tets[4 * t]) > min_volume)) return false;
    }
    return true;
  };
  for (std::size_t v = 0; v < nv; ++v) {
    if (m.on_surface[v] || incident[v].empty()) continue;
    const int t = incident[v][rng() % incident[v].size()];
    std::array<const double*, 3> face{};
    int k = 0;
    for (int a = 0; a < 4; ++a) {
      if (m.tets[4 * t + a] != static_cast<std::int32_t>(v)) face[k++] = x + 3 * m.tets[4 * t + a];
    }
    double e1[3], e2[3], n[3];
    for (int d = 0; d < 3; ++d) {
      e1[d] = face[1][d] - face[0][d];
      e2[d] = face[2][d] - face[0][d];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    const double norm = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    double distance = 0.0;
    for (int d = 0; d < 3; ++d) {
      n[d] /= norm;
      distance += (x[3 * v + d] - face[0][d]) * n[d];
    }
    const double original[3] = {x[3 * v], x[3 * v + 1], x[3 * v + 2]};
    bool moved = false;
    for (double fraction = 0.99; fraction > 0.3 && !moved; fraction -= 0.03) {
      for (int d = 0; d < 3; ++d) x[3 * v + d] = original[d] - fraction * distance * n[d];
      moved = all_positive(v);
    }
    if (!moved) {
      for (int d = 0; d < 3; ++d) x[3 * v + d] = original[d];
    }
  }
  if (Status s = mesh::write_gmsh_msh(m, path); !s.ok()) return s;
  return mesh::mesh_quality(m);
}

// A 200-vertex sphere with tetrahedron 0 inverted (two nodes swapped).
Status write_inverted_mesh(const std::string& path, double radius_m) {
  mesh::SphereMeshOptions options;
  options.radius_m = radius_m;
  options.target_vertex_count = 200;
  StatusOr<mesh::TetMesh> made = mesh::make_sphere_mesh(options);
  if (!made.ok()) return made.status();
  std::swap(made->tets[0], made->tets[1]);
  return mesh::write_gmsh_msh(*made, path);
}

// ---- Compression and indentation -----------------------------------------

scenes::CompressionParams compression(double e_pa, double nu, double w, int vertices, double max_deformation,
                                      int load_points) {
  scenes::CompressionParams p;
  p.cell.radius_m = kCompressionRadius;
  p.cell.material = {.youngs_modulus_pa = e_pa, .poisson_ratio = nu, .mooney_rivlin_w = w};
  p.cell.target_vertex_count = vertices;
  p.max_deformation = max_deformation;
  p.load_points = load_points;
  p.numerics.threads = 1;
  return p;
}

CaseResult run_compression_case(const scenes::CompressionParams& p, std::string mesh_note = "") {
  CompressionCheck check;
  mesh::TetMesh reference;
  check.check_volume = !p.cell.nucleus.has_value();
  scenes::SceneCallbacks callbacks;
  callbacks.on_mesh = [&](const mesh::TetMesh& m) {
    double lo = std::numeric_limits<double>::max(), hi = -lo;
    for (std::size_t v = 0; v < m.num_vertices(); ++v) {
      lo = std::min(lo, m.positions_m[3 * v + 2]);
      hi = std::max(hi, m.positions_m[3 * v + 2]);
    }
    check.initial_height_m = hi - lo;
    check.initial_volume_m3 = mesh::mesh_quality(m).volume_m3;
    reference = m;
  };
  callbacks.on_positions = [&](int index, std::span<const double> positions_m) {
    if (static_cast<int>(check.points.size()) <= index) check.points.resize(index + 1);
    check.points[index] = element_volumes(reference, positions_m.data());
  };
  const auto t0 = std::chrono::steady_clock::now();
  const scenes::QuasiStaticResult r = scenes::run_compression(p, callbacks);
  const double seconds = seconds_since(t0);
  std::string detail =
      mesh_note + number_text(r.curve.size(), 4) + " of " + std::to_string(p.load_points) + " points";
  if (!r.curve.empty()) {
    const scenes::CurvePoint& last = r.curve.back();
    int newton = 0, splits = 0;
    for (const scenes::CurvePoint& c : r.curve) {
      newton += c.newton_iterations;
      splits += c.step_splits;
    }
    double worst_ratio = 0.0, min_j = 1.0, crushed = 0.0;
    for (const scenes::CurvePoint& c : r.curve) {
      const double predicted = -c.force_n * (check.initial_height_m - c.displacement_m) /
                               (3.0 * elastic::moduli_from(p.cell.material).kappa_pa);
      worst_ratio = std::max(worst_ratio, (c.volume_m3 - check.initial_volume_m3) / predicted);
      if (static_cast<std::size_t>(c.index) < check.points.size())
        min_j = std::min(min_j, check.points[c.index].min_j);
      if (static_cast<std::size_t>(c.index) < check.points.size())
        crushed = std::max(crushed, check.points[c.index].crushed_fraction);
    }
    detail += ", max dV / dV(uniform J) " + number_text(worst_ratio, 4) + ", min J " + number_text(min_j, 4) +
              ", crushed volume " + number_text(crushed, 4);
    detail += ", last deformation " + number_text(last.deformation, 4) +
              ": F = " + number_text(last.force_n, 4) +
              " N, F/F_Hertz = " + number_text(last.force_n / last.hertz_force_n, 4) + ", dV/V0 = " +
              number_text(check.initial_volume_m3 > 0 ? last.volume_m3 / check.initial_volume_m3 - 1 : 0, 4) +
              ", Newton " + std::to_string(newton) + ", splits " + std::to_string(splits);
  }
  detail += ", run " + number_text(seconds, 4) + " s";
  if (std::optional<std::string> bad = check_compression(p, r, check)) return wrong(*bad, detail);
  return failed_or_converged(r.status, detail);
}

CaseResult run_indentation_case(double e_pa, double nu, double w, int vertices) {
  scenes::IndentationParams p;
  p.cell.radius_m = kCompressionRadius;
  p.cell.material = {.youngs_modulus_pa = e_pa, .poisson_ratio = nu, .mooney_rivlin_w = w};
  p.cell.target_vertex_count = vertices;
  p.probe_radius_m = 2.5e-6;
  p.max_indentation_m = 0.5 * 2.0 * kCompressionRadius;
  p.load_points = 20;
  p.numerics.threads = 1;
  const auto t0 = std::chrono::steady_clock::now();
  const scenes::QuasiStaticResult r = scenes::run_indentation(p);
  std::string detail = number_text(r.curve.size(), 4) + " of " + std::to_string(p.load_points) + " points";
  if (!r.curve.empty()) {
    detail += ", last deformation " + number_text(r.curve.back().deformation, 4) +
              ": F = " + number_text(r.curve.back().force_n, 4) +
              " N, F/F_Hertz = " + number_text(r.curve.back().force_n / r.curve.back().hertz_force_n, 4);
  }
  detail += ", run " + number_text(seconds_since(t0), 4) + " s";
  if (std::optional<std::string> bad = check_indentation(r)) return wrong(*bad, detail);
  return failed_or_converged(r.status, detail);
}

// ---- Shear flow ----------------------------------------------------------

// Coarse, fast flow: 4 cells per radius, 500 vertices, box 10 x 8 x 5 R, a
// few strain units; steady when D changes by < 0.2 % over 2 strain units.
scenes::ShearFlowParams flow(double ca) {
  scenes::ShearFlowParams p;
  p.cell.radius_m = kFlowRadius;
  p.cell.material = {.youngs_modulus_pa = kFlowE, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = 500;
  p.capillary_number = ca;
  scenes::ShearFlowNumerics& n = p.numerics;
  n.cells_per_radius = 4.0;
  n.box_x_radii = 10.0;
  n.box_y_radii = 8.0;
  n.box_z_radii = 5.0;
  n.max_strain = 8.0;
  n.snapshot_every_strain = 0.0;
  n.threads = 1;
  // These cases probe the stability of the coarse lattice itself; the
  // resolving lattice (9.5 cells/R at Ca 2) would make them ~100 x slower.
  n.resolve_thickness = false;
  return p;
}

CaseResult run_flow_case(const scenes::ShearFlowParams& p, std::string note = "") {
  const scenes::ShearFlowResult r = scenes::run_shear_flow(p);
  std::string detail = note + "Ca " + number_text(r.setup.capillary_number, 4) + ", stop " +
                       std::string(scenes::stop_name(r.stop)) + ", stiffness ratio " +
                       number_text(r.stiffness_ratio, 4) + ", Mach " + number_text(r.setup.mach_number, 4);
  if (!r.samples.empty()) {
    detail += ", strain " + number_text(r.samples.back().strain_units, 4) + ", D " +
              number_text(r.steady_taylor_deformation, 4) + " (5/4 Ca " +
              number_text(scenes::small_ca_taylor_deformation(r.setup.capillary_number), 4) +
              "), net strain " + number_text(r.steady_net_strain, 4) + ", steps " +
              std::to_string(r.time_steps);
  }
  detail += ", run " + number_text(r.wall_time_s, 4) + " s";
  if (!r.warnings.empty())
    detail += "; under-resolved: thickness / kernel " + number_text(r.thickness_over_kernel, 4);
  // A run refused up front has no samples and nothing to check.
  if (!r.samples.empty()) {
    if (std::optional<std::string> bad = check_shear_flow(r)) return wrong(*bad, detail);
  }
  return failed_or_converged(r.status, detail);
}

void add(std::vector<Case>& cases, std::string name, std::string description, double limit_s,
         std::function<CaseResult(const CaseContext&)> run, bool anchor = false) {
  Case c;
  c.name = std::move(name);
  c.description = std::move(description);
  c.time_limit_s = limit_s;
  c.anchor = anchor;
  c.run = std::move(run);
  cases.push_back(std::move(c));
}

// Wall-clock limits: about ten times the measured time of the slowest case
// of the group on one core of the 2-core development machine.
constexpr double kCompressionLimit = 600.0;
constexpr double kSmallCompressionLimit = 120.0;
constexpr double kFlowLimit = 300.0;

}  // namespace

std::vector<Case> make_cases(bool include_self_tests) {
  std::vector<Case> cases;

  // Compression to deformation 0.9 on the default mesh (3000 vertices), 30
  // load points: the w x nu grid.
  for (double w : {1.0, 0.5, 0.25}) {
    for (double nu : {0.45, 0.48, 0.49, 0.499}) {
      const std::string name = "compression/grid/w" + number_text(w, 4) + "-nu" + number_text(nu, 4);
      add(
          cases, name, "E 1 kPa, 3000 vertices, deformation 0.9 in 30 points", kCompressionLimit,
          [=](const CaseContext&) {
            return run_compression_case(compression(kDefaultE, nu, w, 3000, 0.9, 30));
          },
          w == 1.0 && nu == 0.48);
    }
  }
  // Very soft and very stiff cells (the solver's tolerances are relative to
  // E R^2; contact stiffness derived from E).
  for (double e : {1.0, 1e5}) {
    for (double w : {1.0, 0.25}) {
      add(cases, "compression/modulus/E" + number_text(e, 4) + "-w" + number_text(w, 4),
          "nu 0.48, 1000 vertices, deformation 0.9", kSmallCompressionLimit,
          [=](const CaseContext&) { return run_compression_case(compression(e, 0.48, w, 1000, 0.9, 30)); });
    }
  }
  // Poor meshes: the coarsest sphere the mesher allows, a sliver-ridden mesh
  // read from Gmsh, a file with an inverted element.
  for (double w : {1.0, 0.25}) {
    add(cases, "compression/mesh/coarse200-w" + number_text(w, 4),
        "200-vertex sphere, nu 0.48, deformation 0.9", kSmallCompressionLimit, [=](const CaseContext&) {
          return run_compression_case(compression(kDefaultE, 0.48, w, 200, 0.9, 30));
        });
  }
  for (double w : {1.0, 0.5}) {
    add(cases, "compression/mesh/slivers-w" + number_text(w, 4),
        "500-vertex sphere with flattened tets (.msh), nu 0.48", kSmallCompressionLimit,
        [=](const CaseContext& ctx) {
          const std::string path = ctx.work_dir + "/slivers_compression.msh";
          StatusOr<mesh::MeshQuality> q = write_sliver_mesh(path, kCompressionRadius, 500, 7);
          if (!q.ok()) return failed_or_converged(q.status(), "writing the sliver mesh");
          scenes::CompressionParams p = compression(kDefaultE, 0.48, w, 500, 0.9, 30);
          p.cell.mesh_file = path;
          return run_compression_case(p, "min dihedral " + number_text(q->min_dihedral_deg, 4) +
                                             " deg, max " + number_text(q->max_dihedral_deg, 4) + " deg; ");
        });
  }
  add(cases, "compression/mesh/inverted-element", "a .msh with one inverted tetrahedron",
      kSmallCompressionLimit, [](const CaseContext& ctx) {
        const std::string path = ctx.work_dir + "/inverted.msh";
        if (Status s = write_inverted_mesh(path, kCompressionRadius); !s.ok())
          return failed_or_converged(s, "");
        scenes::CompressionParams p = compression(kDefaultE, 0.48, 1.0, 200, 0.5, 10);
        p.cell.mesh_file = path;
        return run_compression_case(p);
      });
  add(cases, "compression/nucleus/stiff10x", "nucleus radius 0.5 R, E x 10, 1000 vertices, deformation 0.9",
      kSmallCompressionLimit, [](const CaseContext&) {
        scenes::CompressionParams p = compression(kDefaultE, 0.48, 0.5, 1000, 0.9, 30);
        p.cell.nucleus = cell::NucleusParams{
            .radius_m = 0.5 * kCompressionRadius,
            .material = {.youngs_modulus_pa = 10 * kDefaultE, .poisson_ratio = 0.48, .mooney_rivlin_w = 0.5}};
        return run_compression_case(p);
      });
  // Indentation extremes (probe 2.5 um, depth 0.5 of the diameter).
  for (double e : {1.0, 1e5}) {
    add(cases, "indentation/modulus/E" + number_text(e, 4), "nu 0.48, w 1, 1000 vertices",
        kSmallCompressionLimit, [=](const CaseContext&) { return run_indentation_case(e, 0.48, 1.0, 1000); });
  }
  add(cases, "indentation/material/w0.25-nu0.499", "1000 vertices", kSmallCompressionLimit,
      [](const CaseContext&) { return run_indentation_case(kDefaultE, 0.499, 0.25, 1000); });

  // Shear flow over Ca (up to 4).
  for (double ca : {0.05, 0.2, 0.8, 1.6, 2.5, 4.0}) {
    add(
        cases, "flow/ca/" + number_text(ca, 4), "4 cells/R, 500 vertices, box 10x8x5 R, 8 strain units",
        kFlowLimit, [=](const CaseContext&) { return run_flow_case(flow(ca)); }, ca == 0.2);
  }
  // The same in a box long enough for the stretched cell (at 10 R it
  // outgrows the periodic box: a clean failure above).
  for (double ca : {2.5, 4.0}) {
    add(cases, "flow/ca-long-box/" + number_text(ca, 4), "box 24x8x5 R, 8 strain units", kFlowLimit,
        [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(ca);
          p.numerics.box_x_radii = 24.0;
          return run_flow_case(p);
        });
  }
  // The explicit-update limit: the stiffness ratio k_max / (6 pi eta dx)
  // grows as 1 / Ca; with the default limit the stiffest are refused, with
  // the limit lifted (max_stiffness_ratio 100) the guards must catch them.
  for (double ca : {0.02, 0.01, 0.005, 0.003}) {
    add(cases, "flow/stiffness/default-limit-ca" + number_text(ca, 4),
        "default max_stiffness_ratio, 3 strain units", kFlowLimit, [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(ca);
          p.numerics.max_strain = 3.0;
          return run_flow_case(p);
        });
  }
  for (double ca : {0.005, 0.003, 0.001}) {
    add(cases, "flow/stiffness/lifted-limit-ca" + number_text(ca, 4),
        "max_stiffness_ratio 100, 2 strain units", kFlowLimit, [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(ca);
          p.numerics.max_stiffness_ratio = 100.0;
          p.numerics.max_strain = 2.0;
          return run_flow_case(p);
        });
  }
  // The time step: dt = nu_lb dx^2 / nu with nu_lb = (tau - 1/2) / 3, and the
  // raised density sets Re_p (steps per strain ~ 1 / (Re nu_lb)).
  for (double tau : {0.55, 0.6, 2.0, 3.0}) {
    add(cases, "flow/timestep/tau" + number_text(tau, 4), "Ca 0.2, 3 strain units", kFlowLimit,
        [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(0.2);
          p.numerics.relaxation_time = tau;
          p.numerics.max_strain = 3.0;
          return run_flow_case(p);
        });
  }
  for (double re : {0.01, 0.3, 0.5, 1.0}) {
    add(cases, "flow/timestep/reynolds" + number_text(re, 4), "Ca 0.2, target Re_p " + number_text(re, 4),
        kFlowLimit, [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(0.2);
          p.numerics.target_reynolds_number = re;
          p.numerics.max_strain = re < 0.05 ? 0.5 : 3.0;
          return run_flow_case(p);
        });
  }
  // Kernels (each has its own calibrated stiffness limit) and precision.
  for (const char* kernel : {"peskin3", "trilinear"}) {
    add(cases, std::string("flow/kernel/") + kernel, "Ca 0.2, 3 strain units", kFlowLimit,
        [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(0.2);
          p.numerics.ibm_kernel = *ibm::parse_kernel(kernel);
          p.numerics.max_strain = 3.0;
          return run_flow_case(p);
        });
  }
  add(cases, "flow/precision/double-ca1.6", "double lattice, Ca 1.6", kFlowLimit, [](const CaseContext&) {
    scenes::ShearFlowParams p = flow(1.6);
    p.numerics.single_precision = false;
    return run_flow_case(p);
  });
  // Very soft and very stiff cells, at fixed Ca (same dimensionless problem
  // unless the physical Reynolds number takes over) and at a fixed shear rate.
  for (double e : {1e3, 1e5}) {
    add(cases, "flow/modulus/E" + number_text(e, 4) + "-ca0.2", "fixed Ca 0.2", kFlowLimit,
        [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(0.2);
          p.cell.material.youngs_modulus_pa = e;
          return run_flow_case(p);
        });
  }
  for (double e : {1.0, 1e5}) {
    add(cases, "flow/modulus/E" + number_text(e, 4) + "-rate10", "fixed shear rate 10/s", kFlowLimit,
        [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(0.0);
          p.cell.material.youngs_modulus_pa = e;
          p.capillary_number = 0.0;
          p.shear_rate_per_s = 10.0;
          p.numerics.max_strain = 3.0;
          return run_flow_case(p);
        });
  }
  // Materials.
  add(cases, "flow/material/nu0.499-ca0.2", "nearly incompressible", kFlowLimit, [](const CaseContext&) {
    scenes::ShearFlowParams p = flow(0.2);
    p.cell.material.poisson_ratio = 0.499;
    return run_flow_case(p);
  });
  add(cases, "flow/material/w0.25-ca1", "Mooney-Rivlin w 0.25, Ca 1", kFlowLimit, [](const CaseContext&) {
    scenes::ShearFlowParams p = flow(1.0);
    p.cell.material.mooney_rivlin_w = 0.25;
    return run_flow_case(p);
  });
  // Poor meshes in flow.
  for (double ca : {0.2, 1.6}) {
    add(cases, "flow/mesh/coarse200-ca" + number_text(ca, 4), "200-vertex sphere", kFlowLimit,
        [=](const CaseContext&) {
          scenes::ShearFlowParams p = flow(ca);
          p.cell.target_vertex_count = 200;
          return run_flow_case(p);
        });
  }
  add(cases, "flow/mesh/slivers-ca0.2", "500-vertex sphere with flattened tets (.msh)", kFlowLimit,
      [](const CaseContext& ctx) {
        const std::string path = ctx.work_dir + "/slivers_flow.msh";
        StatusOr<mesh::MeshQuality> q = write_sliver_mesh(path, kFlowRadius, 500, 11);
        if (!q.ok()) return failed_or_converged(q.status(), "writing the sliver mesh");
        scenes::ShearFlowParams p = flow(0.2);
        p.cell.mesh_file = path;
        return run_flow_case(p, "min dihedral " + number_text(q->min_dihedral_deg, 4) + " deg; ");
      });
  add(cases, "flow/mesh/slivers-lifted-limit-ca0.2", "sliver mesh past the stiffness limit (ratio 100)",
      kFlowLimit, [](const CaseContext& ctx) {
        const std::string path = ctx.work_dir + "/slivers_flow_lifted.msh";
        StatusOr<mesh::MeshQuality> q = write_sliver_mesh(path, kFlowRadius, 500, 11);
        if (!q.ok()) return failed_or_converged(q.status(), "writing the sliver mesh");
        scenes::ShearFlowParams p = flow(0.2);
        p.cell.mesh_file = path;
        p.numerics.max_stiffness_ratio = 100.0;
        return run_flow_case(p, "min dihedral " + number_text(q->min_dihedral_deg, 4) + " deg; ");
      });
  add(cases, "flow/resolution/cpr3-ca0.4", "3 cells per radius, box 8x6x4 R", kFlowLimit,
      [](const CaseContext&) {
        scenes::ShearFlowParams p = flow(0.4);
        p.numerics.cells_per_radius = 3.0;
        p.numerics.box_x_radii = 8.0;
        p.numerics.box_y_radii = 6.0;
        p.numerics.box_z_radii = 4.0;
        return run_flow_case(p);
      });

  if (include_self_tests) {
    // The harness's own checks: each must be reported as what it is.
    add(cases, "selftest/hang", "sleeps past any limit", 2.0, [](const CaseContext&) {
      while (true) std::this_thread::sleep_for(std::chrono::seconds(1));
      return CaseResult{};
    });
    add(cases, "selftest/crash", "raises SIGSEGV", 30.0, [](const CaseContext&) {
      raise(SIGSEGV);
      return CaseResult{};
    });
    add(cases, "selftest/wrong", "a NaN force on a curve with an ok status", 30.0, [](const CaseContext&) {
      scenes::CompressionParams p = compression(kDefaultE, 0.48, 1.0, 200, 0.2, 2);
      scenes::QuasiStaticResult r;
      r.curve.resize(2);
      for (int i = 0; i < 2; ++i) {
        r.curve[i].index = i;
        r.curve[i].deformation = 0.1 * (i + 1);
        r.curve[i].force_n = i == 0 ? 1e-9 : std::numeric_limits<double>::quiet_NaN();
        r.curve[i].hertz_force_n = 1e-9;
      }
      if (std::optional<std::string> bad = check_compression(p, r, {}))
        return wrong(*bad, "fabricated curve");
      return failed_or_converged(Status::ok_status(), "fabricated curve passed the checks");
    });
    add(cases, "selftest/unnamed-failure", "an internal error with no recognised cause", 30.0,
        [](const CaseContext&) { return failed_or_converged(Status(StatusCode::kInternal, "boom"), ""); });
  }
  return cases;
}

}  // namespace cellflow::stability
