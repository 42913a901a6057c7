// Random sequential placement of spheres in a wall-bounded periodic box (see
// placement.h).
#include "physics/scenes/suspension/placement.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "physics/core/violations.h"

namespace cellflow::scenes::placement {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Placed {
  std::array<double, 3> centre{};
  double radius = 0.0;
};

// Rotation vector of a unit quaternion (w, x, y, z), w >= 0.
std::array<double, 3> rotation_vector(double w, double x, double y, double z) {
  if (w < 0.0) {
    w = -w;
    x = -x;
    y = -y;
    z = -z;
  }
  const double s = std::sqrt(x * x + y * y + z * z);
  if (s < 1e-15) return {0.0, 0.0, 0.0};
  const double angle = 2.0 * std::atan2(s, w);
  return {angle * x / s, angle * y / s, angle * z / s};
}

// Uniform random rotation: Shoemake (1992), q from three uniforms u1..u3.
std::array<double, 3> random_rotation(std::mt19937_64& rng) {
  const double u1 = unit_uniform(rng()), u2 = unit_uniform(rng()), u3 = unit_uniform(rng());
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  return rotation_vector(b * std::cos(2.0 * kPi * u3), a * std::sin(2.0 * kPi * u2),
                         a * std::cos(2.0 * kPi * u2), b * std::sin(2.0 * kPi * u3));
}

bool fits_walls(const std::array<double, 3>& c, double r, const PlacementBox& box) {
  return c[1] - r >= box.wall_gap_m && c[1] + r <= box.size_m[1] - box.wall_gap_m;
}

// Index of the first placed cell closer than the gap, -1 if none.
int first_overlap(const std::array<double, 3>& c, double r, const std::vector<Placed>& placed,
                  const PlacementBox& box) {
  for (std::size_t i = 0; i < placed.size(); ++i) {
    if (periodic_distance(c, placed[i].centre, box.size_m) < r + placed[i].radius + box.cell_gap_m) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

// The placed centres binned in a grid of bins at least as wide as the largest
// contact distance 2 R_max + gap, so a try looks at 27 bins, not every cell.
class CentreGrid {
 public:
  CentreGrid(const PlacementBox& box, double max_radius) : box_(box) {
    const double reach = 2.0 * max_radius + box.cell_gap_m;
    for (int d = 0; d < 3; ++d) {
      // At most 64 bins a side: the bins stay few for any box.
      bins_[d] = std::clamp(static_cast<int>(std::floor(box.size_m[d] / reach)), 1, 64);
      size_[d] = box.size_m[d] / bins_[d];
    }
    cells_.resize(static_cast<std::size_t>(bins_[0]) * bins_[1] * bins_[2]);
  }
  void add(const Placed& p) {
    placed_.push_back(p);
    cells_[bin(p.centre)].push_back(static_cast<int>(placed_.size()) - 1);
  }
  bool overlaps(const std::array<double, 3>& c, double r) const {
    int b[3];
    for (int d = 0; d < 3; ++d) b[d] = index(c, d);
    int seen[27];
    int count = 0;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int by = b[1] + dy;
          if (by < 0 || by >= bins_[1]) continue;
          const int bx = (b[0] + dx + bins_[0]) % bins_[0], bz = (b[2] + dz + bins_[2]) % bins_[2];
          const int nb = bx + bins_[0] * (by + bins_[1] * bz);
          if (std::find(seen, seen + count, nb) != seen + count) continue;
          seen[count++] = nb;
          for (int i : cells_[nb]) {
            if (periodic_distance(c, placed_[i].centre, box_.size_m) <
                r + placed_[i].radius + box_.cell_gap_m)
              return true;
          }
        }
      }
    }
    return false;
  }
  const std::vector<Placed>& placed() const { return placed_; }

 private:
  int index(const std::array<double, 3>& c, int d) const {
    return std::clamp(static_cast<int>(std::floor(c[d] / size_[d])), 0, bins_[d] - 1);
  }
  std::size_t bin(const std::array<double, 3>& c) const {
    return static_cast<std::size_t>(index(c, 0) + bins_[0] * (index(c, 1) + bins_[1] * index(c, 2)));
  }
  PlacementBox box_;
  int bins_[3] = {1, 1, 1};
  double size_[3] = {1, 1, 1};
  std::vector<std::vector<int>> cells_;
  std::vector<Placed> placed_;
};

}  // namespace

