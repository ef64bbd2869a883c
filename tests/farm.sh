#!/bin/sh
# Farm-ready frames: a sequence split into chunks gives the same bytes as
# one run, with everything that animates the fog on (wind with a turn,
# turbulence, MacCormack advection; a fogmap sequence blended between
# keys).  GNU parallel with 4 chunks (samples/farm/parallel.sh), and the
# Slurm array script (samples/farm/slurm-array.sh) on a one-node Slurm that
# this test starts on loopback (munged, slurmctld, slurmd, all in a temporary
# directory, stopped at the end); each skips with the reason where it
# cannot run.
. "${FP_SRCDIR:-.}/tests/lib.sh"
FARM=$FP_SRCDIR/samples/farm
FM=$FP_SAMPLES/fogmap.exr

# Eight small frames, and a fogmap sequence with keys 1, 4 and 8.
mkdir -p "$T/in"
for f in 1 2 3 4 5 6 7 8; do
  "$OIIOTOOL" "$FP_SAMPLES/scene.000$f.exr" --resize 96x54 -o "$T/in/scene.000$f.exr"
done
"$OIIOTOOL" "$FM" -o "$T/in/key.0001.exr"
"$OIIOTOOL" "$FM" --flip -o "$T/in/key.0004.exr"
"$OIIOTOOL" "$FM" --flop --mulc 1.5 -o "$T/in/key.0008.exr"
COMMON="--fog-rect -20,-10,20,30 --density 0.2 --height 0,3 --seed 3"
CONF_ADVECT="--fogmap $FM --wind 3,-2,5 --turbulence 0.5 --advect maccormack"
CONF_SEQ="--fogmap $T/in/key.####.exr --fogmap-interp smooth --wind 1,2 --turbulence 0.4"

# same_frames DIR_A DIR_B: every frame 1-8 byte-identical.
same_frames() {
  for f in 1 2 3 4 5 6 7 8; do
    cmp "$1/out.000$f.exr" "$2/out.000$f.exr" || return 1
  done
}

for conf in advect seq; do
  if [ $conf = advect ]; then args="$CONF_ADVECT"; else args="$CONF_SEQ"; fi
  mkdir -p "$T/one-$conf"
  # shellcheck disable=SC2086
  check "$conf: frames 1-8 in one run" "$FOGPIPE" -q -i "$T/in/scene.####.exr" \
    -o "$T/one-$conf/out.####.exr" --frames 1-8 $COMMON $args
done
check "the frames differ from each other" sh -c '! cmp -s "$1/out.0004.exr" "$1/out.0005.exr"' sh "$T/one-advect"

# ---------------------------------------------------------------- GNU parallel
if command -v parallel >/dev/null 2>&1 && parallel --version 2>/dev/null | grep -q "GNU parallel"; then
  for conf in advect seq; do
    if [ $conf = advect ]; then args="$CONF_ADVECT"; else args="$CONF_SEQ"; fi
    mkdir -p "$T/par-$conf"
    # shellcheck disable=SC2086
    check "$conf: GNU parallel, 4 chunks of 1-8" env FOGPIPE="$FOGPIPE" sh "$FARM/parallel.sh" 1 8 4 \
      -q -i "$T/in/scene.####.exr" -o "$T/par-$conf/out.####.exr" $COMMON $args
    check "$conf: the chunks' frames are byte-identical to one run's" same_frames "$T/one-$conf" "$T/par-$conf"
  done
else
  skip "GNU parallel is not installed (Debian package parallel)"
fi

# ---------------------------------------------------------------- Slurm
# slurm_skip_reason: empty when a one-node Slurm can be tried here.
slurm_skip_reason() {
  for c in munged slurmctld slurmd sbatch sinfo; do
    if ! command -v "$c" >/dev/null 2>&1 && ! [ -x "/usr/sbin/$c" ]; then
      echo "no $c (Debian packages munge slurmctld slurmd slurm-client)"
      return
    fi
  done
  [ "$(id -u)" = 0 ] || echo "starting slurmd needs root"
}

# A free TCP port on loopback, from the kernel's table of listening sockets.
free_port() {
  p=$1
  while grep -qi ":$(printf %04X "$p") " /proc/net/tcp /proc/net/tcp6 2>/dev/null; do p=$((p + 1)); done
  echo "$p"
}

