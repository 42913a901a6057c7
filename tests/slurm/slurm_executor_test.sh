#!/usr/bin/env bash
# cellflow-server --executor slurm against a REAL single-node Slurm that this
# test configures and starts itself (tests/slurm/slurm_cluster.sh: munge,
# slurmctld, slurmd in a temporary directory; stopped at the end).
#   1. Three queued jobs finish with no manual sbatch: the server submits a
#      worker array (at most --slurm-max-workers 2 workers), the workers run
#      the jobs and exit when idle.
#   2. A job handed back at scancel finishes on a new worker: the worker's
#      Slurm job is cancelled mid-run (the idle worker of the same array gets
#      SIGTERM too and must not take the job: attempt 2, not 3), the job goes
#      back to QUEUED, the server submits a new worker, and it succeeds.
#   3. A restarted server adopts the worker still in squeue (squeue --me
#      --name): it does not submit past the cap after a restart.
#   slurm_executor_test.sh BIN_DIR     (cellflow-server, cellflow-worker, cellflow)
set -euo pipefail
bin=$(cd "${1:?directory of cellflow-server, cellflow-worker and cellflow}" && pwd)
here=$(cd "$(dirname "$0")" && pwd)
python=/usr/bin/python3
tmp=$(mktemp -d "${TMPDIR:-/tmp}/cellflow-slurm-test.XXXXXX")
server_pid=""

