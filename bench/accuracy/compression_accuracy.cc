#include "bench/accuracy/compression_accuracy.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "bench/accuracy/accuracy_metrics.h"
#include "bench/accuracy/accuracy_report.h"
#include "physics/contact/rigid_contact.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::bench {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// One point of the sweep space.
struct Setting {
  int vertices = 0;
  int load_points = 0;
  double tolerance = 0.0;
  double contact_factor = 1.0;
  auto tie() const { return std::tie(vertices, load_points, tolerance, contact_factor); }
  bool operator<(const Setting& o) const { return tie() < o.tie(); }
  std::string key() const {
    std::ostringstream s;
    s << vertices << '/' << load_points << '/' << tolerance << '/' << contact_factor;
    return s.str();
  }
};

struct Run {
  bool ok = false;
  std::string status = "ok";
  double wall_s = 0.0, cpu_s = 0.0;
  int newton = 0;
  std::vector<double> grid_forces;  // NaN where the curve did not reach
};

struct MeshInfo {
  int vertices = 0;  // actual
  double mean_edge_m = 0.0;
  double default_stiffness_n_per_m = 0.0;
};

cell::CellParams issue_cell(int target_vertices) {
  cell::CellParams cell;
  cell.radius_m = 8.6e-6;
  cell.material = {.youngs_modulus_pa = 150.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 0.5};
  cell.target_vertex_count = target_vertices;
  return cell;
}

class Runner {
 public:
  explicit Runner(const CompressionSweep& sweep) : sweep_(sweep) {}

  const MeshInfo& mesh(int target) {
    auto it = meshes_.find(target);
    if (it != meshes_.end()) return it->second;
    MeshInfo info;
    const cell::CellParams cell = issue_cell(target);
    auto m = cell::build_cell_mesh(cell);
    if (m.ok()) {
      const mesh::MeshQuality q = mesh::mesh_quality(*m);
      info.vertices = static_cast<int>(q.num_vertices);
      info.mean_edge_m = q.mean_edge_length_m;
      info.default_stiffness_n_per_m =
          contact::default_penalty(cell.material.youngs_modulus_pa, cell.radius_m, q.mean_edge_length_m)
              .stiffness_n_per_m;
    }
    return meshes_.emplace(target, info).first->second;
  }

  const Run& run(const Setting& s) {
    auto it = runs_.find(s);
    if (it != runs_.end()) return it->second;
    scenes::CompressionParams p;
    p.cell = issue_cell(s.vertices);
    p.max_deformation = sweep_.max_deformation;
    p.load_points = s.load_points;
    p.numerics.residual_tolerance = s.tolerance;
    p.numerics.threads = sweep_.threads;
    // factor 1 leaves the field unset: the scene's own default path
    if (s.contact_factor != 1.0)
      p.numerics.contact_stiffness_n_per_m = s.contact_factor * mesh(s.vertices).default_stiffness_n_per_m;

    std::fprintf(stderr, "run vertices=%d load_points=%d tolerance=%g contact x%g ... ", s.vertices,
                 s.load_points, s.tolerance, s.contact_factor);
    std::fflush(stderr);
    Run r;
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    const scenes::QuasiStaticResult result = scenes::run_compression(p);
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    r.cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    r.ok = result.status.ok();
    if (!r.ok) r.status = "FAILED: " + result.status.to_string();
    std::vector<double> deformation, force;
    for (const auto& point : result.curve) {
      deformation.push_back(point.deformation);
      force.push_back(point.force_n);
      r.newton += point.newton_iterations;
    }
    r.grid_forces = forces_on_grid(deformation, force, sweep_.grid);
    std::fprintf(stderr, "%.2f s wall, %.2f s CPU, %s\n", r.wall_s, r.cpu_s, r.status.c_str());
    return runs_.emplace(s, std::move(r)).first->second;
  }

 private:
  const CompressionSweep& sweep_;
  std::map<int, MeshInfo> meshes_;
  std::map<Setting, Run> runs_;
};

bool covers_grid(const Run& r) {
  for (double f : r.grid_forces)
    if (!std::isfinite(f)) return false;
  return true;
}

std::string vector_text(const std::vector<double>& v, const char* fmt) {
  std::ostringstream s;
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? ", " : "") << number_text(v[i], fmt);
  return s.str();
}

}  // namespace

CompressionSweep compression_sweep(bool coarse) {
  CompressionSweep s;
  if (coarse) {
    s.vertex_counts = {300, 500, 800};
    s.load_points = {5, 10};
    s.tolerances = {1e-4, 1e-6};
    s.contact_factors = {1.0, 4.0};
    s.default_vertices = 500;
    s.default_load_points = 10;
    s.max_deformation = 0.6;
    s.grid = uniform_grid(0.1, 0.6, 0.1);
  } else {
    s.vertex_counts = {500, 1000, 2000, 3000, 6000, 12000};
    s.load_points = {10, 20, 40, 80};
    s.tolerances = {1e-4, 1e-6, 1e-8};
    s.contact_factors = {0.25, 1.0, 4.0};
    s.max_deformation = 0.6;
    s.grid = uniform_grid(0.1, 0.6, 0.1);
  }
  return s;
}

