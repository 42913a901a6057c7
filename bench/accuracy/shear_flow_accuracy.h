// Accuracy sweep of the shear-flow scene (issue 5, item 1): a cell at a small
// capillary number (default Ca = 0.05, where Roscoe's small-Ca limit
// D = 5/4 Ca applies) run to a steady Taylor deformation with one setting at
// a time moved away from the scene's default: lattice resolution (cells per
// radius), mesh vertex count, immersed-boundary kernel, float or double
// lattice storage, the hydrodynamic radius offset (0: the old default). Each row carries three errors of the
// steady D:
//   error           against the finest setting of its own sweep;
//   total error     against the scene's reference: Roscoe's small-Ca limit
//                   5/4 Ca where it applies (Ca <= kSmallCaLimit), else the
//                   finest lattice;
//   analytic error  against 5/4 Ca.
// The Richardson extrapolation in dx of the three finest lattices is reported
// with its observed order but not used: at a fixed vertex count the mesh
// spacing grows against dx as the lattice is refined (the immersed boundary
// leaks), so D(dx) has no continuum limit to extrapolate to.
// Writes shear_flow.csv, shear_flow.md and shear_flow.svg, and records each
// finished run in shear_flow_runs.tsv (a later sweep with resume = true
// reuses the runs recorded there for the same Ca and stop rule).
#pragma once

#include <string>
#include <vector>

#include "physics/core/status.h"
#include "physics/ibm/ibm.h"

namespace cellflow::bench {

struct ShearFlowSweep {
  double capillary_number = 0.05;
  std::vector<double> cells_per_radius;  // ascending; the three finest give the reference
  std::vector<int> vertex_counts;        // ascending; the last is the sweep's reference
  std::vector<ibm::Kernel> kernels;      // the last is the sweep's reference
  std::vector<bool> single_precision;    // the last is the sweep's reference
  double default_cells_per_radius = 6.0;
  int default_vertices = 3000;
  ibm::Kernel default_kernel = ibm::Kernel::kPeskin4;
  bool default_single_precision = true;
  double default_radius_offset = 0.4;  // hydrodynamic_radius_offset of the default, lattice spacings
  std::vector<double> radius_offsets;  // the last is the sweep's reference
  // The steady-state rule and its cap, the same for every run (shear_flow_sweep
  // takes the scene's defaults).
  double steady_tolerance = 2e-3;
  double steady_window_strain = 1.5;
  double max_strain = 40.0;
  int threads = 1;
  bool resume = false;  // reuse the runs of out_dir/shear_flow_runs.tsv
  // Drop lattices finer than this (0: none) when a sweep must fit a CPU
  // budget; at least three must remain.
  double max_cells_per_radius = 0.0;
  bool cpu_time_axis = false;  // plot against process CPU time (a loaded machine)
};

// Up to this Ca the small-Ca limit D = 5/4 Ca is the sweep's reference
// (Roscoe's lambda = 1 table: 0.0621 against 0.0625 at Ca = 0.05).
inline constexpr double kSmallCaLimit = 0.1;

// The sweep the docs hold (the scene's defaults in the middle), or (coarse) a
// tiny one that runs in seconds and exercises every code path (CI).
ShearFlowSweep shear_flow_sweep(bool coarse);

// Runs the sweep, writing progress to stderr and the three files to out_dir
// (created if missing). Failed runs are rows with their status; the result is
// not ok only when the files cannot be written or the finest lattice failed.
Status run_shear_flow_accuracy(const ShearFlowSweep& sweep, const std::string& out_dir, bool coarse);

}  // namespace cellflow::bench
