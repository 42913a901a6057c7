#include "bench/stability/stability_harness.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <thread>

#include "physics/core/violations.h"
#include "physics/elastic/material.h"
#include "physics/mesh/tet_geometry.h"

extern char** environ;

namespace cellflow::stability {

namespace {

bool contains(std::string_view text, std::string_view part) {
  return text.find(part) != std::string_view::npos;
}

// One line, no separators of the report formats.
std::string one_line(std::string text) {
  for (char& ch : text) {
    if (ch == '\n' || ch == '\r' || ch == '\t') ch = ' ';
    if (ch == '|') ch = '/';
  }
  return text;
}

std::string file_name_of(const std::string& case_name) {
  std::string out = case_name;
  for (char& ch : out) {
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == '-' || ch == '_')) ch = '_';
  }
  return out;
}

std::string tail_of_file(const std::string& path, std::size_t max_chars) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  std::string text = buffer.str();
  if (text.size() > max_chars) text = "..." + text.substr(text.size() - max_chars);
  return one_line(text);
}

// Error of the lever arm of the plate forces taken as the cell's height, in
// units of R: the contact vertices lie within the penalty range (default
// 5e-3 R) of the extremes at each plate; Z0 - delta (without positions)
// misses the same offsets. Relative slack: this over the lever arm.
constexpr double kLeverArmSlack = 0.02;
// An element compressed below this volume ratio without inverting has
// collapsed: no cell material loses 90 % of its volume locally. More than
// kMaxCrushedFraction of the cell volume collapsed is a wrong result; one
// crushed sliver of a bad mesh (1e-6 of the volume) is not.
constexpr double kCrushedJ = 0.1;
constexpr double kMaxCrushedFraction = 1e-3;
// dV / P = 1 + sum_e (J_e - 1)^2 V0_e / |P|: 1.2-2.0 in every converged case
// of the matrix to deformation 0.9 (nu 0.45-0.499, w 0.25-1); a collapsing
// cell reaches 4-1000.
constexpr double kMaxNonUniformity = 3.0;
constexpr double kHertzCheckUpTo = 0.2;

}  // namespace

std::string_view outcome_name(Outcome outcome) {
  switch (outcome) {
    case Outcome::kConverged:
      return "CONVERGED";
    case Outcome::kFailed:
      return "FAILED";
    case Outcome::kHang:
      return "HANG";
    case Outcome::kCrash:
      return "CRASH";
    case Outcome::kWrong:
      return "WRONG";
  }
  return "UNKNOWN";
}

bool acceptable(Outcome outcome, std::string_view cause) {
  return outcome == Outcome::kConverged || (outcome == Outcome::kFailed && !cause.empty());
}

std::string failure_cause(const Status& status) {
  if (status.ok()) return "";
  const std::string& m = status.message();
  switch (status.code()) {
    case StatusCode::kNumericalFailure:
      if (contains(m, "inverts tetrahedron") || contains(m, "inverted") || contains(m, "J <= 0"))
        return "inverted element";
      if (contains(m, "is compressed to J")) return "element volume collapse (J guard)";
      if (contains(m, "the force fell")) return "force drop guard (obstacle slipped between vertices)";
      if (contains(m, "did not converge")) return "non-convergence";
      if (contains(m, "line search")) return "non-convergence (line search)";
      if (contains(m, "elastic energy")) return "energy blow-up / NaN guard";
      if (contains(m, "NaN") || contains(m, "non-finite")) return "NaN guard";
      if (contains(m, "vertex speed")) return "runaway vertex speed guard";
      if (contains(m, "wall region")) return "cell reached the wall";
      if (contains(m, "periodic box")) return "cell longer than the periodic box";
      return "";
    case StatusCode::kInvalidArgument:
      if (contains(m, "explicit elastic update would be unstable")) return "stiffness limit (refused)";
      if (contains(m, "Mach number")) return "Mach limit (refused)";
      if (contains(m, "relaxation_time")) return "tau limit (refused)";
      if (contains(m, "mesh_file")) return "invalid mesh (refused)";
      return "invalid input (refused)";
    case StatusCode::kFailedPrecondition:
      if (contains(m, "inverted") || contains(m, "degenerate")) return "invalid mesh (refused)";
      return "";
    case StatusCode::kResourceExhausted:
      return "memory limit (refused)";
    case StatusCode::kNotFound:
      return "missing file (refused)";
    default:
      return "";
  }
}