Status run_compression_accuracy(const CompressionSweep& sweep, const std::string& out_dir, bool coarse) {
  if (sweep.vertex_counts.size() < 3)
    return Status(StatusCode::kInvalidArgument, "the vertex sweep needs at least three meshes");
  const auto wall_start = std::chrono::steady_clock::now();
  Runner runner(sweep);
  const Setting base{sweep.default_vertices, sweep.default_load_points, sweep.default_tolerance, 1.0};

  // Vertex sweep and its reference: Richardson from the three finest meshes.
  const std::vector<Setting> vertex_settings = vary(base, &Setting::vertices, sweep.vertex_counts);
  for (const Setting& s : vertex_settings) runner.run(s);
  const std::size_t nv = vertex_settings.size();
  const Run& f1 = runner.run(vertex_settings[nv - 1]);
  const Run& f2 = runner.run(vertex_settings[nv - 2]);
  const Run& f3 = runner.run(vertex_settings[nv - 3]);
  const auto h_of = [&](int target) { return std::cbrt(1.0 / runner.mesh(target).vertices); };
  std::vector<double> mesh_reference;
  std::string reference_note;
  Richardson rich;
  if (covers_grid(f1) && covers_grid(f2) && covers_grid(f3)) {
    rich = richardson_extrapolate(h_of(sweep.vertex_counts[nv - 1]), h_of(sweep.vertex_counts[nv - 2]),
                                  h_of(sweep.vertex_counts[nv - 3]), f1.grid_forces, f2.grid_forces,
                                  f3.grid_forces);
    mesh_reference = rich.extrapolated;
    char buffer[256];
    std::snprintf(buffer, sizeof buffer,
                  "observed order p = %.3f (difference ratio S = %.4f; nan: no p in (0, 20] fits) from the "
                  "meshes of %d, %d and %d "
                  "vertices; ",
                  rich.order, rich.difference_ratio, runner.mesh(sweep.vertex_counts[nv - 3]).vertices,
                  runner.mesh(sweep.vertex_counts[nv - 2]).vertices,
                  runner.mesh(sweep.vertex_counts[nv - 1]).vertices);
    reference_note = buffer;
    reference_note += rich.usable
                          ? "p is in (0.5, 4): the reference is the Richardson extrapolation."
                          : "p is NOT in (0.5, 4): the reference is the finest mesh, not extrapolated.";
  } else if (covers_grid(f1)) {
    mesh_reference = f1.grid_forces;
    reference_note =
        "one of the three finest meshes did not reach the end of the grid: the reference is the "
        "finest mesh, not extrapolated.";
  } else {
    return Status(StatusCode::kNumericalFailure, "the finest mesh did not reach deformation " +
                                                     std::to_string(sweep.grid.back()) + ": " + f1.status);
  }

  std::vector<AccuracyRow> rows;
  const auto add_row = [&](const std::string& sweep_name, const Setting& s, const std::string& value,
                           double numeric, const std::vector<double>& reference, bool is_reference) {
    const Run& r = runner.run(s);
    AccuracyRow row;
    row.sweep = sweep_name;
    row.value = value;
    row.numeric_value = numeric;
    row.is_default = !(s < base) && !(base < s);
    row.is_reference = is_reference;
    row.wall_s = r.wall_s;
    row.cpu_s = r.cpu_s;
    row.iterations = r.newton;
    row.error = max_relative_error(r.grid_forces, reference);
    row.total_error = max_relative_error(r.grid_forces, mesh_reference);
    row.status = r.status;
    row.run_key = s.key();
    rows.push_back(row);
  };

  const bool extrapolated = rich.usable;
  for (std::size_t i = 0; i < nv; ++i) {
    const int target = sweep.vertex_counts[i];
    add_row("vertices", vertex_settings[i],
            std::to_string(target) + " (" + std::to_string(runner.mesh(target).vertices) + ")", target,
            mesh_reference, !extrapolated && i + 1 == nv);
  }
  // One factor at a time; the last setting of each list is its sweep's reference.
  const auto one_factor = [&](const std::string& name, const std::vector<Setting>& settings, auto&& value_of,
                              auto&& numeric_of) {
    const Run& ref = runner.run(settings.back());
    for (std::size_t i = 0; i < settings.size(); ++i) {
      runner.run(settings[i]);
      add_row(name, settings[i], value_of(i), numeric_of(i), ref.grid_forces, i + 1 == settings.size());
    }
  };
  one_factor(
      "load_points", vary(base, &Setting::load_points, sweep.load_points),
      [&](std::size_t i) { return std::to_string(sweep.load_points[i]); },
      [&](std::size_t i) { return static_cast<double>(sweep.load_points[i]); });
  one_factor(
      "tolerance", vary(base, &Setting::tolerance, sweep.tolerances),
      [&](std::size_t i) { return number_text(sweep.tolerances[i], "%.0e"); },
      [&](std::size_t i) { return sweep.tolerances[i]; });
  const double default_stiffness = runner.mesh(sweep.default_vertices).default_stiffness_n_per_m;
  one_factor(
      "contact_stiffness", vary(base, &Setting::contact_factor, sweep.contact_factors),
      [&](std::size_t i) {
        char buffer[64];
        std::snprintf(buffer, sizeof buffer, "x%g (%.3g N/m)", sweep.contact_factors[i],
                      sweep.contact_factors[i] * default_stiffness);
        return std::string(buffer);
      },
      [&](std::size_t i) { return sweep.contact_factors[i]; });

  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  double default_total_error = kNaN, default_wall_s = kNaN;
  for (const auto& r : rows)
    if (r.is_default) {
      default_total_error = r.total_error;
      default_wall_s = r.wall_s;
    }

  std::ostringstream md;
  md << "# Compression: run time against force error" << (coarse ? " (coarse CI size)" : "") << "\n\n";
  md << "Generated by `cellflow-bench accuracy compression" << (coarse ? " --coarse" : "")
     << "` (bench/accuracy). The issue's curve: R = 8.6 um, E = 150 Pa, nu = 0.48, w = 0.5, deformation 0 to "
     << sweep.max_deformation << ", " << sweep.threads
     << " thread(s). One setting moves at a time around the "
     << "default (" << sweep.default_vertices << " vertices, " << sweep.default_load_points
     << " load points, residual tolerance " << sweep.default_tolerance << ", default contact stiffness).\n\n";
  md << "- **error**: the largest relative force error at deformations " << vector_text(sweep.grid, "%.2g")
     << " (forces interpolated linearly in deformation) against the reference of the row's sweep: for the "
     << "vertex count the mesh reference below, for the others the sweep's finest setting.\n";
  md << "- **total error**: the same against the mesh reference, for every row.\n";
  md << "- Mesh reference (h = N^-1/3, N the actual vertex count): " << reference_note << "\n";
  if (!rich.pointwise_order.empty())
    md << "- Observed order at each grid deformation: " << vector_text(rich.pointwise_order, "%.2f")
       << " (nan: no order in (0, 20] fits there: the differences change sign, or grow as h shrinks).\n";
  md << "- Reference forces [nN]: ";
  {
    std::vector<double> nano;
    for (double f : mesh_reference) nano.push_back(f * 1e9);
    md << vector_text(nano, "%.4f") << "\n";
  }
  std::set<std::string> distinct_runs;
  for (const auto& r : rows) distinct_runs.insert(r.run_key);
  char buffer[256];
  std::snprintf(buffer, sizeof buffer,
                "- The default setting: total error %.3e (%.2f %%) in %.2f s wall time.\n",
                default_total_error, 100.0 * default_total_error, default_wall_s);
  md << buffer;
  std::snprintf(buffer, sizeof buffer,
                "- Whole sweep: %.1f s wall time (%zu distinct runs; wall times on a "
                "shared machine include waiting, the CSV also has the process CPU time).\n",
                total_s, distinct_runs.size());
  md << buffer;
  md << "- Plot: compression.svg (total error against wall time; Pareto front boxed, default ringed).\n\n";
  // Where along the curve the mesh error sits: the forces of each mesh and
  // their deviation from the reference at every grid deformation.
  md << "## Mesh sweep along the curve\n\n| actual vertex count |";
  for (double d : sweep.grid) md << " F(" << number_text(d, "%.2g") << ") [nN] |";
  md << "\n|---|";
  for (std::size_t j = 0; j < sweep.grid.size(); ++j) md << "---|";
  md << "\n";
  for (std::size_t i = 0; i < nv; ++i) {
    const Run& r = runner.run(vertex_settings[i]);
    md << "| " << runner.mesh(sweep.vertex_counts[i]).vertices << " |";
    for (std::size_t j = 0; j < sweep.grid.size(); ++j)
      md << " " << number_text(1e9 * r.grid_forces[j], "%.4f") << " ("
         << number_text(100.0 * (r.grid_forces[j] / mesh_reference[j] - 1.0), "%+.2f") << " %) |";
    md << "\n";
  }
  md << "\n## Sweeps";

  std::filesystem::create_directories(out_dir);
  const std::string stem = (std::filesystem::path(out_dir) / "compression").string();
  if (Status s = write_csv(stem + ".csv", rows); !s.ok()) return s;
  if (Status s = write_markdown(stem + ".md", md.str(), rows); !s.ok()) return s;
  if (Status s =
          write_svg(stem + ".svg", "Compression (R = 8.6 um, E = 150 Pa): total force error vs time", rows);
      !s.ok())
    return s;
  std::fprintf(stderr, "wrote %s.{csv,md,svg} in %.1f s\n", stem.c_str(), total_s);
  return Status();
}

}  // namespace cellflow::bench
