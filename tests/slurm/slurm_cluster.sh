#!/usr/bin/env bash
# A throwaway single-node Slurm (munge + slurmctld + slurmd) in a directory of
# its own, for the "slurm" ctest label. Nothing outside DIR is written or read
# (no /etc/slurm, no system munge socket): every path is in DIR.
#   slurm_cluster.sh start DIR   # prints SLURM_CONF=DIR/slurm.conf once the node is idle
#   slurm_cluster.sh stop DIR    # stops the daemons it started (by their pid files)
# The daemons run as the current user (root in CI containers) without cgroups:
# ProctrackType=proctrack/linuxproc, TaskPlugin=task/none.
set -euo pipefail
command=${1:?start or stop}
dir=${2:?directory}
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)

stop() {
  for name in slurmd slurmctld munged; do
    local pidfile="$dir/$name.pid"
    [ -f "$pidfile" ] || continue
    local pid
    pid=$(cat "$pidfile")
    if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
      kill -TERM "$pid" 2>/dev/null || true
      for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
      kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null || true
    fi
    rm -f "$pidfile"
  done
}

if [ "$command" = stop ]; then
  stop
  exit 0
fi
[ "$command" = start ] || { echo "usage: $0 start|stop DIR" >&2; exit 1; }

for exe in munged mungekey slurmctld slurmd sinfo; do
  command -v "$exe" >/dev/null || PATH=$PATH:/usr/sbin
  command -v "$exe" >/dev/null || { echo "slurm_cluster: $exe not found (apt-get install slurm-wlm munge)" >&2; exit 77; }
done

node=$(hostname -s)
user=$(id -un)
mkdir -p "$dir/munge" "$dir/spool/ctld" "$dir/spool/d" "$dir/log"
chmod 700 "$dir/munge"
[ -f "$dir/munge/munge.key" ] || mungekey --create --keyfile="$dir/munge/munge.key" --bits=1024
chmod 600 "$dir/munge/munge.key"
socket="$dir/munge/munge.socket"
# Ports of our own (a system slurmctld, if any, keeps the defaults 6817/6818).
base=$(( 20000 + ($$ % 20000) ))
cpus=$(nproc)
memory_mb=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2 ))
cat > "$dir/slurm.conf" <<CONF
ClusterName=cellflowtest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$base
SlurmdPort=$(( base + 1 ))
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$dir/spool/ctld
SlurmdSpoolDir=$dir/spool/d
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=10
MinJobAge=30
SchedulerParameters=sched_interval=2
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$memory_mb State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP OverSubscribe=FORCE:4
CONF
: > "$dir/cgroup.conf"

munged --socket="$socket" --key-file="$dir/munge/munge.key" --pid-file="$dir/munged.pid" \
  --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed" --force
export SLURM_CONF="$dir/slurm.conf"
slurmctld -f "$dir/slurm.conf" -i
slurmd -f "$dir/slurm.conf"
for _ in $(seq 150); do
  state=$(sinfo --noheader --nodes="$node" --format=%t 2>/dev/null || true)
  case "$state" in
    idle*|mix*|alloc*) echo "SLURM_CONF=$dir/slurm.conf"; exit 0 ;;
  esac
  sleep 0.2
done
echo "slurm_cluster: node $node did not become idle (state '${state:-none}'); logs in $dir/log" >&2
tail -n 20 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 || true
stop
exit 1
