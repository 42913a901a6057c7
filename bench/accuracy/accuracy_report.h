// Output of the accuracy benchmark: one row per run of a sweep, written as
// CSV, as a Markdown table, and as an SVG plot of error against wall time
// (log-log) with the Pareto front and the default setting marked.
#pragma once

#include <string>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::bench {

struct AccuracyRow {
  std::string sweep;  // the factor varied: "vertices", "load_points", ...
  std::string value;  // its value as shown, e.g. "3000 (2987 actual)"
  double numeric_value = 0.0;
  bool is_default = false;    // the scene's default setting
  bool is_reference = false;  // the reference of its sweep (error 0 by definition)
  double wall_s = 0.0;
  double cpu_s = 0.0;
  int newton_iterations = 0;
  double error = 0.0;         // largest relative force error against the sweep's reference
  double total_error = 0.0;   // the same against the vertex sweep's (extrapolated) reference
  std::string status = "ok";  // or the failure the scene reported
  std::string run_key;        // one run shared by several sweeps (the default) has one key
};

Status write_csv(const std::string& path, const std::vector<AccuracyRow>& rows);

// A Markdown document: `heading` (already Markdown) then the table.
Status write_markdown(const std::string& path, const std::string& heading,
                      const std::vector<AccuracyRow>& rows);

// Plots total_error against wall_s, one colour per sweep, each run once (by
// run_key); rows with no positive finite error (the reference itself, a
// failed run) are left out. The Pareto front over the plotted runs is a line
// through its points; the default is ringed.
Status write_svg(const std::string& path, const std::string& title, const std::vector<AccuracyRow>& rows);

}  // namespace cellflow::bench
