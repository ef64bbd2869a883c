#!/bin/sh
# Fog a frame range in CHUNKS processes with GNU parallel.  A fogpipe frame
# depends only on its number and its inputs (wind, turbulence, sequences
# and advection included), so the chunks write the same bytes as one run.
#
#   samples/farm/parallel.sh FIRST LAST CHUNKS [fogpipe options...]
#
#   samples/farm/parallel.sh 1001 1100 8 -i shot.####.exr -o fogged.####.exr \
#       --fogmap fog.exr --wind 2,0.5 --turbulence 0.3
#
# Environment: FOGPIPE (default: fogpipe from PATH), JOBS (parallel's -j,
# default CHUNKS), PARALLEL_OPTS (more options for GNU parallel, e.g.
# "--sshloginfile nodes.txt" to spread the chunks over machines that see the
# same files).  With --advect, give every chunk the same --cache-dir on a
# shared file system: a chunk starting late resumes from the latest
# advection state another chunk saved instead of recomputing from the start.
set -eu
if [ $# -lt 3 ]; then
  sed -n '2,17p' "$0" >&2
  exit 2
fi
first=$1 last=$2 chunks=$3
shift 3
case "$first$last$chunks" in
  *[!0-9-]*) echo "parallel.sh: FIRST, LAST and CHUNKS must be integers" >&2; exit 2 ;;
esac
if [ "$last" -lt "$first" ] || [ "$chunks" -lt 1 ]; then
  echo "parallel.sh: expected FIRST <= LAST and CHUNKS >= 1" >&2
  exit 2
fi
# CHUNKS ranges of (almost) equal length, as fogpipe's --frames A-B.
n=$((last - first + 1))
size=$(((n + chunks - 1) / chunks))
ranges=""
a=$first
while [ "$a" -le "$last" ]; do
  b=$((a + size - 1))
  [ "$b" -le "$last" ] || b=$last
  ranges="$ranges $a-$b"
  a=$((b + 1))
done
# -q quotes fogpipe's arguments (patterns such as shot.####.exr stay whole);
# --halt: the first failing chunk stops the others and fails the whole.
# shellcheck disable=SC2086
exec parallel --will-cite -q --halt now,fail=1 -j "${JOBS:-$chunks}" ${PARALLEL_OPTS:-} \
  "${FOGPIPE:-fogpipe}" --frames {} "$@" ::: $ranges
