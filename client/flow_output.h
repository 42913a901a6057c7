// The results of shear-flow jobs: the deformation time series D(t) read from
// the HDF5 file as a table (CSV, the columns of cellflow-run's flow CSV), D
// against strain as an SVG plot, and the steady D of a set of jobs against
// the capillary number beside Roscoe's theory (small-Ca limit D = 5/4 Ca and
// the lambda = 1 table of shared/validation/roscoe_elastic_sphere_shear.csv).
#pragma once

#include <string>
#include <vector>

#include "client/curve_output.h"
#include "physics/core/status.h"

namespace cellflow::client {

// True when `h5_path` holds a shear-flow result (/observables/strain).
bool is_flow_result(const std::string& h5_path);

// The deformation samples as a table: sample, time_s, strain,
// taylor_deformation, inclination_rad, net_strain, a1_m, a2_m, a3_m,
// tank_treading_frequency_per_s, volume_m3 (curve_csv writes it).
StatusOr<Curve> read_deformation_series(const std::string& h5_path);

// What a flow job's result says about its end state.
struct SteadyPoint {
  std::string label;                       // job id
  double capillary_number = 0.0;           // /parameters/setup/capillary_number
  double steady_taylor_deformation = 0.0;  // /summary/steady_taylor_deformation
  std::string stop;                        // /summary/stop: steady, max_strain, ...
};
StatusOr<SteadyPoint> read_steady_point(const std::string& h5_path, const std::string& label);

// D against strain: the samples, the steady D (dotted) and, for reference,
// the small-Ca limit 5/4 Ca (dashed) when capillary_number > 0.
std::string deformation_svg(const Curve& series, double capillary_number, double steady_taylor_deformation,
                            const std::string& title);

// Steady D against Ca: one marker per job (hollow when the job did not reach
// a steady state), 5/4 Ca (dashed) and Roscoe's lambda = 1 curve.
std::string steady_deformation_svg(const std::vector<SteadyPoint>& points, const std::string& title);

// Roscoe (1967) for an elastic sphere in shear flow, viscosity ratio
// lambda = 1: (Ca, D) rows of shared/validation/roscoe_elastic_sphere_shear.csv.
struct RoscoePoint {
  double capillary_number;
  double taylor_deformation;
};
const std::vector<RoscoePoint>& roscoe_lambda1();

}  // namespace cellflow::client
