// Library of dimensionless force curves of cellflow's quasi-static scenes
// (issue 14, item 4): f(eps; w) = F / (E R^2) against the deformation
// eps = delta / (2R), one curve per Mooney-Rivlin ratio w on a grid, per
// geometry (plates; probe with its probe-to-cell radius ratio as a key) and
// numerics (vertex count, load points, nu, tolerance). A curve is computed
// once by running the scene (run_compression / run_indentation) and kept in
// memory; save() and load() write and read it to a directory, one CSV file
// per curve named by a hash of the key text, which holds a code-version
// string so that curves of an older scene are never read back.
//
// F / (E R^2) does not depend on E (the energy is linear in E at fixed nu and
// w; tests/calibration checks it) nor, up to the mesh, on R: the library
// simulates at reference_radius_m and reference_modulus_pa. TetGen meshes the
// sphere afresh for each R, so a curve at another R differs by the mesh
// realisation (about 0.5 % on 600 vertices).
//
// Between grid curves the library interpolates in w (4-point Lagrange cubic
// on the neighbouring grid curves, or linear); along a curve in eps it
// interpolates q = f / eps^1.5 (Hertz-normalised, smooth, finite at 0) with a
// monotone piecewise-cubic Hermite (Fritsch-Carlson), f = q eps^1.5; below
// the first load point q is held at its first value.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "physics/core/status.h"
#include "physics/elastic/elastic_body.h"

namespace cellflow::calibration {

// Bump when the scene, the mesher or the contact law changes a curve: it is
// part of every key, so a saved library of another version is not read.
inline constexpr std::string_view kCurveCodeVersion = "cellflow-quasi-static-2025.1";

enum class Geometry {
  kPlates,  // sphere between two plates (run_compression)
  kProbe,   // spherical probe on a cell resting on a plate (run_indentation)
};

const char* geometry_name(Geometry geometry);

// Numerics of the library's simulations; every field is part of the key.
struct LibraryNumerics {
  int target_vertex_count = 3000;  // sphere mesh, 200 ... 20000
  int load_points = 30;            // per curve, equally spaced in eps up to max_deformation
  double max_deformation = 0.75;   // last eps of a curve, in (0, 0.9]
  double residual_tolerance = 1e-6;
  elastic::VolumetricTerm volumetric = elastic::VolumetricTerm::kNodalAverage;
};

// What a curve depends on besides w.
struct CurveKey {
  Geometry geometry = Geometry::kPlates;
  double probe_to_cell_radius = 0.0;  // Rp / R, > 0 for kProbe (ignored for plates)
  double poisson_ratio = 0.48;
  LibraryNumerics numerics;
};

// One curve: f = F / (E R^2) at the scene's load points.
struct LibraryCurve {
  double mooney_rivlin_w = 1.0;
  std::vector<double> deformation;   // eps, increasing, > 0
  std::vector<double> force_scaled;  // F / (E R^2)
  // Empty when the simulation reached max_deformation; else the scene's
  // failure (e.g. an element crushed at eps 0.78) and the curve ends before it.
  std::string failure;

  double max_deformation() const { return deformation.empty() ? 0.0 : deformation.back(); }
};

enum class WInterpolation { kCubic, kLinear };

struct LibraryOptions {
  // Grid of w for interpolation; sorted, distinct, in [0, 1], >= 2 values.
  // Halved below 0.125: the curves change fastest there (measured on 1000
  // vertices: 4.4 % interpolation error at w = 0.0625 with a 0.125 step, the
  // two neighbours close to their non-convergence at deformation 0.65).
  std::vector<double> w_grid = {0.0, 0.0625, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0};
  WInterpolation interpolation = WInterpolation::kCubic;
  // The library's cells: F / (E R^2) does not depend on them up to the mesh.
  double reference_radius_m = 10e-6;
  double reference_modulus_pa = 1000.0;
  int threads = 1;  // OpenMP threads of each simulation (0 = OpenMP default)
  std::string code_version = std::string(kCurveCodeVersion);
};

// The canonical text of a curve's key (geometry, ratio, nu, w, numerics,
// reference cell, code version), and the file name it is saved under
// (16 hex digits of its FNV-1a 64 hash + ".csv").
std::string curve_key_text(const CurveKey& key, double w, const LibraryOptions& options);
std::string curve_file_name(std::string_view key_text);

// The curves of one key, ready to evaluate f(w, eps) many times (a fit does
// so millions of times). Holds copies of its curves.
class CurveInterpolant {
 public:
  CurveInterpolant() = default;
  // f = F / (E R^2) at w in [w_min, w_max] and eps in [0, max_deformation];
  // eps <= 0 gives 0, eps above max_deformation the value there (callers check the range).
  double force_scaled(double w, double deformation) const;
  double w_min() const { return nodes_.empty() ? 0.0 : nodes_.front().w; }
  double w_max() const { return nodes_.empty() ? 0.0 : nodes_.back().w; }
  double max_deformation() const { return max_deformation_; }

