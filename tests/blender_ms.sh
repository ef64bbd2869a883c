#!/bin/sh
# fogpipe's Monte Carlo reference against Cycles' multiple scattering
# (issue 28; doc/notes/multiple-scattering.md).  tests/blender/ms_scene.py:
# a scatter-only height fog (albedo 1, isotropic) over a black ground with
# a black wall with slits and pillars, a sun 18 degrees up; Cycles renders
# it with volume_bounces 32 (33 scattering events), the VolumeDir
# (single) and VolumeInd (the rest) passes, two seeds; fogpipe's reference
# (--bounces 0 and 32, two seeds) on the plate with the add-on's rig and
# the sun's map.  tests/blender/ms_run.sh and ms_compare.py: over the
# frame, single and multiple scattering within max(2%, 3 x the noise) of
# Cycles', in a thin (sigma0 0.025) and a dense (0.1) fog; and the check
# fails when scattered paths cross the geometry (--ref-geometry 0: 12-19%
# too much light).  The fast path (--multiple-scattering, no fog color)
# on the same frames: |bias| <= 2% of the fog's light, 8x8-block rms <= 3
# x Cycles' noise; it misses with the fast path off.  Skips when blender
# is not installed.
. "${FP_SRCDIR:-.}/tests/lib.sh"
BLENDER=${BLENDER:-blender}
if ! command -v "$BLENDER" >/dev/null 2>&1; then
  skip "blender is not installed (Debian package blender; ./bootstrap check installs it)"
  finish
  exit $?
fi
RUN="$FP_SRCDIR/tests/blender/ms_run.sh"
export FOGPIPE BLENDER
for fog in thin:0.025 dense:0.1; do
  name=${fog%%:*} sigma=${fog#*:}
  desc="$name fog (sigma0 $sigma), wall: the reference's single and multiple scattering are Cycles' (2%, 3 x noise)"
  if FP_MS_MAXBIAS=0.02 sh "$RUN" "$T/$name" 128 256 sigma="$sigma" occluder=1 > "$T/$name.txt" 2>&1; then
    ok "$desc"
  else
    not_ok "$desc"
  fi
  diag "$T/$name.txt"
  # The fast path (no fog color: --fog-color auto, --multiple-scattering
  # auto) on the same frame: bias and 8x8-block rms against Cycles' whole
  # fog light (tests/blender/msfast_compare.py); and single scattering
  # alone (off, fog color 0) must miss.
  opts=$(sed 's/--fog-color [^ ]*//' "$T/$name/scene.txt")
  : > "$T/$name-fast.txt"
  for ms in auto off; do
    color=auto
    [ "$ms" = off ] && color=0,0,0
    # shellcheck disable=SC2086 # the options are words
    nice -n 19 "$FOGPIPE" -q -i "$T/$name/plate.####.exr" -o "$T/$name/fast-$ms.####.exr" \
      --frames 1 $opts --multiple-scattering "$ms" --fog-color "$color" --float \
      >> "$T/$name-fast.txt" 2>&1 || true
    python3 "$FP_SRCDIR/tests/blender/msfast_compare.py" "$T/$name/ms1.0001.exr" \
      "$T/$name/ms2.0001.exr" "$T/$name/fast-$ms.0001.exr" 0.02 3 >> "$T/$name-fast.txt" 2>&1
    st=$?
    if [ "$ms" = auto ]; then
      desc="$name fog: the fast path without a fog color is Cycles' light (|bias| 2%, 8x8 blocks 3 x noise)"
      if [ $st = 0 ]; then ok "$desc"; else not_ok "$desc"; fi
    else
      desc="$name fog: the same check misses without multiple scattering"
      if [ $st = 1 ] && grep -q "^MISS" "$T/$name-fast.txt"; then ok "$desc"; else not_ok "$desc"; fi
    fi
  done
  diag "$T/$name-fast.txt"
done
desc="dense fog: the comparison fails when scattered paths cross the geometry (--ref-geometry 0)"
if FP_SKIP_CYCLES=1 FP_EXTRA="--ref-geometry 0" FP_MS_MAXBIAS=0.02 sh "$RUN" "$T/dense" 128 256 \
  > "$T/wrong.txt" 2>&1; then
  not_ok "$desc"
elif grep -q "^MISS multiple" "$T/wrong.txt"; then
  ok "$desc"
else
  not_ok "$desc: no comparison made"
fi
diag "$T/wrong.txt"
finish
