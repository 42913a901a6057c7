// Output of the accuracy benchmark: one row per run of a sweep, written as
// CSV, as a Markdown table, and as an SVG plot of error against wall time
// (log-log) with the Pareto front and the default setting marked.
#pragma once

#include <limits>
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
  long long iterations = 0;  // Newton iterations (quasi-static) or time steps (flow)
  double error = 0.0;        // largest relative error against the sweep's reference
  double total_error = 0.0;  // the same against the scene's (extrapolated) reference
  // Optional: the run's result (e.g. the steady D) and its relative error
  // against an analytic value; NaN where the scene has none.
  double result = std::numeric_limits<double>::quiet_NaN();
  double analytic_error = std::numeric_limits<double>::quiet_NaN();
  std::string status = "ok";  // or the failure the scene reported
  std::string run_key;        // one run shared by several sweeps (the default) has one key
};

// What the columns of a scene's table are called. The result and analytic
// columns are written only when named.
struct ReportLabels {
  std::string iterations_csv = "newton_iterations";
  std::string iterations_md = "Newton its";
  std::string result_csv, result_md;                        // e.g. "steady_D", "steady D"
  std::string analytic_csv, analytic_md;                    // e.g. "error_small_ca", "error vs 5/4 Ca"
  std::string error_axis = "largest relative force error";  // y axis of the plot
  // Plot (and list in the table) the process CPU time instead of the wall
  // time: on a loaded machine wall times measure the neighbours.
  bool cpu_time_axis = false;
};

// `x` through printf format `fmt` (one double), for tables and notes.
std::string number_text(double x, const char* fmt);

Status write_csv(const std::string& path, const std::vector<AccuracyRow>& rows,
                 const ReportLabels& labels = {});

// A Markdown document: `heading` (already Markdown) then the table.
Status write_markdown(const std::string& path, const std::string& heading,
                      const std::vector<AccuracyRow>& rows, const ReportLabels& labels = {});

// Plots total_error against wall_s (cpu_s with labels.cpu_time_axis), one colour per sweep (in the order the
// sweeps first appear), each run once (by run_key); rows with no positive
// finite error (the reference itself, a failed run) are left out. The Pareto
// front over the plotted runs is a line through its points; the default is
// ringed.
Status write_svg(const std::string& path, const std::string& title, const std::vector<AccuracyRow>& rows,
                 const ReportLabels& labels = {});

}  // namespace cellflow::bench
