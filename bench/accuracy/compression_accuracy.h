// Accuracy sweep of the compression scene (issue 5, item 1): the issue's
// curve (R = 8.6 um, E = 150 Pa, nu = 0.48, w = 0.5, deformation 0 to 0.6)
// solved with one setting at a time moved away from the default: vertex
// count, load points, residual tolerance, contact stiffness. The error of a
// run is the largest relative force error on a fixed deformation grid
// against the reference of its sweep: for the vertex count the Richardson
// extrapolation in h = N^-1/3 from the three finest meshes (the finest mesh
// where the observed order is outside (0.5, 4)), otherwise the sweep's finest
// setting. Writes compression.csv, compression.md and compression.svg.
#pragma once

#include <string>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::bench {

struct CompressionSweep {
  std::vector<int> vertex_counts;       // ascending; the last three give the reference
  std::vector<int> load_points;         // ascending; the last is the reference
  std::vector<double> tolerances;       // descending; the last is the reference
  std::vector<double> contact_factors;  // of contact::default_penalty, ascending; the last is the reference
  int default_vertices = 3000;
  int default_load_points = 40;
  double default_tolerance = 1e-6;
  double max_deformation = 0.6;
  std::vector<double> grid;  // deformations at which the forces are compared
  int threads = 1;
};

// The full sweep of the issue, or (coarse) a tiny one that runs in seconds
// and exercises every code path (CI).
CompressionSweep compression_sweep(bool coarse);

// Runs the sweep, writing progress to stderr and the three files to out_dir
// (created if missing). Failed runs are rows with their status; the result
// is not ok only when the files cannot be written or no reference exists.
Status run_compression_accuracy(const CompressionSweep& sweep, const std::string& out_dir, bool coarse);

}  // namespace cellflow::bench