ElementVolumes element_volumes(const mesh::TetMesh& reference, const double* positions_m) {
  ElementVolumes out;
  double crushed = 0.0, total = 0.0;
  for (std::size_t t = 0; t < reference.num_tets(); ++t) {
    const std::int32_t* tet = &reference.tets[4 * t];
    const double v0 = mesh::tet_signed_volume(reference.positions_m.data(), tet);
    const double j = mesh::tet_signed_volume(positions_m, tet) / v0;
    out.min_j = std::min(out.min_j, j);
    out.squared_deviation_m3 += (j - 1.0) * (j - 1.0) * v0;
    if (j < kCrushedJ) crushed += v0;
    total += v0;
  }
  out.crushed_fraction = crushed / total;
  double lo = std::numeric_limits<double>::max(), hi = -lo;
  for (std::size_t v = 0; v < reference.num_vertices(); ++v) {
    lo = std::min(lo, positions_m[3 * v + 2]);
    hi = std::max(hi, positions_m[3 * v + 2]);
  }
  out.height_m = hi - lo;
  return out;
}

std::optional<std::string> check_compression(const scenes::CompressionParams& params,
                                             const scenes::QuasiStaticResult& result,
                                             const CompressionCheck& check) {
  const std::vector<scenes::CurvePoint>& curve = result.curve;
  if (result.status.ok() && static_cast<int>(curve.size()) != params.load_points) {
    return "ok status but " + std::to_string(curve.size()) + " of " + std::to_string(params.load_points) +
           " load points";
  }
  const elastic::Moduli moduli = elastic::moduli_from(params.cell.material);
  double previous_force = 0.0;
  for (const scenes::CurvePoint& p : curve) {
    const std::string at =
        "point " + std::to_string(p.index) + " (deformation " + number_text(p.deformation, 4) + ")";
    for (double v : {p.force_n, p.hertz_force_n, p.volume_m3, p.elastic_energy_j, p.taylor_deformation,
                     p.semi_axes_m[0], p.semi_axes_m[1], p.semi_axes_m[2], p.residual}) {
      if (!std::isfinite(v)) return at + ": non-finite value";
    }
    if (!(p.force_n > 0.0)) return at + ": force " + number_text(p.force_n, 4) + " N not positive";
    if (!(p.force_n > previous_force)) {
      return at + ": force " + number_text(p.force_n, 4) + " N not above the previous " +
             number_text(previous_force, 4) + " N";
    }
    previous_force = p.force_n;
    // Hertz grows as E R^2 eps^1.5; up to eps = 0.2 a ratio outside
    // [0.3, 10] is a unit or scaling error, not locking or the finite-size
    // effect (beyond, the curve leaves Hertz by design: 40 times at 0.9).
    const double hertz_ratio = p.force_n / p.hertz_force_n;
    if (p.deformation <= kHertzCheckUpTo && !(hertz_ratio > 0.3 && hertz_ratio < 10.0)) {
      return at + ": F / F_Hertz = " + number_text(hertz_ratio, 4);
    }
    if (!(p.taylor_deformation >= 0.0 && p.taylor_deformation < 1.0)) {
      return at + ": Taylor deformation " + number_text(p.taylor_deformation, 4) + " outside [0, 1)";
    }
    if (check.check_volume && check.initial_volume_m3 > 0.0) {
      const std::size_t k = static_cast<std::size_t>(p.index);
      const ElementVolumes* e = k < check.points.size() ? &check.points[k] : nullptr;
      // P = -F H / (3 kappa): the volume change if J were uniform.
      const double lever_arm = e ? e->height_m : check.initial_height_m - p.displacement_m;
      const double predicted = -p.force_n * lever_arm / (3.0 * moduli.kappa_pa);
      const double measured = p.volume_m3 - check.initial_volume_m3;
      // Slack: the contact vertices sit within the penalty range (~5e-3 R)
      // of the extremes; without the positions, Z0 - delta misses that too.
      const double slack = kLeverArmSlack * params.cell.radius_m / lever_arm * std::abs(predicted) +
                           1e-9 * check.initial_volume_m3;
      const double v0 = check.initial_volume_m3;
      if (!(measured <= predicted + slack)) {
        return at + ": volume change " + number_text(measured / v0, 4) + " V0 above the virial bound " +
               number_text(predicted / v0, 4) + " V0 of the plate force (force or volume wrong)";
      }
      if (e) {
        if (!(measured >= predicted - e->squared_deviation_m3 - slack)) {
          return at + ": volume change " + number_text(measured / v0, 4) + " V0 below the virial bound " +
                 number_text((predicted - e->squared_deviation_m3) / v0, 4) + " V0 (force or volume wrong)";
        }
        if (!(e->crushed_fraction <= kMaxCrushedFraction)) {
          return at + ": " + number_text(100.0 * e->crushed_fraction, 4) +
                 " % of the cell volume crushed below J = " + number_text(kCrushedJ, 4) +
                 " without inverting (min J " + number_text(e->min_j, 4) + ", volume " +
                 number_text(p.volume_m3 / v0, 4) + " V0, uniform-J estimate " +
                 number_text(1.0 + predicted / v0, 4) +
                 " V0): the volumetric energy kappa/2 (J-1)^2 of eq. 5 stays bounded as J -> 0";
        }
      }
      if (!(measured >= kMaxNonUniformity * predicted - slack)) {
        return at + ": volume change " + number_text(measured / v0, 4) + " V0 is " +
               number_text(measured / predicted, 4) + " times the uniform-J estimate " +
               number_text(predicted / v0, 4) +
               " V0 for nu = " + number_text(params.cell.material.poisson_ratio, 4) + " (local collapse)";
      }
    }
  }
  return std::nullopt;
}

