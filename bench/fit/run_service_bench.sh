#!/usr/bin/env bash
# Benchmark of a fit through the service (issue 14): the joint fit of the
# five synthetic curves of examples/fit with w free, submitted by `cellflow
# fit` to a local server with WORKERS workers (default 2). From an empty
# library the server queues the library simulations as child jobs that all
# workers run at once; a second fit finds every curve in the server's
# library and queues none. Prints the wall time of each (submit to result)
# and the simulations counted.
#
#   bench/fit/run_service_bench.sh [BUILD_DIR] [WORKERS]   (default build, 2)
#
# Library numerics as bench/fit/run_bench.sh: 1000 vertices, 20 load points;
# OMP_NUM_THREADS=1 per worker.
set -euo pipefail
build=${1:-build}
workers=${2:-2}
root=$(cd "$(dirname "$0")/../.." && pwd)
work=$(mktemp -d)
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} OMP_WAIT_POLICY=passive
export CELLFLOW_LIBRARY_DIR="$work/worker-cache"  # the workers' own caches: empty
CELLFLOW_TOKEN=$("$build/bin/cellflow-server" token create --user bench --data-dir "$work/data")
export CELLFLOW_TOKEN
"$build/bin/cellflow-server" --listen 127.0.0.1:0 --port-file "$work/port" --worker-listen 127.0.0.1:0 \
  --data-dir "$work/data" --workers "$workers" --log-level warn &
server=$!
trap 'kill -TERM $server 2>/dev/null || true; wait $server 2>/dev/null || true; rm -rf "$work"' EXIT
for _ in $(seq 200); do [ -s "$work/port" ] && break; sleep 0.1; done
export CELLFLOW_SERVER="127.0.0.1:$(cat "$work/port")"
for run in cold warm; do
  start=$(date +%s.%N)
  "$build/bin/cellflow" fit "$root"/examples/fit/synthetic_plates_E150_w0.5_*.csv --geometry plates \
    --radius-m 8.6e-6 --w-free --vertices 1000 --load-points 20 --no-per-curve --json > "$work/$run.json"
  end=$(date +%s.%N)
  /usr/bin/python3 - "$work/$run.json" "$run" "$(echo "$end - $start" | bc)" <<'PY'
import json, sys
text = open(sys.argv[1]).read()
r = json.loads(text[text.index('{'):])
j = r["joint"]
print(f'{sys.argv[2]} library: {float(sys.argv[3]):.2f} s wall; E {j["youngs_modulus_pa"]["value"]:.2f} Pa, '
      f'w {j["mooney_rivlin_w"]["value"]:.3f}; simulations {r["simulations_run"]} '
      f'(children {r["library"]["child_simulations"]}, server curves {r["library"]["server_curves"]})')
PY
done
