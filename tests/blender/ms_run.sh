#!/bin/sh
# Issue 28: Cycles' single and multiple scattering against fogpipe's
# Monte Carlo reference (doc/notes/multiple-scattering.md).
#   tests/blender/ms_run.sh OUTDIR CYCLES_SAMPLES FP_SPP [ms_scene.py options...]
# Renders the scene with Cycles (tests/blender/ms_scene.py, two seeds,
# volume_bounces 32 unless bounces= says), then fogpipe's reference of the
# black plate with --bounces 0 and --bounces N (two seeds each, the rig
# from the plate, the medium from OUTDIR/scene.txt, FP_EXTRA added), and
# prints tests/blender/ms_compare.py's table.  FOGPIPE, BLENDER: the
# programs (default ./fogpipe, blender); FP_SKIP_CYCLES=1 reuses OUTDIR's
# renders; FP_MS_MAXBIAS: ms_compare.py's pass/fail bound (exit status).
# Everything runs under nice -n 19.
set -e
out=$1 cs=$2 spp=$3
shift 3
src=$(cd "$(dirname "$0")/../.." && pwd)
FOGPIPE=${FOGPIPE:-$src/fogpipe}
BLENDER=${BLENDER:-blender}
n=32
for a in "$@"; do
  case $a in bounces=*) n=${a#bounces=} ;; esac
done
if [ "${FP_SKIP_CYCLES:-0}" != 1 ]; then
  nice -n 19 "$BLENDER" -b --factory-startup -noaudio -P "$src/samples/blender/fogpipe_blender/__init__.py" \
    -P "$src/tests/blender/ms_scene.py" -- "$out" "$cs" "$@" > "$out.blender.log" 2>&1 ||
    { grep -i -E "error|traceback" "$out.blender.log" | head; exit 1; }
  grep "^ Time: " "$out.blender.log" | tail -n +2 | head -n 2 | sed 's/^/cycles render/'
fi
for b in 0 "$n"; do
  for seed in 1 2; do
    # shellcheck disable=SC2046 # the options are words
    /usr/bin/time -f "fogpipe bounces $b seed $seed: %e s" nice -n 19 "$FOGPIPE" -q \
      -i "$out/plate.####.exr" -o "$out/fp$b-$seed.####.exr" --frames 1 \
      $(cat "$out/scene.txt") --integrator reference --bounces "$b" --spp "$spp" --seed "$seed" \
      --float ${FP_EXTRA:-}
  done
done
python3 "$src/tests/blender/ms_compare.py" "$out/ms1.0001.exr" "$out/ms2.0001.exr" \
  "$out/fp0-1.0001.exr" "$out/fp0-2.0001.exr" "$out/fp$n-1.0001.exr" "$out/fp$n-2.0001.exr" \
  ${FP_MS_MAXBIAS:-}