  // The interpolant at one w, for many eps (a fit's inner loop evaluates a
  // whole curve's samples at one w and contact offset): the w stencil's
  // Lagrange weights applied once to the nodes' q values and Hermite slopes
  // (a Hermite cubic is linear in them, so this is the same function as
  // force_scaled up to rounding) when the stencil's nodes share their eps
  // grid (or its first points: a curve that ended early); otherwise it falls
  // back to force_scaled. eval() with a
  // nondecreasing eps walks the segments instead of searching them.
  class AtW {
   public:
    double force_scaled(double deformation);  // = CurveInterpolant::force_scaled(w, deformation)

   private:
    friend class CurveInterpolant;
    const CurveInterpolant* owner_ = nullptr;
    double w_ = 0.0;
    bool combined_ = false;
    const std::vector<double>* eps_ = nullptr;
    std::vector<double> q_, slope_;
    std::size_t segment_ = 0;  // the last segment found
  };
  AtW at_w(double w) const;

  // One curve of the interpolant (built by CurveLibrary).
  struct Node {
    double w = 0.0;
    std::vector<double> eps, q, slope;  // q = f / eps^1.5 and its Hermite slopes
    double eval_q(double eps) const;
  };

 private:
  friend class CurveLibrary;
  std::vector<Node> nodes_;  // sorted by w
  WInterpolation interpolation_ = WInterpolation::kCubic;
  double max_deformation_ = 0.0;
};

// Inline: a fit calls it for every sample of every trial (curve_sums).
inline double CurveInterpolant::AtW::force_scaled(double deformation) {
  if (!combined_) return owner_ == nullptr ? 0.0 : owner_->force_scaled(w_, deformation);
  if (!(deformation > 0.0)) return 0.0;
  const double e = std::min(deformation, owner_->max_deformation_);
  const double scale = e * std::sqrt(e);
  const std::vector<double>& x = *eps_;
  const std::size_t n = x.size();
  if (n == 1 || e <= x.front()) return scale * q_.front();
  if (e >= x.back()) return scale * q_.back();
  // the segment [x_k, x_k+1) holding e: from the last one, forwards, else a search
  std::size_t k = segment_;
  if (k + 1 >= n || e < x[k]) {
    k = static_cast<std::size_t>(std::upper_bound(x.begin(), x.end(), e) - x.begin()) - 1;
  } else {
    while (e >= x[k + 1]) ++k;
  }
  segment_ = k;
  const double h = x[k + 1] - x[k];
  const double t = (e - x[k]) / h;
  const double t2 = t * t, t3 = t2 * t;
  // Hermite basis as in Node::eval_q
  return scale * ((2 * t3 - 3 * t2 + 1) * q_[k] + (t3 - 2 * t2 + t) * h * slope_[k] +
                  (-2 * t3 + 3 * t2) * q_[k + 1] + (t3 - t2) * h * slope_[k + 1]);
}

// Not thread-safe: one fit (or one thread) at a time per library.
class CurveLibrary {
 public:
  explicit CurveLibrary(LibraryOptions options = {});

  const LibraryOptions& options() const { return options_; }

  // Every field of the key in range (kInvalidArgument naming it).
  Status validate(const CurveKey& key) const;

  // The curve at exactly w: from memory, or one simulation (counted). A
  // simulation that fails before max_deformation keeps its curve with the
  // failure; one that fails before its first point is an error.
  StatusOr<const LibraryCurve*> curve(const CurveKey& key, double w);

  // Interpolant over the grid curves of the key (simulating those missing)
  // whose curves reach needed_max_deformation: the grid from w = 1 down to
  // the last w whose curve reaches it (strain-hardening curves at small w
  // may end early), at least two nodes, else kFailedPrecondition naming the
  // curve that ends too early.
  StatusOr<CurveInterpolant> grid_interpolant(const CurveKey& key, double needed_max_deformation);
  // Interpolant of the one curve at w (w_min = w_max = w).
  StatusOr<CurveInterpolant> fixed_w_interpolant(const CurveKey& key, double w,
                                                 double needed_max_deformation);

  // Adds a curve computed elsewhere (the server's library, built by child
  // jobs) under its key text. Refused (INVALID_ARGUMENT, nothing added) unless
  // the key carries this library's code version and reference cell, names
  // the curve's w, and the curve has increasing eps > 0 and finite forces; a
  // curve already held is kept.
  Status insert(const std::string& key_text, LibraryCurve curve);

  // Simulations run by this library since it was made (loaded curves not counted).
  int simulations_run() const { return simulations_run_; }
  std::size_t size() const { return curves_.size(); }
  // Every curve held, by key text.
  const std::map<std::string, LibraryCurve>& curves() const { return curves_; }

  // Writes every curve to directory (created if missing), one file each,
  // written under a temporary name and renamed. Reads every *.csv file of the
  // directory whose key line carries this library's code version and
  // reference cell; other files are skipped, a malformed one is an error.
  Status save(const std::string& directory) const;
  StatusOr<int> load(const std::string& directory);  // number of curves read

 private:
  LibraryOptions options_;
  std::map<std::string, LibraryCurve> curves_;  // by key text
  int simulations_run_ = 0;
};

}  // namespace cellflow::calibration
