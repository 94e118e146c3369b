#!/usr/bin/env bash
# A single-node Slurm "cluster" on localhost (Debian's slurm-wlm + munge) to test profiles/slurm:
#   scripts/local_slurm.sh start STATE_DIR    # munged + slurmctld + slurmd, partition "local"
#   scripts/local_slurm.sh stop STATE_DIR     # cancels its jobs, stops the daemons it started (by their
#                                             # pid files) and waits until they are gone
# Needs root (slurmd) and `apt-get install -y slurm-wlm munge`. State, logs and the munge key live
# under STATE_DIR; the config goes to /etc/slurm/slurm.conf (refused if one exists that is not ours).
set -euo pipefail
export PATH="$PATH:/usr/sbin:/sbin"   # the daemons live in sbin, not on every user's PATH
cmd=${1:?start|stop}; state=$(realpath -m "${2:?state dir}")
conf=/etc/slurm/slurm.conf   # where Debian's sbatch/srun (also srun inside jobs) look for it
marker="# written by madpinn scripts/local_slurm.sh"

stop() {
  if [[ -f $conf ]] && head -1 "$conf" | grep -qF "$marker" && [[ -f $state/slurmctld.pid ]]; then
    scancel --partition=local 2>/dev/null || true      # this cluster's jobs only (the config is ours)
    for _ in $(seq 30); do [[ -z $(squeue -h -t R,CG,PD 2>/dev/null) ]] && break; sleep 1; done
    # a job step that ignored the cancel's SIGTERM can outlive its job here (proctrack/linuxproc,
    # e.g. a snakemake job step waiting on its killed job): kill what this cluster started, by the
    # cluster name Slurm put in its jobs' environment
    for env in /proc/[0-9]*/environ; do
      if tr '\0' '\n' < "$env" 2>/dev/null | grep -qx "SLURM_CLUSTER_NAME=local"; then
        pid=${env#/proc/}; kill -9 "${pid%/environ}" 2>/dev/null || true
      fi
    done
  fi
  local pids=()
  for d in slurmd slurmctld munged; do
    if [[ -f $state/$d.pid ]]; then pids+=("$(cat "$state/$d.pid")"); kill "${pids[-1]}" 2>/dev/null || true; rm -f "$state/$d.pid"; fi
  done
  for p in "${pids[@]}"; do
    for _ in $(seq 30); do kill -0 "$p" 2>/dev/null || break; sleep 1; done
  done
  if [[ -f $conf ]] && head -1 "$conf" | grep -qF "$marker"; then rm -f "$conf"; fi
}

if [[ $cmd == stop ]]; then stop; exit 0; fi

if [[ -f $conf ]] && ! head -1 "$conf" | grep -qF "$marker"; then
  echo "$conf exists and is not ours; not touching a real Slurm installation" >&2; exit 1
fi
mkdir -p "$state"/{spool,ctld,munge,log} /etc/slurm
cpus=$(nproc); mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
host=$(hostname -s)
# munge: a fresh key for this state dir
[[ -f $state/munge/munge.key ]] || dd if=/dev/urandom of="$state/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$state/munge/munge.key"
munged --key-file="$state/munge/munge.key" --socket="$state/munge/munge.socket" \
       --pid-file="$state/munged.pid" --log-file="$state/log/munged.log" --seed-file="$state/munge/seed" --force
cat > "$conf" <<CONF
$marker
ClusterName=local
SlurmctldHost=$host
AuthType=auth/munge
AuthInfo=socket=$state/munge/munge.socket
CredType=cred/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MinJobAge=900
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$state/log/slurmctld.log
SlurmdLogFile=$state/log/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -c -i -f "$conf"
slurmd -c -f "$conf"
for i in $(seq 60); do
  if sinfo -h -o %t 2>/dev/null | grep -q idle; then sinfo; exit 0; fi
  sleep 1
done
echo "local slurm did not come up; logs in $state/log" >&2
tail -20 "$state"/log/*.log >&2
stop
exit 1
