#!/usr/bin/env bash
# Brings up a single-node Slurm cluster on this machine (Debian/Ubuntu, run as root), so that
# figure.sh can be tried without a real cluster.
#   - installs slurm-wlm and munge with apt-get if they are missing, creates a munge key if missing;
#   - writes /etc/slurm/slurm.conf for one node (`hostname -s`, nproc CPUs, the machine's memory),
#     one 1-CPU job per core at a time (select/cons_tres + CR_Core), no cgroups, and a job
#     completion log (start/end time of every job) at /var/spool/slurmctld/jobcomp.log;
#     an existing slurm.conf is only replaced if this script wrote it (see MARK below);
#   - starts munged, slurmctld and slurmd (with systemctl if systemd is PID 1, else as plain
#     background daemons; logs in /var/log/slurm) and waits until `sinfo` shows the node idle.
# Idempotent: rerunning while the daemons run changes nothing.
# Usage: sudo experiments/slurm/setup_local_cluster.sh
set -euo pipefail

[ "$(id -u)" = 0 ] || { echo "run as root" >&2; exit 1; }
CONF=/etc/slurm/slurm.conf
MARK="# Written by experiments/slurm/setup_local_cluster.sh"
JOBCOMP=/var/spool/slurmctld/jobcomp.log

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  apt-get update
  DEBIAN_FRONTEND=noninteractive apt-get install -y slurm-wlm munge
fi

if [ ! -s /etc/munge/munge.key ]; then
  mkdir -p /etc/munge
  dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 status=none
  chown munge:munge /etc/munge/munge.key
  chmod 400 /etc/munge/munge.key
fi

node=$(hostname -s 2>/dev/null || true)
getent hosts "$node" >/dev/null 2>&1 || node=localhost
mem=$(( $(free -m | awk '/^Mem:/ {print $2}') * 95 / 100 ))   # a little under, or slurmd drains the node

new_conf() {
  cat <<EOF
$MARK (do not edit; remove this line to keep the script from rewriting the file)
ClusterName=local
SlurmctldHost=$node
SlurmUser=root
AuthType=auth/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
SchedulerType=sched/backfill
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurm/slurmctld.pid
SlurmdPidFile=/run/slurm/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
JobCompType=jobcomp/filetxt
JobCompLoc=$JOBCOMP
JobAcctGatherType=jobacct_gather/none
NodeName=$node CPUs=$(nproc) RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
}

mkdir -p /etc/slurm /var/spool/slurmctld /var/spool/slurmd /run/slurm /var/log/slurm
changed=0
if [ ! -e "$CONF" ] || head -n1 "$CONF" | grep -qF "$MARK"; then
  if ! new_conf | cmp -s - "$CONF"; then new_conf > "$CONF"; changed=1; fi
else
  echo "note: $CONF was not written by this script; using it as it is" >&2
fi

if [ "$(ps -p 1 -o comm= | tr -d ' ')" = systemd ]; then
  systemctl start munge slurmctld slurmd
  [ "$changed" = 0 ] || systemctl restart slurmctld slurmd
else
  mkdir -p /run/munge && chown munge:munge /run/munge
  if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
    runuser -u munge -- munged
  fi
  if [ "$changed" = 1 ] && [ -s /run/slurm/slurmctld.pid ]; then   # config changed: restart ours
    for d in slurmd slurmctld; do
      [ -s "/run/slurm/$d.pid" ] && kill "$(cat "/run/slurm/$d.pid")" 2>/dev/null || true
    done
    sleep 2
  fi
  running() { [ -s "/run/slurm/$1.pid" ] && kill -0 "$(cat "/run/slurm/$1.pid")" 2>/dev/null; }
  running slurmctld || slurmctld
  running slurmd || slurmd
fi

echo -n "waiting for node $node to be idle"
for _ in $(seq 60); do
  state=$(sinfo -h -n "$node" -o %T 2>/dev/null || true)
  case "$state" in
    idle|mixed|allocated) echo " - $state"; sinfo; exit 0 ;;
    *drain*|down*) scontrol update NodeName="$node" State=RESUME 2>/dev/null || true ;;
  esac
  echo -n .; sleep 2
done
echo; echo "node did not become idle (state: ${state:-?}); see /var/log/slurm/" >&2
exit 1
