#include "physics/calibration/curve_library.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "physics/core/violations.h"
#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::calibration {

namespace {

const char* volumetric_name(elastic::VolumetricTerm v) {
  return v == elastic::VolumetricTerm::kPerTet ? "per_tet" : "nodal_average";
}

// Fields of a key text "name=value;name=value;...".
std::map<std::string, std::string> key_fields(std::string_view text) {
  std::map<std::string, std::string> fields;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find(';', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view item = text.substr(start, end - start);
    const std::size_t eq = item.find('=');
    if (eq != std::string_view::npos)
      fields[std::string(item.substr(0, eq))] = std::string(item.substr(eq + 1));
    start = end + 1;
  }
  return fields;
}

// Fritsch-Carlson slopes of a monotone piecewise-cubic Hermite interpolant
// (the harmonic-mean form of MATLAB's pchip; shape-preserving ends).
std::vector<double> pchip_slopes(const std::vector<double>& x, const std::vector<double>& y) {
  const std::size_t n = x.size();
  std::vector<double> m(n, 0.0);
  if (n < 2) return m;
  std::vector<double> h(n - 1), d(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    h[k] = x[k + 1] - x[k];
    d[k] = (y[k + 1] - y[k]) / h[k];
  }
  if (n == 2) {
    m[0] = m[1] = d[0];
    return m;
  }
  for (std::size_t k = 1; k + 1 < n; ++k) {
    if (d[k - 1] * d[k] <= 0.0) continue;
    const double w1 = 2.0 * h[k] + h[k - 1], w2 = h[k] + 2.0 * h[k - 1];
    m[k] = (w1 + w2) / (w1 / d[k - 1] + w2 / d[k]);
  }
  // one-sided three-point ends: m = ((2 h0 + h1) d0 - h0 d1) / (h0 + h1), kept shape-preserving
  auto end_slope = [](double h0, double h1, double d0, double d1) {
    double s = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
    if (s * d0 <= 0.0) {
      s = 0.0;
    } else if (d0 * d1 <= 0.0 && std::abs(s) > std::abs(3.0 * d0)) {
      s = 3.0 * d0;
    }
    return s;
  };
  m[0] = end_slope(h[0], h[1], d[0], d[1]);
  m[n - 1] = end_slope(h[n - 2], h[n - 3], d[n - 2], d[n - 3]);
  return m;
}

std::uint64_t fnv1a64(std::string_view text) {
  std::uint64_t hash = 14695981039346656037ull;
  for (const unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace

const char* geometry_name(Geometry geometry) {
  return geometry == Geometry::kProbe ? "probe" : "plates";
}

std::string curve_key_text(const CurveKey& key, double w, const LibraryOptions& options) {
  const LibraryNumerics& n = key.numerics;
  std::string text = "cellflow-calibration-curve;code=" + options.code_version;
  text += ";geometry=" + std::string(geometry_name(key.geometry));
  text += ";probe_to_cell_radius=" +
          number_text(key.geometry == Geometry::kProbe ? key.probe_to_cell_radius : 0.0);
  text += ";poisson_ratio=" + number_text(key.poisson_ratio);
  text += ";mooney_rivlin_w=" + number_text(w);
  text += ";target_vertex_count=" + std::to_string(n.target_vertex_count);
  text += ";load_points=" + std::to_string(n.load_points);
  text += ";max_deformation=" + number_text(n.max_deformation);
  text += ";residual_tolerance=" + number_text(n.residual_tolerance);
  text += ";volumetric=" + std::string(volumetric_name(n.volumetric));
  text += ";reference_radius_m=" + number_text(options.reference_radius_m);
  text += ";reference_modulus_pa=" + number_text(options.reference_modulus_pa);
  return text;
}

std::string curve_file_name(std::string_view key_text) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%016llx.csv", static_cast<unsigned long long>(fnv1a64(key_text)));
  return buffer;
}

// q(eps) by cubic Hermite on [eps_k, eps_k+1]; q(eps_0) below the first point
double CurveInterpolant::Node::eval_q(double e) const {
  const std::size_t n = eps.size();
  if (n == 1 || e <= eps.front()) return q.front();
  if (e >= eps.back()) return q.back();
  const std::size_t k =
      static_cast<std::size_t>(std::upper_bound(eps.begin(), eps.end(), e) - eps.begin()) - 1;
  const double h = eps[k + 1] - eps[k];
  const double t = (e - eps[k]) / h;
  const double t2 = t * t, t3 = t2 * t;
  // Hermite basis: h00 = 2t^3 - 3t^2 + 1, h10 = t^3 - 2t^2 + t, h01 = -2t^3 + 3t^2, h11 = t^3 - t^2
  return (2 * t3 - 3 * t2 + 1) * q[k] + (t3 - 2 * t2 + t) * h * slope[k] + (-2 * t3 + 3 * t2) * q[k + 1] +
         (t3 - t2) * h * slope[k + 1];
}

// f(w, eps) = eps^1.5 sum_j L_j(w) q_j(eps), L_j the Lagrange (or linear) weights of the w stencil
double CurveInterpolant::force_scaled(double w, double deformation) const {
  if (!(deformation > 0.0) || nodes_.empty()) return 0.0;
  const double eps = std::min(deformation, max_deformation_);
  const double scale = eps * std::sqrt(eps);
  const std::size_t n = nodes_.size();
  if (n == 1) return scale * nodes_[0].eval_q(eps);
  w = std::clamp(w, nodes_.front().w, nodes_.back().w);
  std::size_t k = 0;
  while (k + 2 < n && w > nodes_[k + 1].w) ++k;  // w in [w_k, w_k+1]
  if (interpolation_ == WInterpolation::kLinear || n == 2) {
    const double t = (w - nodes_[k].w) / (nodes_[k + 1].w - nodes_[k].w);
    return scale * ((1.0 - t) * nodes_[k].eval_q(eps) + t * nodes_[k + 1].eval_q(eps));
  }
  // 4 neighbouring nodes (3 when only 3 exist), shifted inwards at the ends
  const std::size_t width = std::min<std::size_t>(4, n);
  std::size_t first = k > 0 ? k - 1 : 0;
  if (first + width > n) first = n - width;
  double sum = 0.0;
  for (std::size_t j = first; j < first + width; ++j) {
    double l = 1.0;
    for (std::size_t m = first; m < first + width; ++m) {
      if (m != j) l *= (w - nodes_[m].w) / (nodes_[j].w - nodes_[m].w);
    }
    sum += l * nodes_[j].eval_q(eps);
  }
  return scale * sum;
}

CurveInterpolant::AtW CurveInterpolant::at_w(double w) const {
  AtW out;
  out.owner_ = this;
  out.w_ = w;
  const std::size_t n = nodes_.size();
  if (n == 0) return out;
  // The stencil and its weights, as force_scaled chooses them.
  std::vector<std::pair<std::size_t, double>> stencil;
  if (n == 1) {
    stencil.emplace_back(0, 1.0);
  } else {
    const double wc = std::clamp(w, nodes_.front().w, nodes_.back().w);
    std::size_t k = 0;
    while (k + 2 < n && wc > nodes_[k + 1].w) ++k;
    if (interpolation_ == WInterpolation::kLinear || n == 2) {
      const double t = (wc - nodes_[k].w) / (nodes_[k + 1].w - nodes_[k].w);
      stencil = {{k, 1.0 - t}, {k + 1, t}};
    } else {
      const std::size_t width = std::min<std::size_t>(4, n);
      std::size_t first = k > 0 ? k - 1 : 0;
      if (first + width > n) first = n - width;
      for (std::size_t j = first; j < first + width; ++j) {
        double l = 1.0;
        for (std::size_t m = first; m < first + width; ++m) {
          if (m != j) l *= (wc - nodes_[m].w) / (nodes_[j].w - nodes_[m].w);
        }
        stencil.emplace_back(j, l);
      }
    }
  }
  // The shortest grid of the stencil, which every other must begin with: a
  // curve that ended early holds the first load points of the others, and
  // eps never exceeds max_deformation_, the end of the shortest curve.
  const std::vector<double>* shortest = &nodes_[stencil.front().first].eps;
  for (const auto& [j, l] : stencil) {
    if (nodes_[j].eps.size() < shortest->size()) shortest = &nodes_[j].eps;
  }
  const std::vector<double>& eps = *shortest;
  for (const auto& [j, l] : stencil) {
    if (!std::equal(eps.begin(), eps.end(), nodes_[j].eps.begin())) return out;  // the general path
  }
  out.combined_ = true;
  out.eps_ = &eps;
  out.q_.assign(eps.size(), 0.0);
  out.slope_.assign(eps.size(), 0.0);
  for (const auto& [j, l] : stencil) {
    for (std::size_t i = 0; i < eps.size(); ++i) {
      out.q_[i] += l * nodes_[j].q[i];
      out.slope_[i] += l * nodes_[j].slope[i];
    }
  }
  return out;
}

CurveLibrary::CurveLibrary(LibraryOptions options) : options_(std::move(options)) {}

Status CurveLibrary::validate(const CurveKey& key) const {
  Violations v;
  if (key.geometry == Geometry::kProbe &&
      !(key.probe_to_cell_radius > 0.0 && std::isfinite(key.probe_to_cell_radius))) {
    v.add_value("probe_to_cell_radius", key.probe_to_cell_radius, "be > 0 for the probe geometry");
  }
  if (!(key.poisson_ratio > -1.0 && key.poisson_ratio < 0.5)) {
    v.add_value("poisson_ratio", key.poisson_ratio, "lie in (-1, 0.5)");
  }
  const LibraryNumerics& n = key.numerics;
  if (n.target_vertex_count < 200 || n.target_vertex_count > 20000) {
    v.add_value("numerics.target_vertex_count", n.target_vertex_count, "lie in [200, 20000]");
  }
  if (n.load_points < 2 || n.load_points > 10000) {
    v.add_value("numerics.load_points", n.load_points, "lie in [2, 10000]");
  }
  if (!(n.max_deformation > 0.0 && n.max_deformation <= 0.9)) {
    v.add_value("numerics.max_deformation", n.max_deformation, "lie in (0, 0.9]");
  }
  if (!(n.residual_tolerance >= 1e-12 && n.residual_tolerance <= 1e-2)) {
    v.add_value("numerics.residual_tolerance", n.residual_tolerance, "lie in [1e-12, 0.01]");
  }
  const std::vector<double>& g = options_.w_grid;
  if (g.size() < 2) v.add("library.w_grid", "needs at least 2 values of w");
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (!(g[i] >= 0.0 && g[i] <= 1.0) || (i > 0 && !(g[i] > g[i - 1]))) {
      v.add("library.w_grid", "must be increasing values in [0, 1] (w_grid[" + std::to_string(i) +
                                  "] = " + number_text(g[i]) + ")");
      break;
    }
  }
  return v.status("curve_key.");
}

StatusOr<const LibraryCurve*> CurveLibrary::curve(const CurveKey& key, double w) {
  if (!(w >= 0.0 && w <= 1.0)) {
    return invalid_argument("mooney_rivlin_w = " + number_text(w) + " must lie in [0, 1]");
  }
  if (Status s = validate(key); !s.ok()) return s;
  const std::string text = curve_key_text(key, w, options_);
  if (auto it = curves_.find(text); it != curves_.end()) return &it->second;

  const double radius = options_.reference_radius_m, modulus = options_.reference_modulus_pa;
  cell::CellParams cell;
  cell.radius_m = radius;
  cell.material = {.youngs_modulus_pa = modulus, .poisson_ratio = key.poisson_ratio, .mooney_rivlin_w = w};
  cell.target_vertex_count = key.numerics.target_vertex_count;
  scenes::QuasiStaticOptions numerics;
  numerics.residual_tolerance = key.numerics.residual_tolerance;
  numerics.volumetric = key.numerics.volumetric;
  numerics.threads = options_.threads;
  scenes::QuasiStaticResult run;
  if (key.geometry == Geometry::kPlates) {
    scenes::CompressionParams p;
    p.cell = cell;
    p.max_deformation = key.numerics.max_deformation;
    p.load_points = key.numerics.load_points;
    p.numerics = numerics;
    run = scenes::run_compression(p);
  } else {
    scenes::IndentationParams p;
    p.cell = cell;
    p.probe_radius_m = key.probe_to_cell_radius * radius;
    p.max_indentation_m = key.numerics.max_deformation * 2.0 * radius;
    p.load_points = key.numerics.load_points;
    p.numerics = numerics;
    run = scenes::run_indentation(p);
  }
  ++simulations_run_;
  if (run.status.code() == StatusCode::kInvalidArgument || run.curve.empty()) {
    return Status(run.status.ok() ? StatusCode::kInternal : run.status.code(),
                  "library curve (" + text + "): " + (run.status.ok() ? "no point" : run.status.message()));
  }
  LibraryCurve c;
  c.mooney_rivlin_w = w;
  if (!run.status.ok()) c.failure = run.status.to_string();
  const double force_scale = modulus * radius * radius;
  for (const scenes::CurvePoint& p : run.curve) {
    c.deformation.push_back(p.deformation);
    c.force_scaled.push_back(p.force_n / force_scale);
  }
  return &curves_.emplace(text, std::move(c)).first->second;
}

namespace {

CurveInterpolant::Node make_node(const LibraryCurve& c) {
  CurveInterpolant::Node node;
  node.w = c.mooney_rivlin_w;
  node.eps = c.deformation;
  node.q.resize(c.deformation.size());
  for (std::size_t i = 0; i < c.deformation.size(); ++i) {
    const double e = c.deformation[i];
    node.q[i] = c.force_scaled[i] / (e * std::sqrt(e));  // q = f / eps^1.5
  }
  node.slope = pchip_slopes(node.eps, node.q);
  return node;
}

}  // namespace

StatusOr<CurveInterpolant> CurveLibrary::grid_interpolant(const CurveKey& key,
                                                          double needed_max_deformation) {
  if (Status s = validate(key); !s.ok()) return s;
  std::vector<const LibraryCurve*> grid;
  for (const double w : options_.w_grid) {
    StatusOr<const LibraryCurve*> c = curve(key, w);
    if (!c.ok()) return c.status();
    grid.push_back(*c);
  }
  CurveInterpolant out;
  out.interpolation_ = options_.interpolation;
  out.max_deformation_ = key.numerics.max_deformation;
  // from w = 1 down to the last curve that reaches the needed deformation
  for (std::size_t i = grid.size(); i-- > 0;) {
    const LibraryCurve& c = *grid[i];
    if (c.max_deformation() < needed_max_deformation * (1.0 - 1e-12)) {
      if (out.nodes_.size() < 2) {
        return Status(StatusCode::kFailedPrecondition,
                      "library curve at w = " + number_text(c.mooney_rivlin_w) + " ends at deformation " +
                          number_text(c.max_deformation()) + " (" + c.failure + "), below the " +
                          number_text(needed_max_deformation) +
                          " the fit needs; lower the fit's max_deformation or the contact window");
      }
      break;
    }
    out.max_deformation_ = std::min(out.max_deformation_, c.max_deformation());
    out.nodes_.insert(out.nodes_.begin(), make_node(c));
  }
  return out;
}

StatusOr<CurveInterpolant> CurveLibrary::fixed_w_interpolant(const CurveKey& key, double w,
                                                             double needed_max_deformation) {
  StatusOr<const LibraryCurve*> c = curve(key, w);
  if (!c.ok()) return c.status();
  if ((*c)->max_deformation() < needed_max_deformation * (1.0 - 1e-12)) {
    return Status(StatusCode::kFailedPrecondition,
                  "library curve at w = " + number_text(w) + " ends at deformation " +
                      number_text((*c)->max_deformation()) + " (" + (*c)->failure + "), below the " +
                      number_text(needed_max_deformation) +
                      " the fit needs; lower the fit's max_deformation or the contact window");
  }
  CurveInterpolant out;
  out.interpolation_ = options_.interpolation;
  out.max_deformation_ = (*c)->max_deformation();
  out.nodes_.push_back(make_node(**c));
  return out;
}

Status CurveLibrary::insert(const std::string& key_text, LibraryCurve curve) {
  std::map<std::string, std::string> fields = key_fields(key_text);
  if (key_text.rfind("cellflow-calibration-curve;", 0) != 0 || fields["code"] != options_.code_version ||
      fields["reference_radius_m"] != number_text(options_.reference_radius_m) ||
      fields["reference_modulus_pa"] != number_text(options_.reference_modulus_pa)) {
    return invalid_argument("library curve: its key is not of this code version and reference cell");
  }
  if (fields["mooney_rivlin_w"] != number_text(curve.mooney_rivlin_w)) {
    return invalid_argument("library curve: w = " + number_text(curve.mooney_rivlin_w) +
                            " is not the w of its key");
  }
  if (curve.deformation.empty() || curve.deformation.size() != curve.force_scaled.size()) {
    return invalid_argument("library curve: no points, or deformations and forces of different lengths");
  }
  for (std::size_t i = 0; i < curve.deformation.size(); ++i) {
    const double e = curve.deformation[i];
    if (!std::isfinite(e) || !(e > 0.0) || !std::isfinite(curve.force_scaled[i]) ||
        (i > 0 && !(e > curve.deformation[i - 1]))) {
      return invalid_argument("library curve: point " + std::to_string(i) +
                              ": expected increasing deformation > 0 and a finite force");
    }
  }
  curves_.emplace(key_text, std::move(curve));
  return Status::ok_status();
}

Status CurveLibrary::save(const std::string& directory) const {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) return Status(StatusCode::kNotFound, "library directory " + directory + ": " + ec.message());
  for (const auto& [text, c] : curves_) {
    const fs::path final_path = fs::path(directory) / curve_file_name(text);
    const fs::path temp_path = final_path.string() + ".tmp";
    {
      std::ofstream out(temp_path);
      if (!out) return Status(StatusCode::kNotFound, "cannot write " + temp_path.string());
      out << "# cellflow calibration curve: F/(E R^2) against deformation delta/(2R)\n";
      out << "# key: " << text << "\n";
      out << "# failure: " << c.failure << "\n";
      out << "deformation,force_over_e_r2\n";
      char line[80];
      for (std::size_t i = 0; i < c.deformation.size(); ++i) {
        std::snprintf(line, sizeof(line), "%.17g,%.17g\n", c.deformation[i], c.force_scaled[i]);
        out << line;
      }
      if (!out) return Status(StatusCode::kInternal, "write failed: " + temp_path.string());
    }
    fs::rename(temp_path, final_path, ec);
    if (ec) return Status(StatusCode::kInternal, "rename " + temp_path.string() + ": " + ec.message());
  }
  return Status::ok_status();
}