double unit_uniform(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

std::array<double, 9> rotation_matrix(const std::array<double, 3>& r) {
  const double angle = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  if (angle < 1e-15) return {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double k[3] = {r[0] / angle, r[1] / angle, r[2] / angle};
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  // R = c I + s [k]x + t k k^T   (Rodrigues)
  return {c + t * k[0] * k[0],        t * k[0] * k[1] - s * k[2], t * k[0] * k[2] + s * k[1],
          t * k[1] * k[0] + s * k[2], c + t * k[1] * k[1],        t * k[1] * k[2] - s * k[0],
          t * k[2] * k[0] - s * k[1], t * k[2] * k[1] + s * k[0], c + t * k[2] * k[2]};
}

double periodic_distance(const std::array<double, 3>& a, const std::array<double, 3>& b,
                         const std::array<double, 3>& box_m) {
  double d2 = 0.0;
  for (int d = 0; d < 3; ++d) {
    double delta = a[d] - b[d];
    if (d != 1) delta -= box_m[d] * std::round(delta / box_m[d]);
    d2 += delta * delta;
  }
  return std::sqrt(d2);
}

StatusOr<std::vector<CellPlacement>> place_cells(const PlacementBox& box,
                                                 const std::vector<PlacementKind>& kinds,
                                                 std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const double box_volume = box.size_m[0] * box.size_m[1] * box.size_m[2];
  // The given places of every kind first, each checked against the box and
  // the ones before it.
  std::vector<Placed> fixed;
  for (const PlacementKind& kind : kinds) {
    const double r = kind.radius_m;
    for (std::size_t i = 0; i < kind.fixed.size(); ++i) {
      const CellPlacement& p = kind.fixed[i];
      const std::string field = kind.placements_field + "[" + std::to_string(i) + "]";
      const std::array<double, 3>& c = p.centre_m;
      bool finite = true;
      for (int d = 0; d < 3; ++d) finite = finite && std::isfinite(c[d]) && std::isfinite(p.rotation_rad[d]);
      if (!finite) return invalid_argument(field + ": centre and rotation must be finite");
      if (!(c[0] >= 0.0 && c[0] < box.size_m[0] && c[2] >= 0.0 && c[2] < box.size_m[2]) ||
          !fits_walls(c, r, box)) {
        return invalid_argument(
            field + ": the cell (centre " + number_text(c[0], 6) + ", " + number_text(c[1], 6) + ", " +
            number_text(c[2], 6) + " m, radius " + number_text(r, 6) + " m) lies outside the box: x in [0, " +
            number_text(box.size_m[0], 6) + "), z in [0, " + number_text(box.size_m[2], 6) +
            ") m and y in [R + gap, H - R - gap] = [" + number_text(r + box.wall_gap_m, 6) + ", " +
            number_text(box.size_m[1] - r - box.wall_gap_m, 6) + "] m");
      }
      if (const int other = first_overlap(c, r, fixed, box); other >= 0) {
        return invalid_argument(field + ": the cell overlaps cell " + std::to_string(other) +
                                " of the given places (centre distance " +
                                number_text(periodic_distance(c, fixed[other].centre, box.size_m), 6) +
                                " m, less than the radii plus the gap " +
                                number_text(r + fixed[other].radius + box.cell_gap_m, 6) + " m)");
      }
      fixed.push_back({c, r});
    }
  }
  // Then the random ones, kind by kind; a jammed attempt starts the random
  // part again (the generator runs on, so the result stays a function of the seed).
  std::vector<std::vector<CellPlacement>> random(kinds.size());
  double best_fraction = 0.0;
  std::size_t failed_kind = 0;
  int failed_cell = 0;
  bool done = false;
  double max_radius = 0.0;
  for (const PlacementKind& kind : kinds) max_radius = std::max(max_radius, kind.radius_m);
  std::int64_t tries_left = kMaxTotalTries;
  for (int restart = 0; restart < kMaxRestarts && !done && tries_left > 0; ++restart) {
    CentreGrid placed(box, max_radius);
    for (const Placed& p : fixed) placed.add(p);
    double placed_volume = 0.0;
    for (const Placed& p : fixed) placed_volume += 4.0 / 3.0 * kPi * std::pow(p.radius, 3);
    done = true;
    for (std::size_t k = 0; k < kinds.size() && done; ++k) {
      const PlacementKind& kind = kinds[k];
      const double r = kind.radius_m;
      random[k].clear();
      const double y_lo = r + box.wall_gap_m, y_hi = box.size_m[1] - r - box.wall_gap_m;
      for (int i = 0; i < kind.random_count && done; ++i) {
        bool found = false;
        for (int attempt = 0; attempt < kMaxTriesPerCell && y_hi >= y_lo && tries_left > 0; ++attempt) {
          --tries_left;
          const std::array<double, 3> c = {unit_uniform(rng()) * box.size_m[0],
                                           y_lo + unit_uniform(rng()) * (y_hi - y_lo),
                                           unit_uniform(rng()) * box.size_m[2]};
          if (placed.overlaps(c, r)) continue;
          placed.add({c, r});
          random[k].push_back({c, random_rotation(rng)});
          placed_volume += 4.0 / 3.0 * kPi * r * r * r;
          found = true;
          break;
        }
        if (!found) {
          done = false;
          if (placed_volume / box_volume >= best_fraction) {
            best_fraction = placed_volume / box_volume;
            failed_kind = k;
            failed_cell = i;
          }
        }
      }
    }
  }
  if (!done) {
    const PlacementKind& kind = kinds[failed_kind];
    return invalid_argument(kind.count_field + ": cannot place cell " + std::to_string(failed_cell + 1) +
                            " of " + std::to_string(kind.random_count) + " (radius " +
                            number_text(kind.radius_m, 6) + " m) without overlap (" +
                            std::to_string(kMaxRestarts) + " attempts of " +
                            std::to_string(kMaxTriesPerCell) +
                            " random tries per cell); the best attempt filled a volume fraction of " +
                            number_text(best_fraction, 4) +
                            " (random sequential placement jams near 0.38 for equal spheres in a large box, "
                            "less with the gaps, the walls and a small box): lower it or enlarge the box");
  }
  std::vector<CellPlacement> out;
  for (std::size_t k = 0; k < kinds.size(); ++k) {
    out.insert(out.end(), kinds[k].fixed.begin(), kinds[k].fixed.end());
    out.insert(out.end(), random[k].begin(), random[k].end());
  }
  return out;
}

}  // namespace cellflow::scenes::placement
