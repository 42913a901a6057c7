// Placement of the cells of a suspension (issue 15, item 1): spheres of given
// radii at random non-overlapping centres and random orientations in a box
// periodic in x and z with walls at y = 0 and y = H, or at given places,
// checked for overlap and for lying inside the box.
//
// Random sequential addition: each cell is tried at uniform random centres
// until it keeps the gaps to every cell placed before it (minimum image in x
// and z) and to the walls; an attempt that jams (a cell finds no place in
// kMaxTriesPerCell tries) starts the random cells again, up to kMaxRestarts
// times (the paper's 8 cells in the 5 x 8 x 4 R box jam a single pass in
// about one seed of ten). Reproducible: std::mt19937_64 from the seed, and
// the uniform numbers and rotations are computed here from its raw 64-bit
// output (no std::*_distribution, whose results differ between standard
// libraries). Orientation: a uniform random rotation (Shoemake's quaternion
// from three uniforms), returned as a rotation vector.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::scenes {

// A centre (box coordinates, metres) and a rotation vector (axis x angle,
// radians) of the cell's mesh about its centre.
struct CellPlacement {
  std::array<double, 3> centre_m{};
  std::array<double, 3> rotation_rad{};
};

namespace placement {

struct PlacementBox {
  std::array<double, 3> size_m{};  // Lx, H, Lz
  double cell_gap_m = 0.0;         // least surface-to-surface distance between two cells
  double wall_gap_m = 0.0;         // least distance of a cell's surface from a wall
};

// One kind of sphere: `fixed` places first (checked), then `random_count`
// more at random places.
struct PlacementKind {
  double radius_m = 0.0;
  int random_count = 0;
  std::vector<CellPlacement> fixed;
  // Field names for errors: the count or fraction that asked for the random
  // cells ("suspension.kinds[0].volume_fraction") and the placements list
  // ("suspension.kinds[0].placements").
  std::string count_field;
  std::string placements_field;
};

// Random tries per cell before an attempt counts as jammed, and attempts of
// the whole random placement before it gives up.
inline constexpr int kMaxTriesPerCell = 2000;
inline constexpr int kMaxRestarts = 200;
// Random tries in all attempts together (bounds the work of a hostile spec).
inline constexpr std::int64_t kMaxTotalTries = 20'000'000;

// Every cell, kinds in order (fixed ones of a kind first, then its random
// ones). Errors (kInvalidArgument): a fixed place outside the box or closer
// than the gaps to a wall or to an earlier given place ("...placements[3]"),
// random cells that jammed in every attempt (names count_field with the
// best fraction reached).
StatusOr<std::vector<CellPlacement>> place_cells(const PlacementBox& box,
                                                 const std::vector<PlacementKind>& kinds, std::uint64_t seed);

// Uniform in [0, 1) from the top 53 bits of one 64-bit draw.
double unit_uniform(std::uint64_t bits);

// 3 x 3 rotation matrix (row-major) of a rotation vector (Rodrigues).
std::array<double, 9> rotation_matrix(const std::array<double, 3>& rotation_rad);

// Centre distance with the minimum image in the periodic x and z.
double periodic_distance(const std::array<double, 3>& a, const std::array<double, 3>& b,
                         const std::array<double, 3>& box_m);

}  // namespace placement
}  // namespace cellflow::scenes
