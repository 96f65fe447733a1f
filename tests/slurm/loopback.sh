#!/bin/bash
# A real single-node Slurm cluster on loopback for one test (issue #18): starts munged (unless one
# runs already), slurmctld and slurmd with a configuration, state and spool of their own under a
# scratch folder, submits a 4-shard bake of a small scene with `penumbra slurm`, waits for the
# dependent merge job, compares the merged bytes with a local bake, and stops the daemons it
# started by their pid files. Only ports on 127.0.0.1 are used.
#
# Usage: loopback.sh PENUMBRA_BINARY [CUTS] (default "receivers blockers": one 4-shard bake per
# cut). Exit 0: identical; 77: skipped (no packages, not root), with a notice on stdout; anything
# else: failure.
set -u
PENUMBRA=$(readlink -f "$1")
CUTS=${2:-receivers blockers}
for tool in munged slurmctld slurmd sbatch sinfo scontrol; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "SKIP: $tool not found: install slurm-wlm and munge (./setup.sh test does) to run the loopback Slurm test"
    exit 77
  fi
done
if [ "$(id -u)" != 0 ]; then echo "SKIP: the loopback Slurm test starts slurmd and munged, which needs root"; exit 77; fi

D=$(mktemp -d /tmp/penumbra-slurm-XXXXXX)
HOST=$(hostname -s)
STARTED_MUNGE=""
stop() {
  for pidfile in "$D/slurmd.pid" "$D/slurmctld.pid" $STARTED_MUNGE; do
    [ -s "$pidfile" ] && kill "$(cat "$pidfile")" 2>/dev/null
  done
  sleep 1
  for pidfile in "$D/slurmd.pid" "$D/slurmctld.pid"; do
    [ -s "$pidfile" ] && kill -9 "$(cat "$pidfile")" 2>/dev/null
  done
  [ -n "${KEEP_SLURM_DIR:-}" ] || rm -rf "$D"
}
trap stop EXIT
fail() { echo "FAIL: $*"; for f in "$D"/*.log "$D"/job-*/logs/*.log; do [ -f "$f" ] && { echo "== $f"; tail -20 "$f"; }; done; exit 1; }

# munged as user munge with the key in /etc/munge/munge.key; one that serves the default socket
# already is used as it is (a munged on a socket of its own, another cluster's, is not one).
if ! [ -S /run/munge/munge.socket.2 ] || ! munge -n </dev/null >/dev/null 2>&1; then
  [ -f /etc/munge/munge.key ] || { dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=128 2>/dev/null; chown munge:munge /etc/munge/munge.key; chmod 400 /etc/munge/munge.key; }
  mkdir -p /run/munge && chown munge:munge /run/munge
  runuser -u munge -- /usr/sbin/munged --pid-file=/run/munge/penumbra-test.pid || fail "munged did not start"
  STARTED_MUNGE=/run/munge/penumbra-test.pid
fi

# Ports no other test uses; slurmctld changes directory, so SLURM_CONF is absolute.
MEM=$(awk '/MemTotal/ {print int($2 / 1024 * 0.8)}' /proc/meminfo)
CPUS=$(nproc)
mkdir -p "$D/state" "$D/spool"
cat > "$D/slurm.conf" <<CONF
ClusterName=penumbra-loopback
SlurmctldHost=$HOST(127.0.0.1)
SlurmctldPort=16917
SlurmdPort=16918
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
MailProg=/bin/true
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MinJobAge=600
NodeName=$HOST NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM State=UNKNOWN
PartitionName=loopback Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$D/slurm.conf"
slurmctld -f "$SLURM_CONF" || fail "slurmctld did not start"
slurmd -f "$SLURM_CONF" -N "$HOST" || fail "slurmd did not start"
for _ in $(seq 60); do
  sinfo -h -o %t 2>/dev/null | grep -qx idle && break
  sleep 0.5
done
sinfo -h -o %t | grep -qx idle || fail "the node is not idle: $(sinfo -h 2>&1)"

cat > "$D/scene.json" <<'SCENE'
{"geometry": [{"type": "grid", "cells": 6, "levels": 2, "size": 2, "floor_size": 5, "rotate_step_deg": 20}],
 "lights": [{"type": "rect", "center": [0,4,0], "u": [1,0,0], "v": [0,0,1], "samples": 64, "sample_sets": 4}],
 "receivers": {"type": "camera", "eye": [0,4,5], "target": [0,0.5,0], "width": 128, "height": 96},
 "output": "out/scene.exr"}
SCENE
mkdir -p "$D/local"  # -o names an existing folder
"$PENUMBRA" bake "$D/scene.json" -o "$D/local/scene.exr" --quiet || fail "the local bake failed"
for CUT in $CUTS; do
  mkdir -p "$D/merged-$CUT"
  # A fan-in of 2 makes a tree: two combine tasks of two shards each, then a merge of their files.
  "$PENUMBRA" slurm "$D/scene.json" --shards 4 --shard-by "$CUT" --threads 1 --dir "$D/job-$CUT" -o "$D/merged-$CUT/scene.exr" \
    --partition loopback --fan-in 2 > "$D/submitted-$CUT.txt" || fail "penumbra slurm failed: $(cat "$D/submitted-$CUT.txt")"
  cat "$D/submitted-$CUT.txt"
  MERGE=$(awk '/^merge job/ {print $3}' "$D/submitted-$CUT.txt")
  [ -n "$MERGE" ] || fail "no merge job id"
  STATE=""
  for _ in $(seq 240); do
    STATE=$(scontrol show job "$MERGE" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p')
    case "$STATE" in COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|DEADLINE) break ;; esac
    sleep 0.5
  done
  [ "$STATE" = COMPLETED ] || fail "the merge job ended $STATE"
  [ "$(ls "$D/job-$CUT/shards" | wc -l)" = 4 ] || fail "expected 4 shard files, found: $(ls "$D/job-$CUT/shards")"
  [ "$(ls "$D/job-$CUT/level-1")" = "$(printf 'shards-0-1-of-4.pnpart\nshards-2-3-of-4.pnpart')" ] ||
    fail "expected two combined files, found: $(ls "$D/job-$CUT/level-1")"
  cmp "$D/local/scene.exr" "$D/merged-$CUT/scene.exr" || fail "merged EXR differs from the local bake"
  cmp "$D/local/scene.png" "$D/merged-$CUT/scene.png" || fail "merged PNG differs from the local bake"
  echo "OK: 4 shards by $CUT on a loopback Slurm cluster, combined in a tree of fan-in 2, merged to the local bake's bytes"
done
