#include "bench/accuracy/shear_flow_accuracy.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bench/accuracy/accuracy_metrics.h"
#include "bench/accuracy/accuracy_report.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::bench {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// One point of the sweep space.
struct Setting {
  double cells_per_radius = 0.0;
  int vertices = 0;
  ibm::Kernel kernel = ibm::Kernel::kPeskin4;
  bool single_precision = true;
  double radius_offset = 0.0;  // hydrodynamic_radius_offset, lattice spacings (0: none)
  auto tie() const { return std::tie(cells_per_radius, vertices, kernel, single_precision, radius_offset); }
  bool operator<(const Setting& o) const { return tie() < o.tie(); }
  bool operator==(const Setting& o) const { return tie() == o.tie(); }
  std::string key() const {
    std::ostringstream s;
    s << cells_per_radius << " cells/R, " << vertices << " vertices, " << ibm::kernel_name(kernel) << ", "
      << (single_precision ? "float" : "double") << ", offset " << radius_offset << " dx";
    return s.str();
  }
};

struct Run {
  bool ok = false;
  bool measured_now = false;  // run by this invocation, not reused from the run log
  std::string status = "ok";
  double wall_s = 0.0, cpu_s = 0.0;
  long long time_steps = 0;
  double taylor_deformation = kNaN;
  double inclination_deg = kNaN;
  double tank_treading_over_shear_rate = kNaN;
  double final_strain = 0.0;
  std::string stop;
  int actual_vertices = 0;
};

// The bench cell of bench/shear_flow and the validation tests: R = 6 um,
// E = 10 Pa, nu = 0.48, in water; Ca sets the shear rate.
scenes::ShearFlowParams bench_params(const ShearFlowSweep& sweep, const Setting& s) {
  scenes::ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = s.vertices;
  p.capillary_number = sweep.capillary_number;
  scenes::ShearFlowNumerics& n = p.numerics;
  n.cells_per_radius = s.cells_per_radius;
  n.ibm_kernel = s.kernel;
  n.single_precision = s.single_precision;
  n.hydrodynamic_radius_offset = s.radius_offset;
  n.steady_tolerance = sweep.steady_tolerance;
  n.steady_window_strain = sweep.steady_window_strain;
  n.max_strain = sweep.max_strain;
  n.threads = sweep.threads;
  return p;
}

// The run log: one tab-separated line per finished run, with the sweep
// parameters every run shares, so that a resumed sweep reuses only runs of
// the same Ca and stop rule. The radius offset is the last field (lines
// written before it existed have none: those runs had no offset).
std::string log_line(const ShearFlowSweep& sweep, const Setting& s, const Run& r) {
  std::ostringstream out;
  out.precision(17);
  out << sweep.capillary_number << '\t' << sweep.steady_tolerance << '\t' << sweep.steady_window_strain
      << '\t' << sweep.max_strain << '\t' << sweep.threads << '\t' << s.cells_per_radius << '\t' << s.vertices
      << '\t' << ibm::kernel_name(s.kernel) << '\t' << (s.single_precision ? 1 : 0) << '\t' << (r.ok ? 1 : 0)
      << '\t' << r.wall_s << '\t' << r.cpu_s << '\t' << r.time_steps << '\t' << r.taylor_deformation << '\t'
      << r.inclination_deg << '\t' << r.tank_treading_over_shear_rate << '\t' << r.final_strain << '\t'
      << r.stop << '\t' << r.status << '\t' << s.radius_offset << '\n';
  return out.str();
}

class Runner {
 public:
  Runner(const ShearFlowSweep& sweep, std::string log_path) : sweep_(sweep), log_path_(std::move(log_path)) {
    if (sweep_.resume) load();
    std::ofstream(log_path_, sweep_.resume ? std::ios::app : std::ios::trunc);
  }

  const Run& run(const Setting& s) {
    auto it = runs_.find(s);
    if (it != runs_.end()) return it->second;
    std::fprintf(stderr, "run %s ... ", s.key().c_str());
    std::fflush(stderr);
    Run r;
    r.measured_now = true;
    const std::clock_t cpu_start = std::clock();
    const scenes::ShearFlowResult result = scenes::run_shear_flow(bench_params(sweep_, s));
    r.cpu_s = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    r.wall_s = result.wall_time_s;
    r.ok = result.status.ok();
    r.stop = std::string(scenes::stop_name(result.stop));
    if (!r.ok) r.status = "FAILED: " + result.status.to_string();
    r.time_steps = static_cast<long long>(result.time_steps);
    if (!result.samples.empty()) r.final_strain = result.samples.back().strain_units;
    if (r.ok) {
      r.taylor_deformation = result.steady_taylor_deformation;
      r.inclination_deg = result.steady_inclination_deg;
      r.tank_treading_over_shear_rate = result.tank_treading_frequency_per_s / result.setup.shear_rate_per_s;
    }
    std::fprintf(stderr, "%.1f s wall, D %.5f, stop %s at strain %.2f, %s\n", r.wall_s, r.taylor_deformation,
                 r.stop.c_str(), r.final_strain, r.status.c_str());
    std::ofstream(log_path_, std::ios::app) << log_line(sweep_, s, r);
    return runs_.emplace(s, std::move(r)).first->second;
  }

