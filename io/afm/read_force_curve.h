// Entry point: reads any supported force-curve file into the SI data model.
//
//   .jpk-force (or a zip starting with "PK")  JPK force file
//   .csv starting "Force-Distance Curve"      AFM Workshop single curve
//   .tab with "# BEGIN METADATA"              tab export with JSON header
//   .txt of 3 numeric columns, decimal comma  NT-MDT Nova text export
//   other .csv / .tsv / .txt / .dat           columns named with units
#pragma once

#include <string>

#include "io/afm/force_curve.h"
#include "io/afm/read_options.h"
#include "physics/core/status.h"

namespace cellflow::afm {

StatusOr<ForceCurve> read_force_curve(const std::string& path, const ReadOptions& options = {});

}  // namespace cellflow::afm