cleanup() {
  set +e
  if [ -n "${SLURM_CONF:-}" ]; then scancel --name=cellflow-test-worker >/dev/null 2>&1; fi
  if [ -n "$server_pid" ]; then kill -TERM "$server_pid" 2>/dev/null; wait "$server_pid" 2>/dev/null; fi
  bash "$here/slurm_cluster.sh" stop "$tmp/slurm"
  if [ "${keep:-0}" = 1 ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*" >&2
  echo "--- server log" >&2; tail -n 40 "$tmp/server.log" >&2 || true
  for f in "$tmp"/worker-*.log; do [ -f "$f" ] && { echo "--- $f" >&2; tail -n 15 "$f" >&2; }; done
  echo "--- squeue" >&2; squeue >&2 || true
  exit 1
}

out=$(bash "$here/slurm_cluster.sh" start "$tmp/slurm") || { rc=$?; [ $rc = 77 ] && exit 77; exit $rc; }
export "${out##*$'\n'}"   # SLURM_CONF=...
echo "slurm: $(sinfo --noheader --format='%P %t %c CPUs' | head -1)"

(umask 077
 "$bin/cellflow-server" token create --user tester --data-dir "$tmp/data" > "$tmp/user.token"
 "$bin/cellflow-server" token create --worker --user slurm --data-dir "$tmp/data" > "$tmp/worker.token")
# Slow load points (0.4 s each) so that a job is still running when its
# worker is cancelled; idle workers exit after 6 s.
# A worker cancelled 3 s after its start is no failed start (--slurm-min-worker-life-s 1).
start_server() {  # worker-listen address
  rm -f "$tmp/port"
  "$bin/cellflow-server" --data-dir "$tmp/data" --listen 127.0.0.1:0 --port-file "$tmp/port" \
    --worker-listen "$1" --worker-port-file "$tmp/worker-port" --executor slurm --slurm-max-workers 2 \
    --slurm-poll-s 0.5 --slurm-job-name cellflow-test-worker --slurm-idle-exit-s 6 --slurm-min-worker-life-s 1 \
    --slurm-worker-path "$bin/cellflow-worker" --slurm-worker-token-file "$tmp/worker.token" \
    --slurm-arg=--output="$tmp/worker-%A_%a.log" --slurm-arg=--cpus-per-task=1 \
    --slurm-worker-arg=--threads=1 --slurm-worker-arg=--debug-delay-per-point-ms=400 \
    >> "$tmp/server.log" 2>&1 &
  server_pid=$!
  for _ in $(seq 100); do [ -s "$tmp/port" ] && break; sleep 0.1; done
  [ -s "$tmp/port" ] || fail "the server did not start"
}
start_server 127.0.0.1:0
cli=("$bin/cellflow" --server "127.0.0.1:$(cat "$tmp/port")" --token-file "$tmp/user.token")
submit() {  # load points
  "${cli[@]}" submit compression --radius-m 5e-6 --youngs-modulus-pa 1000 --max-deformation 0.1 \
    --target-vertex-count 300 --load-points "$1"
}
field() {  # job field_name (proto name; the JSON may carry it in lowerCamelCase)
  "${cli[@]}" get --json "$1" | "$python" -c "
import json, sys
job = json.load(sys.stdin)
camel = '$2'.split('_')[0] + ''.join(w.title() for w in '$2'.split('_')[1:])
print(job.get('$2', job.get(camel, '')))"
}
wait_state() {  # job state seconds
  local state=""
  for _ in $(seq $(( $3 * 5 ))); do
    state=$(field "$1" state)
    [ "$state" = "$2" ] && return 0
    sleep 0.2
  done
  fail "$1 is $state after $3 s, expected $2"
}
submissions() { grep -c "slurm executor: submitted job" "$tmp/server.log" || true; }

echo "== 1. queued jobs finish with no manual sbatch"
started=$(date +%s.%N)
jobs=()
for _ in 1 2 3; do jobs+=("$(submit 2)"); done
for job in "${jobs[@]}"; do wait_state "$job" SUCCEEDED 60; done
elapsed=$("$python" -c "import time; print(f'{time.time() - $started:.1f}')")
for job in "${jobs[@]}"; do
  worker=$(field "$job" worker_id)
  [[ "$worker" == slurm-* ]] || fail "$job ran on $worker, not on a Slurm worker"
done
n=$(submissions)
[ "$n" -ge 1 ] || fail "no sbatch by the server"
# The cap: never more than 2 workers of ours in squeue at once (checked by the
# server's own count in its log: each submission is of at most 2).
grep "slurm executor: submitted job" "$tmp/server.log" | grep -qv "(1 worker(s))\|(2 worker(s))" &&
  fail "a submission above the cap of 2"
echo "ok: 3 jobs SUCCEEDED in $elapsed s on Slurm workers ($n sbatch submission(s) by the server)"
# The workers end when idle (6 s).
for _ in $(seq 100); do
  [ -z "$(squeue --noheader --name=cellflow-test-worker)" ] && break
  sleep 0.2
done
[ -z "$(squeue --noheader --name=cellflow-test-worker)" ] || fail "idle workers did not exit"
echo "ok: idle workers exited"

echo "== 2. a job handed back at scancel finishes on a new worker"
before=$(submissions)
slow=$(submit 12)   # 12 x 0.4 s
quick=$(submit 1)   # the second worker of the array runs this one and then idles
wait_state "$slow" RUNNING 60
wait_state "$quick" SUCCEEDED 60
sleep 1
worker=$(field "$slow" worker_id)          # slurm-<job>_<task>@host:pid
slurm_job=${worker#slurm-}
slurm_job=${slurm_job%%_*}
[[ "$slurm_job" =~ ^[0-9]+$ ]] || fail "cannot tell the Slurm job of worker $worker"
[ "$(field "$slow" state)" = RUNNING ] || fail "$slow finished before the scancel (make it slower)"
echo "scancel $slurm_job (worker $worker running $slow, attempt $(field "$slow" attempt))"
scancel "$slurm_job"
for _ in $(seq 100); do
  grep -q "$slow handed back" "$tmp/server.log" && break
  sleep 0.1
done
grep -q "$slow handed back" "$tmp/server.log" || fail "$slow was not handed back at scancel"
echo "ok: $slow handed back: $(grep "$slow handed back" "$tmp/server.log" | head -1 | sed 's/.*handed back: //')"
# The other worker of that array (idle after $quick) got SIGTERM as well.
for log in "$tmp"/worker-"${slurm_job}"_*.log; do
  if grep -q "stopped after" "$log" && ! grep -q "$slow: attempt 1" "$log"; then
    grep -q "$slow" "$log" && fail "the idle worker of $log took $slow after SIGTERM"
    echo "ok: the idle worker of the same array stopped without a lease ($(basename "$log"))"
  fi
done
wait_state "$slow" SUCCEEDED 90
attempt=$(field "$slow" attempt)
new_worker=$(field "$slow" worker_id)
[ "$attempt" = 2 ] || fail "$slow took $attempt attempts; an idle worker that got SIGTERM leased it?"
[ "${new_worker#slurm-$slurm_job}" = "$new_worker" ] || fail "$slow finished on $new_worker of the cancelled job"
[ "$(submissions)" -gt "$before" ] || fail "no new worker was submitted for the handed-back job"
echo "ok: $slow SUCCEEDED at attempt 2 on $new_worker (a new Slurm job)"

echo "== 3. a restarted server adopts its workers still in squeue"
kill -TERM "$server_pid"; wait "$server_pid" || true
server_pid=""
[ -n "$(squeue --noheader --name=cellflow-test-worker)" ] || fail "the new worker exited already (idle 6 s)"
start_server "127.0.0.1:$(cat "$tmp/worker-port")"   # the same worker port: the worker reconnects
for _ in $(seq 50); do  # adopt() runs squeue as the executor starts, after the port file appears
  grep -q "adopted 1 worker(s) already in squeue" "$tmp/server.log" && break
  sleep 0.1
done
grep -q "adopted 1 worker(s) already in squeue" "$tmp/server.log" || fail "the restarted server adopted nothing"
echo "ok: $(grep -o "adopted .*" "$tmp/server.log" | tail -1)"