  const std::map<Setting, Run>& runs() const { return runs_; }
  int reused() const { return reused_; }

 private:
  // Runs of an earlier sweep with the same Ca, stop rule and threads.
  void load() {
    std::ifstream in(log_path_);
    std::string line;
    while (std::getline(in, line)) {
      std::vector<std::string> f;
      std::istringstream fields(line);
      for (std::string x; std::getline(fields, x, '\t');) f.push_back(x);
      if (f.size() < 18) continue;
      const auto number = [&](int i) { return std::strtod(f[i].c_str(), nullptr); };
      if (number(0) != sweep_.capillary_number || number(1) != sweep_.steady_tolerance ||
          number(2) != sweep_.steady_window_strain || number(3) != sweep_.max_strain ||
          static_cast<int>(number(4)) != sweep_.threads)
        continue;
      StatusOr<ibm::Kernel> kernel = ibm::parse_kernel(f[7]);
      if (!kernel.ok()) continue;
      const Setting s{number(5), static_cast<int>(number(6)), *kernel, f[8] == "1",
                      f.size() > 19 ? number(19) : 0.0};
      Run r;
      r.ok = f[9] == "1";
      r.wall_s = number(10);
      r.cpu_s = number(11);
      r.time_steps = std::strtoll(f[12].c_str(), nullptr, 10);
      r.taylor_deformation = number(13);
      r.inclination_deg = number(14);
      r.tank_treading_over_shear_rate = number(15);
      r.final_strain = number(16);
      r.stop = f[17];
      r.status = f.size() > 18 ? f[18] : "";
      if (runs_.insert_or_assign(s, r).second) ++reused_;
    }
    std::fprintf(stderr, "reusing %d runs recorded in %s\n", reused_, log_path_.c_str());
  }

  const ShearFlowSweep& sweep_;
  std::string log_path_;
  std::map<Setting, Run> runs_;
  int reused_ = 0;
};

double relative_error(double value, double reference) {
  if (!std::isfinite(value) || !std::isfinite(reference) || reference == 0.0) return kNaN;
  return std::abs(value / reference - 1.0);
}

}  // namespace

ShearFlowSweep shear_flow_sweep(bool coarse) {
  const scenes::ShearFlowNumerics defaults;
  ShearFlowSweep s;
  s.default_cells_per_radius = defaults.cells_per_radius;
  s.default_vertices = scenes::kFlowDefaultVertexCount;
  s.default_kernel = defaults.ibm_kernel;
  s.default_single_precision = defaults.single_precision;
  s.default_radius_offset = scenes::radius_offset(defaults);
  // The old default (no correction) for comparison; the last is the reference.
  s.radius_offsets = {0.0, s.default_radius_offset};
  s.steady_tolerance = defaults.steady_tolerance;
  s.steady_window_strain = defaults.steady_window_strain;
  s.max_strain = defaults.max_strain;
  s.kernels = {ibm::Kernel::kTrilinear, ibm::Kernel::kPeskin3, ibm::Kernel::kPeskin4};
  s.single_precision = {true, false};
  if (coarse) {
    // Seconds: a small mesh on coarse lattices, one strain unit at most.
    s.cells_per_radius = {3.0, 4.0, 5.0};
    s.vertex_counts = {300, 600};
    // trilinear is refused at this time step (stiffness limit 0.05): peskin3 instead
    s.kernels = {ibm::Kernel::kPeskin3, ibm::Kernel::kPeskin4};
    s.default_cells_per_radius = 4.0;
    s.default_vertices = 300;
    s.steady_window_strain = 0.5;
    s.max_strain = 1.0;
  } else {
    s.cells_per_radius = {4.0, 6.0, 8.0, 10.0, 12.0};
    s.vertex_counts = {1000, 3000, 8000};
  }
  return s;
}

