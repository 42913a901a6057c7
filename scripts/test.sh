#!/usr/bin/env bash
# The test command of the README and of CI: configure, build, run the default
# ctest suite (everything but the labels "long", "stability" and "slurm").
set -euo pipefail
cd "$(dirname "$0")/.."
# Every dependency first (Debian 12 packages; a no-op when all are present),
# so that this one command works on a fresh machine.
if [ "${CELLFLOW_SKIP_DEPS:-0}" != 1 ]; then bash scripts/install-deps.sh; fi
build_dir=${CELLFLOW_BUILD_DIR:-build}
jobs=${CELLFLOW_JOBS:-$(nproc)}
# Tests run side by side: idle OpenMP threads must sleep, not spin on a core
# another test needs.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build_dir" -j "$jobs"
# "slurm" (a real Slurm, tests/slurm) is registered only with
# -DCELLFLOW_SLURM_TESTS=ON and never part of the default suite.
ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" -LE "long|stability|slurm" "$@"
