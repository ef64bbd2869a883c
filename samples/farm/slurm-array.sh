#!/bin/bash
# Fog a frame range as a Slurm array job: array task k of N fogs the k-th of
# N (almost) equal chunks of FIRST..LAST.  A fogpipe frame depends only on
# its number and its inputs, so the tasks write the same bytes as one run.
#
#   FIRST=1001 LAST=1100 sbatch --array=0-9 samples/farm/slurm-array.sh \
#       -i /shared/shot.####.exr -o /shared/fogged.####.exr --fogmap /shared/fog.exr
#
# Everything after the script's name goes to fogpipe.  sbatch exports the
# submitting environment (FIRST, LAST, FOGPIPE: the fogpipe to run, default
# fogpipe from PATH).  Paths must be the same on every node (a shared file
# system).  Outputs appear whole or not at all, so a requeued task only
# redoes its chunk.  With --advect, give every task the same --cache-dir
# on the shared file system: a late chunk resumes from the latest saved
# advection state instead of recomputing from --advect-start.
#
#SBATCH --job-name=fogpipe
#SBATCH --array=0-3
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=1
#SBATCH --output=fogpipe-%A_%a.log
set -euo pipefail
: "${FIRST:?set FIRST and LAST, the frame range (FIRST=1001 LAST=1100 sbatch ...)}"
: "${LAST:?set FIRST and LAST, the frame range (FIRST=1001 LAST=1100 sbatch ...)}"
task=$((${SLURM_ARRAY_TASK_ID:-0} - ${SLURM_ARRAY_TASK_MIN:-0}))
count=${SLURM_ARRAY_TASK_COUNT:-1}
n=$((LAST - FIRST + 1))
size=$(((n + count - 1) / count))
a=$((FIRST + task * size))
b=$((a + size - 1))
((b <= LAST)) || b=$LAST
if ((a > LAST)); then
  echo "fogpipe array task $task of $count: no frames left (range $FIRST-$LAST)"
  exit 0
fi
echo "fogpipe array task $task of $count on $(hostname): frames $a-$b"
exec "${FOGPIPE:-fogpipe}" --frames "$a-$b" "$@"