StatusOr<int> CurveLibrary::load(const std::string& directory) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    return Status(StatusCode::kNotFound, "library directory " + directory + " does not exist");
  }
  int read = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(directory, ec)) {
    if (!entry.is_regular_file() || entry.path().extension() != ".csv") continue;
    const std::string name = entry.path().string();
    std::ifstream in(entry.path());
    std::string title, key_line, failure_line, header;
    if (!std::getline(in, title) || !std::getline(in, key_line) || !std::getline(in, failure_line) ||
        !std::getline(in, header) || key_line.rfind("# key: ", 0) != 0 ||
        failure_line.rfind("# failure: ", 0) != 0 || header != "deformation,force_over_e_r2") {
      return invalid_argument(name + ": not a calibration curve file (header lines)");
    }
    const std::string text = key_line.substr(7);
    std::map<std::string, std::string> fields = key_fields(text);
    if (fields["code"] != options_.code_version ||
        fields["reference_radius_m"] != number_text(options_.reference_radius_m) ||
        fields["reference_modulus_pa"] != number_text(options_.reference_modulus_pa)) {
      continue;  // another code version or reference cell: never looked up
    }
    if (entry.path().filename().string() != curve_file_name(text)) {
      return invalid_argument(name + ": the file name is not the hash of its key " + curve_file_name(text));
    }
    LibraryCurve c;
    c.failure = failure_line.substr(11);
    char* end = nullptr;
    c.mooney_rivlin_w = std::strtod(fields["mooney_rivlin_w"].c_str(), &end);
    std::string row;
    int line_number = 4;
    while (std::getline(in, row)) {
      ++line_number;
      if (row.empty()) continue;
      double e = 0.0, f = 0.0;
      if (std::sscanf(row.c_str(), "%lf,%lf", &e, &f) != 2 || !std::isfinite(e) || !std::isfinite(f) ||
          !(e > 0.0) || (!c.deformation.empty() && !(e > c.deformation.back()))) {
        return invalid_argument(name + ":" + std::to_string(line_number) +
                                ": expected increasing deformation > 0 and a finite force");
      }
      c.deformation.push_back(e);
      c.force_scaled.push_back(f);
    }
    if (c.deformation.empty()) return invalid_argument(name + ": no points");
    curves_[text] = std::move(c);
    ++read;
  }
  if (ec) return Status(StatusCode::kNotFound, "library directory " + directory + ": " + ec.message());
  return read;
}

}  // namespace cellflow::calibration