std::optional<std::string> check_indentation(const scenes::QuasiStaticResult& result) {
  double previous_force = 0.0;
  for (const scenes::CurvePoint& p : result.curve) {
    const std::string at =
        "point " + std::to_string(p.index) + " (deformation " + number_text(p.deformation, 4) + ")";
    for (double v : {p.force_n, p.hertz_force_n, p.volume_m3, p.elastic_energy_j, p.residual}) {
      if (!std::isfinite(v)) return at + ": non-finite value";
    }
    if (!(p.force_n > 0.0)) return at + ": force " + number_text(p.force_n, 4) + " N not positive";
    if (!(p.force_n > previous_force)) {
      return at + ": force " + number_text(p.force_n, 4) + " N not above the previous " +
             number_text(previous_force, 4) + " N";
    }
    previous_force = p.force_n;
  }
  return std::nullopt;
}

std::optional<std::string> check_shear_flow(const scenes::ShearFlowResult& result) {
  if (result.samples.empty()) return "no samples";
  const double v0 = result.samples.front().volume_m3;
  for (const scenes::ShearFlowSample& s : result.samples) {
    const std::string at =
        "sample " + std::to_string(s.index) + " (strain " + number_text(s.strain_units, 4) + ")";
    if (!(std::isfinite(s.taylor_deformation) && s.taylor_deformation >= 0.0 && s.taylor_deformation < 1.0)) {
      return at + ": D = " + number_text(s.taylor_deformation, 4) + " not finite in [0, 1)";
    }
    if (!(std::isfinite(s.volume_m3) && s.volume_m3 > 0.0 && std::abs(s.volume_m3 / v0 - 1.0) < 0.3)) {
      return at + ": volume " + number_text(s.volume_m3 / v0, 4) + " V0";
    }
    if (!std::isfinite(s.inclination_deg) || !std::isfinite(s.net_strain)) {
      return at + ": non-finite inclination or strain";
    }
  }
  const double d = result.steady_taylor_deformation;
  if (!(std::isfinite(d) && d >= 0.0 && d < 1.0))
    return "steady D = " + number_text(d, 4) + " not finite in [0, 1)";
  const double ca = result.setup.capillary_number;
  if (result.stop == scenes::ShearFlowStop::kSteady && ca <= 0.2) {
    // Roscoe's small-Ca limit D = (5/4) Ca; coarse lattices overshoot by
    // tens of percent, never by a factor 2.
    const double ratio = d / scenes::small_ca_taylor_deformation(ca);
    if (!(ratio > 0.5 && ratio < 2.0))
      return "steady D / (5/4 Ca) = " + number_text(ratio, 4) + " at Ca = " + number_text(ca, 4);
  }
  return std::nullopt;
}

