// cellflow-bench: benchmarks of run time against error (issue 5).
//
//   cellflow-bench accuracy compression [--out DIR] [--coarse] [--threads 1]
//   cellflow-bench accuracy shear_flow  [--out DIR] [--coarse] [--threads 1] [--resume]
//                                       [--max-cells-per-radius C] [--cpu-time]
//   cellflow-bench accuracy all         [--out DIR] [--coarse] [--threads 1]
//
// Sweeps the settings that trade time for accuracy of a scene and writes
// SCENE.csv, SCENE.md and SCENE.svg to DIR (see compression_accuracy.h and
// shear_flow_accuracy.h).
// --coarse runs a tiny sweep in seconds (CI keeps the harness from rotting).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "bench/accuracy/compression_accuracy.h"
#include "bench/accuracy/shear_flow_accuracy.h"
#include "physics/core/passive_threads.h"

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  CLI::App app{"cellflow benchmarks of run time against error"};
  app.require_subcommand(1);
  CLI::App* accuracy = app.add_subcommand("accuracy", "sweep the time-accuracy settings of a scene");
  accuracy->require_subcommand(1);
  CLI::App* compression = accuracy->add_subcommand(
      "compression", "vertex count, load points, tolerance, contact stiffness of the compression scene");
  CLI::App* shear_flow = accuracy->add_subcommand(
      "shear_flow", "lattice resolution, vertex count, IBM kernel, float/double of the shear-flow scene");
  CLI::App* all = accuracy->add_subcommand("all", "every scene's sweep, one after the other (docs/accuracy)");
  std::string out_dir = "accuracy-out";
  bool coarse = false;
  int threads = 1;
  bool resume = false;
  double max_cells_per_radius = 0.0;
  bool cpu_time = false;
  shear_flow
      ->add_option("--max-cells-per-radius", max_cells_per_radius,
                   "leave out lattices finer than this (a CPU budget; at least three remain)")
      ->check(CLI::Range(0.0, 64.0));
  shear_flow->add_flag(
      "--cpu-time", cpu_time,
      "plot and list the process CPU time (wall times on a loaded machine measure the load)");
  for (CLI::App* scene : {shear_flow, all})
    scene->add_flag("--resume", resume,
                    "shear flow: reuse the runs recorded in OUT/shear_flow_runs.tsv by an earlier sweep "
                    "(same Ca and stop rule)");
  for (CLI::App* scene : {compression, shear_flow, all}) {
    scene->add_option("--out", out_dir, "output folder (created if missing)");
    scene->add_flag("--coarse", coarse, "tiny sweep for CI (seconds)");
    scene->add_option("--threads", threads, "OpenMP threads of each run (timings in the docs use 1)")
        ->check(CLI::Range(1, 1024));
  }
  CLI11_PARSE(app, argc, argv);

  int failures = 0;
  const auto report = [&](const char* scene, const cellflow::Status& status) {
    if (status.ok()) return;
    std::fprintf(stderr, "cellflow-bench: %s: %s\n", scene, status.to_string().c_str());
    ++failures;
  };
  if (compression->parsed() || all->parsed()) {
    cellflow::bench::CompressionSweep sweep = cellflow::bench::compression_sweep(coarse);
    sweep.threads = threads;
    report("compression", cellflow::bench::run_compression_accuracy(sweep, out_dir, coarse));
  }
  if (shear_flow->parsed() || all->parsed()) {
    cellflow::bench::ShearFlowSweep sweep = cellflow::bench::shear_flow_sweep(coarse);
    sweep.threads = threads;
    sweep.resume = resume;
    sweep.max_cells_per_radius = max_cells_per_radius;
    sweep.cpu_time_axis = cpu_time;
    report("shear_flow", cellflow::bench::run_shear_flow_accuracy(sweep, out_dir, coarse));
  }
  return failures == 0 ? 0 : 1;
}
