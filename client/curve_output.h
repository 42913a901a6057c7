// The force-deformation curve of a quasi-static result: read from the HDF5
// file, written as CSV (the columns of cellflow-run's curve CSV) or drawn as
// an SVG plot with the Hertz curve beside it.
#pragma once

#include <string>
#include <vector>

#include "client/svg_plot.h"  // nice_ticks
#include "physics/core/status.h"

namespace cellflow::client {

struct Curve {
  std::vector<std::string> columns;           // "point", "deformation", "displacement_m", "force_n", ...
  std::vector<bool> integer_columns;          // written without a fraction (point, iteration counts)
  std::vector<std::vector<double>> rows;      // one per load point, columns.size() values
  int column(const std::string& name) const;  // index, or -1
};

// Reads /observables of a result written by worker/job_runner.
StatusOr<Curve> read_curve(const std::string& h5_path);

// Header line and one line per point, the format of `cellflow-run`'s curve
// CSV: point, deformation, displacement_m, force_n, hertz_force_n,
// force_over_hertz, taylor_deformation, a1_m, a2_m, a3_m, volume_m3,
// elastic_energy_j, max_penetration_m, newton_iterations, step_splits,
// residual; doubles with 17 significant digits so they read back exactly.
std::string curve_csv(const Curve& curve);

// Force against deformation: simulated points and line, Hertz dashed, axes
// with ticks and labels, a legend and a title. Force in the SI prefix that
// suits the data (pN, nN, uN, ...).
std::string curve_svg(const Curve& curve, const std::string& title);

}  // namespace cellflow::client
