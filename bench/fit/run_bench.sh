#!/usr/bin/env bash
# Benchmark of the fit job (issue 14): a joint fit of the five synthetic
# curves of examples/fit with w free, run locally by cellflow-run (the same
# registry entry and job code a worker runs), wall time from an empty curve
# library and from a warm one. Targets: 60 s cold, 1 s warm.
#
#   bench/fit/run_bench.sh [BUILD_DIR]   (default build; needs cellflow, cellflow-run)
#
# The library numerics are the demo's: 1000 vertices, 20 load points
# (the examples were made with them). OMP_NUM_THREADS=1.
set -euo pipefail
build=${1:-build}
root=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} OMP_WAIT_POLICY=passive
export CELLFLOW_LIBRARY_DIR="$work/library"
"$build/bin/cellflow" fit "$root"/examples/fit/synthetic_plates_E150_w0.5_*.csv --geometry plates \
  --radius-m 8.6e-6 --w-free --vertices 1000 --load-points 20 --no-per-curve --print-spec > "$work/spec.json"
for run in cold warm; do
  start=$(date +%s.%N)
  "$build/bin/cellflow-run" "$work/spec.json" > "$work/$run.csv"
  end=$(date +%s.%N)
  printf '%s library: %.2f s wall\n' "$run" "$(echo "$end - $start" | bc)"
  cut -d, -f1-8,16 "$work/$run.csv" | sed 's/^/  /'
done