Status run_shear_flow_accuracy(const ShearFlowSweep& requested, const std::string& out_dir, bool coarse) {
  ShearFlowSweep sweep = requested;
  if (sweep.max_cells_per_radius > 0.0) {
    std::erase_if(sweep.cells_per_radius, [&](double c) { return c > sweep.max_cells_per_radius; });
  }
  if (sweep.cells_per_radius.size() < 3)
    return Status(StatusCode::kInvalidArgument, "the resolution sweep needs at least three lattices");
  if (sweep.vertex_counts.empty() || sweep.kernels.empty() || sweep.single_precision.empty())
    return Status(StatusCode::kInvalidArgument, "every sweep needs at least one value");
  const auto wall_start = std::chrono::steady_clock::now();
  std::filesystem::create_directories(out_dir);
  Runner runner(sweep, (std::filesystem::path(out_dir) / "shear_flow_runs.tsv").string());
  const Setting base{sweep.default_cells_per_radius, sweep.default_vertices, sweep.default_kernel,
                     sweep.default_single_precision, sweep.default_radius_offset};
  const double small_ca_d = scenes::small_ca_taylor_deformation(sweep.capillary_number);

  // Resolution sweep and its reference: Richardson in dx / R = 1 / cpr from
  // the three finest lattices.
  const std::vector<Setting> lattice_settings =
      vary(base, &Setting::cells_per_radius, sweep.cells_per_radius);
  const std::vector<Setting> vertex_settings = vary(base, &Setting::vertices, sweep.vertex_counts);
  std::vector<Setting> kernel_settings = vary(base, &Setting::kernel, sweep.kernels);
  // Each kernel with its own calibrated offset (the scene's default for it).
  for (Setting& s : kernel_settings) s.radius_offset = scenes::default_radius_offset(s.kernel);
  const std::vector<Setting> precision_settings =
      vary(base, &Setting::single_precision, sweep.single_precision);
  const std::vector<Setting> offset_settings = vary(base, &Setting::radius_offset, sweep.radius_offsets);
  {
    // Cheapest first (the cost grows with the lattice), so that an
    // interrupted sweep leaves the most runs in the log for --resume.
    std::vector<Setting> all;
    const std::vector<Setting>* lists[] = {&lattice_settings, &vertex_settings, &kernel_settings,
                                           &precision_settings, &offset_settings};
    for (const std::vector<Setting>* list : lists) all.insert(all.end(), list->begin(), list->end());
    std::stable_sort(all.begin(), all.end(), [](const Setting& a, const Setting& b) {
      return a.cells_per_radius < b.cells_per_radius;
    });
    for (const Setting& s : all) runner.run(s);
  }
  const std::size_t nl = lattice_settings.size();
  const Run& d1 = runner.run(lattice_settings[nl - 1]);
  const Run& d2 = runner.run(lattice_settings[nl - 2]);
  const Run& d3 = runner.run(lattice_settings[nl - 3]);
  if (!d1.ok)
    return Status(StatusCode::kNumericalFailure,
                  "the finest lattice (" + lattice_settings[nl - 1].key() + ") failed: " + d1.status);
  // The reference: 5/4 Ca where Roscoe's small-Ca limit applies, else the
  // finest lattice. Richardson in dx is reported, not used (header).
  const bool analytic_reference = sweep.capillary_number <= kSmallCaLimit;
  const double reference_d = analytic_reference ? small_ca_d : d1.taylor_deformation;
  std::string reference_note =
      analytic_reference ? "Roscoe's small-Ca limit 5/4 Ca (Ca <= " + number_text(kSmallCaLimit, "%g") + ")."
                         : "the finest lattice (" + lattice_settings[nl - 1].key() + ").";
  std::string richardson_note;
  Richardson rich;
  if (d2.ok && d3.ok) {
    const double f1[1] = {d1.taylor_deformation}, f2[1] = {d2.taylor_deformation},
                 f3[1] = {d3.taylor_deformation};
    rich = richardson_extrapolate(1.0 / sweep.cells_per_radius[nl - 1], 1.0 / sweep.cells_per_radius[nl - 2],
                                  1.0 / sweep.cells_per_radius[nl - 3], f1, f2, f3);
    char buffer[256];
    std::snprintf(
        buffer, sizeof buffer,
        "observed order p = %.3f (difference ratio S = %.4f; nan: no p in (0, 20] fits) from %g, %g "
        "and %g cells per radius; ",
        rich.order, rich.difference_ratio, sweep.cells_per_radius[nl - 3], sweep.cells_per_radius[nl - 2],
        sweep.cells_per_radius[nl - 1]);
    richardson_note = buffer;
    richardson_note += "extrapolated D = " + number_text(rich.extrapolated[0], "%.5f") +
                       (rich.usable ? "" : " (no usable order: the finest D)") +
                       ". Not used as a reference: at a fixed vertex count the mesh spacing grows against dx "
                       "as the lattice is refined, so D(dx) has no continuum limit.";
  } else {
    richardson_note = "one of the three finest lattices failed: no extrapolation.";
  }

  std::vector<AccuracyRow> rows;
  const auto add_row = [&](const std::string& sweep_name, const Setting& s, const std::string& value,
                           double numeric, double sweep_reference_d, bool is_reference) {
    const Run& r = runner.run(s);
    AccuracyRow row;
    row.sweep = sweep_name;
    row.value = value;
    row.numeric_value = numeric;
    row.is_default = s == base;
    row.is_reference = is_reference;
    row.wall_s = r.wall_s;
    row.cpu_s = r.cpu_s;
    row.iterations = r.time_steps;
    row.result = r.taylor_deformation;
    row.error = relative_error(r.taylor_deformation, sweep_reference_d);
    row.total_error = relative_error(r.taylor_deformation, reference_d);
    row.analytic_error = relative_error(r.taylor_deformation, small_ca_d);
    row.status = r.ok ? r.stop + " at strain " + number_text(r.final_strain, "%.1f") : r.status;
    row.run_key = s.key();
    rows.push_back(row);
  };

  for (std::size_t i = 0; i < nl; ++i)
    add_row("cells_per_radius", lattice_settings[i], number_text(sweep.cells_per_radius[i], "%g"),
            sweep.cells_per_radius[i], d1.taylor_deformation, i + 1 == nl);
  // One factor at a time; the last setting of each list is its sweep's reference.
  const auto one_factor = [&](const std::string& name, const std::vector<Setting>& settings, auto&& value_of,
                              auto&& numeric_of) {
    const Run& ref = runner.run(settings.back());
    for (std::size_t i = 0; i < settings.size(); ++i) {
      runner.run(settings[i]);
      add_row(name, settings[i], value_of(i), numeric_of(i), ref.taylor_deformation,
              i + 1 == settings.size());
    }
  };
  one_factor(
      "vertices", vertex_settings, [&](std::size_t i) { return std::to_string(sweep.vertex_counts[i]); },
      [&](std::size_t i) { return static_cast<double>(sweep.vertex_counts[i]); });
  one_factor(
      "kernel", kernel_settings,
      [&](std::size_t i) { return std::string(ibm::kernel_name(sweep.kernels[i])); },
      [&](std::size_t i) { return ibm::kernel_width(sweep.kernels[i]); });
  one_factor(
      "precision", precision_settings,
      [&](std::size_t i) { return std::string(sweep.single_precision[i] ? "float" : "double"); },
      [&](std::size_t i) { return sweep.single_precision[i] ? 4.0 : 8.0; });
  one_factor(
      "hydrodynamic_radius_offset", offset_settings,
      [&](std::size_t i) {
        return number_text(sweep.radius_offsets[i], "%g") +
               (sweep.radius_offsets[i] == 0.0 ? " (old default)" : "");
      },
      [&](std::size_t i) { return sweep.radius_offsets[i]; });

  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const Run& default_run = runner.run(base);

  std::ostringstream md;
  md << "# Shear flow: run time against the error of the steady Taylor deformation"
     << (coarse ? " (coarse CI size)" : "") << "\n\n";
  md << "Generated by `cellflow-bench accuracy shear_flow" << (coarse ? " --coarse" : "")
     << (sweep.max_cells_per_radius > 0.0
             ? " --max-cells-per-radius " + number_text(sweep.max_cells_per_radius, "%g")
             : std::string())
     << (sweep.cpu_time_axis ? " --cpu-time" : "")
     << "` (bench/accuracy). One cell (R = 6 um, E = 10 Pa, nu = 0.48, lambda = 1) in the default box "
     << "(10 x 15 x 5 R) at Ca = " << sweep.capillary_number
     << ", run until D is steady (the means of D over two consecutive windows of "
     << sweep.steady_window_strain << " strain units differ by less than " << sweep.steady_tolerance
     << " and the slope over the last stays below 3 of that; at most " << sweep.max_strain
     << " strain units), " << sweep.threads << " thread(s). One setting moves at a time around the default ("
     << base.key() << ").\n\n";
  md << "- **steady D**: mean Taylor deformation over the last steady window.\n";
  md << "- **error**: |D / D_ref - 1| against the finest setting of the row's sweep.\n";
  md << "- **total error**: the same against the sweep's reference, for every row: " << reference_note
     << " Reference D = " << number_text(reference_d, "%.5f") << ".\n";
  md << "- Resolution sweep, Richardson in dx / R: " << richardson_note << "\n";
  md << "- **error vs 5/4 Ca**: against Roscoe's small-Ca limit D = 5/4 Ca = "
     << number_text(small_ca_d, "%.5f") << " (Roscoe's lambda = 1 table: 0.0621 at Ca = 0.05).\n";
  md << "- Time steps in the steps column; wall times on a shared machine include waiting, the CSV also has "
        "the process CPU time.\n";
  md << "- The default setting: steady D " << number_text(default_run.taylor_deformation, "%.5f") << ", "
     << number_text(100.0 * relative_error(default_run.taylor_deformation, reference_d), "%.1f")
     << " % from the reference, "
     << number_text(100.0 * relative_error(default_run.taylor_deformation, d1.taylor_deformation), "%.1f")
     << " % from the finest lattice, in " << number_text(default_run.wall_s, "%.1f") << " s wall time ("
     << number_text(default_run.cpu_s, "%.1f") << " s CPU).\n";
  double runs_wall_s = 0.0;
  for (const auto& [setting, r] : runner.runs()) runs_wall_s += r.wall_s;
  md << "- Whole sweep: " << number_text(runs_wall_s, "%.0f") << " s wall time over " << runner.runs().size()
     << " distinct runs";
  if (runner.reused() > 0)
    md << " (" << runner.reused() << " of them recorded in shear_flow_runs.tsv by an earlier invocation and "
       << "reused with --resume; this one took " << number_text(total_s, "%.0f") << " s)";
  md << ".\n";
  int measured_now = 0;
  for (const auto& [setting, r] : runner.runs()) measured_now += r.measured_now ? 1 : 0;
  md << "- Measured by this invocation: " << measured_now << " of the runs (column measured); the others "
     << "come from shear_flow_runs.tsv (same Ca, stop rule and threads).\n";
  md << "- Plot: shear_flow.svg (total error against "
     << (sweep.cpu_time_axis ? "process CPU time" : "wall time")
     << "; Pareto front boxed, default ringed).\n\n";
  md << "## Runs\n\n| run | steady D | D / (5/4 Ca) | inclination [deg] | minus (45 deg - 5/4 Ca rad) [deg] "
        "| tank treading / gammadot | wall [s] | CPU [s] | measured "
        "|\n|---|---|---|---|---|---|---|---|---|\n";
  const double small_ca_theta = scenes::small_ca_inclination_deg_lambda1(sweep.capillary_number);
  for (const auto& [setting, r] : runner.runs()) {
    md << "| " << setting.key() << " | " << number_text(r.taylor_deformation, "%.5f") << " | "
       << number_text(r.taylor_deformation / small_ca_d, "%.3f") << " | "
       << number_text(r.inclination_deg, "%.2f") << " | "
       << number_text(r.inclination_deg - small_ca_theta, "%+.2f") << " | "
       << number_text(r.tank_treading_over_shear_rate, "%.4f") << " | " << number_text(r.wall_s, "%.1f")
       << " | " << number_text(r.cpu_s, "%.1f") << " | "
       << (r.measured_now ? "this invocation" : "run log (--resume)") << " |\n";
  }
  md << "\n## Sweeps";

  ReportLabels labels;
  labels.iterations_csv = "time_steps";
  labels.iterations_md = "time steps";
  labels.result_csv = "steady_D";
  labels.result_md = "steady D";
  labels.analytic_csv = "error_small_ca";
  labels.analytic_md = "error vs 5/4 Ca";
  labels.error_axis = "relative error of the steady D (total)";
  labels.cpu_time_axis = sweep.cpu_time_axis;

  const std::string stem = (std::filesystem::path(out_dir) / "shear_flow").string();
  if (Status s = write_csv(stem + ".csv", rows, labels); !s.ok()) return s;
  if (Status s = write_markdown(stem + ".md", md.str(), rows, labels); !s.ok()) return s;
  char title[160];
  std::snprintf(title, sizeof title, "Shear flow (Ca = %g): error of the steady D vs time",
                sweep.capillary_number);
  if (Status s = write_svg(stem + ".svg", title, rows, labels); !s.ok()) return s;
  std::fprintf(stderr, "wrote %s.{csv,md,svg} in %.1f s\n", stem.c_str(), total_s);
  return Status();
}

}  // namespace cellflow::bench