D=""
PIDS=""
# pid_alive PID: a running process (a zombie has ended).
pid_alive() {
  [ -d "/proc/$1" ] && ! grep -q '^State:[[:space:]]*Z' "/proc/$1/status" 2>/dev/null
}
# track NAME: remember a daemon's id once its pid file is there (the
# daemons remove their pid files when they stop).
track() {
  [ -s "$D/$1.pid.saved" ] && return 0
  cp "$D/$1.pid" "$D/$1.pid.saved" 2>/dev/null || return 0
  PIDS="$PIDS $(cat "$D/$1.pid.saved")"
}
# Only the daemons this test started, by their ids.
stop_slurm() {
  [ -n "$D" ] || return 0
  # Jobs first (a timed-out sbatch leaves its tasks queued or running).
  if [ -s "$D/slurmd.pid.saved" ]; then
    timeout 10 scancel --quiet --partition=fp >/dev/null 2>&1
    n=0
    while [ $n -lt 20 ] && timeout 5 squeue -h 2>/dev/null | grep -q .; do sleep 0.5; n=$((n + 1)); done
  fi
  for name in slurmd slurmctld munged; do
    pid=$(cat "$D/$name.pid.saved" 2>/dev/null || true)
    [ -n "$pid" ] && kill "$pid" 2>/dev/null
  done
  n=0
  while [ $n -lt 20 ]; do
    alive=""
    for pid in $PIDS; do pid_alive "$pid" && alive=1; done
    [ -z "$alive" ] && break
    sleep 0.5
    n=$((n + 1))
  done
  for pid in $PIDS; do pid_alive "$pid" && kill -9 "$pid" 2>/dev/null; done
  rm -rf "$D"
  D=""
}
trap 'stop_slurm' EXIT
trap 'stop_slurm; exit 1' INT TERM

# start_slurm: munged, slurmctld and slurmd with a generated slurm.conf in
# a short temporary directory (socket paths are limited to 108 bytes).
start_slurm() {
  D=$(mktemp -d /tmp/fp-slurm.XXXXXX) || return 1
  mkdir -p "$D/state" "$D/spool" && chmod 700 "$D" || return 1
  head -c 1024 /dev/urandom > "$D/munge.key" && chmod 400 "$D/munge.key" || return 1
  munged --force --key-file="$D/munge.key" --socket="$D/munge.sock" --pid-file="$D/munged.pid" \
    --log-file="$D/munged.log" --seed-file="$D/munged.seed" || return 1
  track munged
  host=$(hostname)
  ctl=$(free_port $((20000 + $$ % 20000)))
  slurmd_port=$(free_port $((ctl + 1)))
  cat > "$D/slurm.conf" <<EOF
ClusterName=fogpipe-test
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$ctl
SlurmdPort=$slurmd_port
AuthType=auth/munge
AuthInfo=socket=$D/munge.sock
CredType=cred/munge
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
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
NodeName=fpnode NodeHostname=$host NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=fp Nodes=fpnode Default=YES MaxTime=10 State=UP
EOF
  SLURM_CONF=$D/slurm.conf
  export SLURM_CONF
  timeout 20 slurmctld -c -f "$D/slurm.conf" || return 1
  timeout 20 slurmd -f "$D/slurm.conf" -N fpnode || return 1
  # The pid files appear once the daemons are up; the node goes idle once
  # slurmd has registered.
  n=0
  while [ $n -lt 40 ]; do
    track slurmctld
    track slurmd
    if [ -s "$D/slurmd.pid.saved" ] && timeout 5 sinfo -h -o %T 2>/dev/null | grep -q '^idle'; then
      return 0
    fi
    sleep 0.5
    n=$((n + 1))
  done
  return 1
}

reason=$(slurm_skip_reason)
if [ -n "$reason" ]; then
  skip "Slurm array job: $reason"
elif ! start_slurm > "$T/slurm-start.txt" 2>&1; then
  for f in "$D"/*.log; do [ -f "$f" ] && tail -n 5 "$f" >> "$T/slurm-start.txt"; done
  skip "Slurm array job: could not start a one-node Slurm on loopback (see $T/slurm-start.txt)"
  stop_slurm
else
  mkdir -p "$T/slurm-advect"
  # shellcheck disable=SC2086
  if env FIRST=1 LAST=8 FOGPIPE="$FOGPIPE" timeout 120 sbatch --wait --array=0-3 \
       --output="$T/slurm-advect/task-%A_%a.log" "$FARM/slurm-array.sh" \
       -q -i "$T/in/scene.####.exr" -o "$T/slurm-advect/out.####.exr" $COMMON $CONF_ADVECT \
       > "$T/sbatch.txt" 2>&1; then
    ok "Slurm array job (4 tasks of 1-8) on a one-node Slurm"
  else
    not_ok "Slurm array job (4 tasks of 1-8) on a one-node Slurm"
    diag "$T/sbatch.txt"
    for f in "$T"/slurm-advect/task-*.log "$D/slurmctld.log" "$D/slurmd.log"; do
      [ -f "$f" ] && tail -n 5 "$f" | sed 's/^/# /'
    done
  fi
  check "Slurm: the tasks' frames are byte-identical to one run's" same_frames "$T/one-advect" "$T/slurm-advect"
  check "Slurm: each task did its own chunk" sh -c 'grep -h "frames" "$1"/task-*.log | sort | tr "\n" " " | grep -q "frames 1-2 .*frames 3-4 .*frames 5-6 .*frames 7-8"' sh "$T/slurm-advect"
  stop_slurm
fi
if [ -n "$PIDS" ]; then
  left=""
  for pid in $PIDS; do pid_alive "$pid" && left="$left $pid"; done
  check "the daemons this test started are stopped (${PIDS# })" test -z "$left"
fi
finish
