// The fit job (issue 14, items 5-6): E, the Mooney-Rivlin ratio w and the
// contact point of measured force curves sent as data in the spec
// (proto/cellflow/v1/fit.proto; conversion and checks in jobs/fit/fit_spec.h),
// with the compression or indentation scene as the model
// (physics/calibration/fit.h).
//
// run(): loads the curve library from RunOptions::library_dir (a per-user
// cache, default_library_dir()), simulates the grid curves it lacks one by
// one (a progress event per simulation, cancellable between them, the
// library saved after each), calls fit_curves, and writes the result
// (layout in jobs/fit/result_schema.json): per curve the data in the fit
// range, the best model curve and the Hertz curve as observables, and the
// whole fit as a JSON document (/summary/fit_json) -- the document
// `cellflow fit --json` prints. The results reach a watcher as the last
// progress stage ("fit joint (5 curves): E ... Pa [lo, hi], w ...;
// simulations run 7", or the one curve's fit) and in the result file, where
// the client reads every curve's fit; there is no sample message for them
// (JobEvent's samples are force and deformation points; a FitSample kind
// would touch the worker protocol, the server's report handling and the
// store). The worker forwards one progress report per fraction and at most
// five a second, so one stage at fraction 1 carries the summary.
//
// The tip geometry is fitted with the probe scene: a sphere of the tip's
// apex radius (a paraboloid near its apex). The Hertz model needs no scene:
// per curve E and the contact point by the closed form and a contact search
// on the Hertz force (no profile intervals: lower and upper are NaN, null in
// the JSON); joint E by the closed form over all curves at their contacts.
//
// Not here (a later task, with the sweeps): child jobs -- the library's
// simulations as jobs other workers lease. This job runs them itself, one
// after the other, on the worker that leased it; the library lives in that
// worker's cache directory, not on the server.
#pragma once

#include <memory>
#include <string>

#include "cellflow/v1/spec.pb.h"
#include "jobs/scene.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Registry entry (jobs/registry.cc).
StatusOr<std::unique_ptr<PreparedJob>> prepare_fit(const v1::JobSpec& spec);

// $CELLFLOW_LIBRARY_DIR, else $XDG_CACHE_HOME/cellflow/curves, else
// $HOME/.cache/cellflow/curves, else $TMPDIR/cellflow-curves.
std::string default_library_dir();

// The header of cellflow-run's fit CSV: one row per curve and fit (per_curve,
// joint) with the parameters and their 95 % bounds.
std::string fit_csv_header();

}  // namespace cellflow::jobs
