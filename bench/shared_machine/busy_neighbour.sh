#!/usr/bin/env bash
# A program of ours next to a busy core: the wall time of one cellflow-run
# (default: the issue's default compression spec, 3000 vertices, 40 points to 0.5) with the machine idle and with another process
# spinning on one core, each the median of RUNS runs. OMP_WAIT_POLICY is
# left unset on purpose: the program must wait passively by itself.
#   bash bench/shared_machine/busy_neighbour.sh [build-dir] [spec] [runs]
set -euo pipefail
build=${1:-build}
spec=${2:-bench/shared_machine/default_compression.json}
runs=${3:-3}
unset OMP_WAIT_POLICY
run_once() {
  local start end
  start=$(date +%s.%N)
  "$build/bin/cellflow-run" -q "$spec" > /dev/null
  end=$(date +%s.%N)
  echo "$end - $start" | bc -l
}
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
idle=$(for _ in $(seq "$runs"); do run_once; done | median)
# The neighbour: one process that keeps one core busy for as long as we measure.
( while :; do :; done ) &
spinner=$!
trap 'kill $spinner 2>/dev/null || true' EXIT
busy=$(for _ in $(seq "$runs"); do run_once; done | median)
kill $spinner 2>/dev/null || true
printf 'spec %s, %d runs each (median), %s cores\n' "$spec" "$runs" "$(nproc)"
printf 'idle: %.2f s   busy neighbour core: %.2f s   ratio %.2f (target <= 1.3)\n' "$idle" "$busy" \
  "$(echo "$busy / $idle" | bc -l)"