CaseRecord run_case_in_child(const std::string& executable, const Case& c, const std::string& work_dir,
                             double time_limit_s) {
  CaseRecord record;
  record.name = c.name;
  record.description = c.description;
  record.anchor = c.anchor;
  const std::string base = work_dir + "/" + file_name_of(c.name);
  const std::string result_file = base + ".result";
  const std::string log_file = base + ".log";
  std::remove(result_file.c_str());

  std::vector<std::string> args = {executable,  "--run-case", c.name,  "--result-file",
                                   result_file, "--work-dir", work_dir};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  // Own process group, so a case that starts helpers is killed whole.
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attributes, 0);

  const auto start = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, executable.c_str(), &actions, &attributes, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  if (spawned != 0) {
    record.outcome = Outcome::kCrash;
    record.cause = "could not start the child";
    record.detail = std::strerror(spawned);
    return record;
  }
  int wait_status = 0;
  bool killed = false;
  while (true) {
    const pid_t done = waitpid(pid, &wait_status, WNOHANG);
    if (done == pid) break;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (elapsed > time_limit_s) {
      kill(-pid, SIGKILL);
      waitpid(pid, &wait_status, 0);
      killed = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(elapsed < 1.0 ? 5 : 50));
  }
  record.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  if (killed) {
    record.outcome = Outcome::kHang;
    record.cause = "no result within " + number_text(time_limit_s, 4) + " s";
    record.detail = tail_of_file(log_file, 300);
    return record;
  }
  if (WIFSIGNALED(wait_status)) {
    record.outcome = Outcome::kCrash;
    record.cause = std::string("signal ") + strsignal(WTERMSIG(wait_status));
    record.detail = tail_of_file(log_file, 300);
    return record;
  }
  std::ifstream in(result_file);
  std::string outcome_line, cause, detail;
  if (!in || !std::getline(in, outcome_line)) {
    record.outcome = Outcome::kCrash;
    record.cause = "exit " + std::to_string(WEXITSTATUS(wait_status)) + " without a result";
    record.detail = tail_of_file(log_file, 300);
    return record;
  }
  std::getline(in, cause);
  std::getline(in, detail);
  static const std::map<std::string, Outcome> kByName = {{"CONVERGED", Outcome::kConverged},
                                                         {"FAILED", Outcome::kFailed},
                                                         {"HANG", Outcome::kHang},
                                                         {"CRASH", Outcome::kCrash},
                                                         {"WRONG", Outcome::kWrong}};
  const auto it = kByName.find(outcome_line);
  record.outcome = it == kByName.end() ? Outcome::kCrash : it->second;
  record.cause = cause;
  record.detail = detail;
  return record;
}

int run_case_here(const Case& c, const std::string& result_file, const std::string& work_dir) {
  // A crash is reported from the signal; no core files in the work folder.
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  CaseResult result;
  try {
    result = c.run(CaseContext{work_dir});
  } catch (const std::exception& e) {
    result.outcome = Outcome::kCrash;
    result.cause = "exception";
    result.detail = e.what();
  }
  std::ofstream out(result_file);
  out << outcome_name(result.outcome) << '\n'
      << one_line(result.cause) << '\n'
      << one_line(result.detail) << '\n';
  out.close();
  return out ? 0 : 3;
}

std::string markdown_report(const std::vector<CaseRecord>& records, double total_wall_s) {
  std::map<std::string, int> counts;
  for (const CaseRecord& r : records) counts[std::string(outcome_name(r.outcome))]++;
  std::ostringstream md;
  md << "# Stability matrix\n\n";
  md << records.size() << " cases, total wall time " << number_text(total_wall_s, 4) << " s:";
  for (const char* name : {"CONVERGED", "FAILED", "HANG", "CRASH", "WRONG"}) {
    md << " " << name << " " << counts[name];
  }
  md << ".\n\nEach case ran in its own process under a wall-clock limit. FAILED with a named cause is "
        "an allowed outcome; HANG, CRASH and WRONG are not.\n\n";
  md << "| case | outcome | cause | time (s) | detail |\n|---|---|---|---:|---|\n";
  for (const CaseRecord& r : records) {
    md << "| " << r.name << (r.anchor ? " (anchor)" : "") << " | " << outcome_name(r.outcome) << " | "
       << one_line(r.cause) << " | " << number_text(r.wall_s, 4) << " | " << one_line(r.detail) << " |\n";
  }
  return md.str();
}

std::string csv_report(const std::vector<CaseRecord>& records) {
  auto quoted = [](const std::string& s) {
    std::string out = "\"";
    for (char ch : s) {
      if (ch == '"') out += '"';
      out += ch;
    }
    return out + "\"";
  };
  std::ostringstream csv;
  csv << "case,outcome,cause,wall_s,anchor,detail\n";
  for (const CaseRecord& r : records) {
    csv << quoted(r.name) << "," << outcome_name(r.outcome) << "," << quoted(r.cause) << ","
        << number_text(r.wall_s, 4) << "," << (r.anchor ? 1 : 0) << "," << quoted(one_line(r.detail)) << "\n";
  }
  return csv.str();
}

}  // namespace cellflow::stability
