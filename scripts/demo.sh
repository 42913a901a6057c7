#!/usr/bin/env bash
# Quick-start demo: builds cellflow, creates an API token, starts a local
# server with two workers on an ephemeral loopback port, submits a compression job with the client,
# streams the force-deformation curve to the terminal, writes the plot and the
# HDF5 result, and stops the server.
set -euo pipefail
cd "$(dirname "$0")/.."
# Every dependency first (Debian 12 packages; a no-op when all are present),
# so that this one command works on a fresh machine.
if [ "${CELLFLOW_SKIP_DEPS:-0}" != 1 ]; then bash scripts/install-deps.sh; fi
build_dir=${CELLFLOW_BUILD_DIR:-build}
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build_dir" -j "$(nproc)" --target cellflow-server cellflow-worker cellflow cellflow-run

# the server's workers inherit it: idle OpenMP threads sleep, not spin
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
out=${CELLFLOW_DEMO_DIR:-demo-out}
mkdir -p "$out"
data_dir=$(mktemp -d)
port_file="$data_dir/port"
# Authentication is on: a token for this demo's user, shown once, handed to
# the client in its environment (CELLFLOW_TOKEN).
CELLFLOW_TOKEN=$("$build_dir/bin/cellflow-server" token create --user demo --data-dir "$data_dir")
export CELLFLOW_TOKEN
"$build_dir/bin/cellflow-server" --listen 127.0.0.1:0 --port-file "$port_file" \
  --worker-listen 127.0.0.1:0 --data-dir "$data_dir" --workers 2 --log-level warn &
server_pid=$!
trap 'kill -TERM $server_pid 2>/dev/null || true; wait $server_pid 2>/dev/null || true; rm -rf "$data_dir"' EXIT
for _ in $(seq 100); do [ -s "$port_file" ] && break; sleep 0.1; done
export CELLFLOW_SERVER="127.0.0.1:$(cat "$port_file")"
client="$build_dir/bin/cellflow"

echo "== submitting examples/compression.json to $CELLFLOW_SERVER"
job=$("$client" submit --spec examples/compression.json)
echo "== job $job: live samples"
"$client" watch "$job"
"$client" result "$job" --csv -o "$out/curve.csv"
"$client" result "$job" -o "$out/result.h5"
"$client" plot "$job" -o "$out/curve.svg"
echo "== curve: $out/curve.csv, plot: $out/curve.svg, HDF5 + XDMF: $out/result.h5 (open the .xdmf in ParaView)"
