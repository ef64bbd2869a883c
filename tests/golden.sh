#!/bin/sh
# Golden frames: two frames of the sample scene fogged with a fixed look,
# compared with OpenImageIO's idiff.  Thresholds: no pixel channel off by
# more than 0.004 (hard), at most 0.1% of them off by more than 0.001
# (about one half-float step near 1.0, room for other OpenCL devices'
# exp/float rounding).  `make golden` rewrites them on purpose.
update=0
[ "${1:-}" = --update ] && update=1
if [ "$update" = 1 ]; then
  FP_TMP=${FP_TMP:-$(mktemp -d)}; FP_SRCDIR=${FP_SRCDIR:-$(cd "$(dirname "$0")/.." && pwd)}
  IDIFF=${IDIFF:-idiff}
fi
. "${FP_SRCDIR:-.}/tests/lib.sh"
G="$FP_SRCDIR/tests/golden"

# name | options
P="$FP_SRCDIR/samples/presets"
FM="--fogmap $FP_SAMPLES/fogmap.exr --fog-rect -60,-20,60,160 --density 0.1 --height 0,5 --levels 3"
cases="height|--density 0.03 --height 0,12 --fog-color 0.75,0.78,0.82
homogeneous|--visibility 150 --height 0,inf --fog-color 0.6,0.65,0.7
layer|--density 0.08 --height 1,2,6 --fog-color 0.9,0.9,0.95
fogmap-haar|$FM --basis haar
fogmap-linear|$FM --basis linear
fogmap-quadratic|$FM --basis quadratic
fogmap-cubic|$FM --basis cubic --haze 0.002
preset-mist|--preset $P/morning-valley-mist.preset --shadow-map $FP_SAMPLES/shadow.####.exr
preset-shafts|--preset $P/low-sun-shafts.preset --shadow-map $FP_SAMPLES/shadow.####.exr
preset-lamps|--preset $P/night-street-lamps.preset
lamps-shadowed|--preset $P/night-street-lamps.preset --lamp-shadows screen
buffers|--preset $P/low-sun-shafts.preset --shadow-map $FP_SAMPLES/shadow.####.exr --fog-resolution 1/2 --blur bilateral --blur-radius 3 --blur-falloff 4"
names=$(echo "$cases" | cut -d'|' -f1)

echo "$cases" | while IFS='|' read -r name opts; do
  for f in 1 5; do
    out="$T/$name.$f.exr"
    # shellcheck disable=SC2086
    "$FOGPIPE" $opts --frames "$f" -i "$FP_SAMPLES/scene.####.exr" -o "$T/$name.####.exr" || echo "fogpipe failed" > "$T/$name.failed"
    mv "$(printf "$T/$name.%04d.exr" "$f")" "$out" 2>/dev/null
    if [ "$update" = 1 ]; then
      cp "$out" "$G/$name.$f.exr" && echo "updated $G/$name.$f.exr" >&2
    fi
  done
done
[ "$update" = 1 ] && exit 0

for name in $names; do
  for f in 1 5; do
    check "golden $name frame $f (idiff -fail 0.001 -failpercent 0.1 -hardfail 0.004)" \
      "$IDIFF" -fail 0.001 -failpercent 0.1 -hardfail 0.004 "$G/$name.$f.exr" "$T/$name.$f.exr"
  done
done
finish
