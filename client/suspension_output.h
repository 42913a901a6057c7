// The results of suspension jobs (paper section 7.2): the mean time series
// read from the HDF5 file as a table (CSV, the columns of cellflow-run's
// suspension CSV), mean D against strain with the band of the cells' D as an
// SVG plot, and, for a set of jobs, the time-averaged mean D and relative
// viscosity (with their standard errors) against the capillary number or the
// volume fraction.
#pragma once

#include <string>
#include <vector>

#include "client/curve_output.h"
#include "physics/core/status.h"

namespace cellflow::client {

// True when `h5_path` holds a suspension result (/observables/mean_taylor_deformation).
bool is_suspension_result(const std::string& h5_path);

// The mean series as a table: sample, time_s, strain, cell_count,
// mean_taylor_deformation, mean_inclination_rad, relative_viscosity,
// contact_pairs, average_taylor_deformation, average_taylor_deformation_error,
// average_relative_viscosity, average_relative_viscosity_error (curve_csv
// writes it), and the band of the cells' D per sample.
struct SuspensionSeries {
  Curve table;
  std::vector<double> min_taylor_deformation;  // over the cells, per sample (empty: no per-cell series)
  std::vector<double> max_taylor_deformation;
};
StatusOr<SuspensionSeries> read_suspension_series(const std::string& h5_path);

// What a suspension job's result says about its averages.
struct SuspensionPoint {
  std::string label;              // job id or study point
  double capillary_number = 0.0;  // /parameters/setup/capillary_number
  double volume_fraction = 0.0;   // /parameters/setup/volume_fraction
  int cell_count = 0;
  double average_taylor_deformation = 0.0, average_taylor_deformation_error = 0.0;  // /summary
  double average_relative_viscosity = 0.0, average_relative_viscosity_error = 0.0;
  std::string stop;
};
StatusOr<SuspensionPoint> read_suspension_point(const std::string& h5_path, const std::string& label);

// Mean D against strain, the band (min and max over the cells, thin lines)
// and the time average (dotted) with its standard error.
std::string suspension_svg(const SuspensionSeries& series, const std::string& title);

// The x quantity of a set of suspension jobs.
enum class SuspensionAxis { kCapillaryNumber, kVolumeFraction };

// Two plots one above the other: the averaged mean D, and the averaged
// relative viscosity, each with its standard error bar, against `axis`;
// against the volume fraction with the rigid-sphere suspension
// 1 + 2.5 phi + 6.2 phi^2 (Batchelor 1977) beside it.
std::string suspension_points_svg(const std::vector<SuspensionPoint>& points, SuspensionAxis axis,
                                  const std::string& title);

}  // namespace cellflow::client
