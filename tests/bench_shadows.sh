#!/bin/sh
# make bench (tests/bench.sh): the user's shadow map (issue 23).  The
# low-sun-shafts look on frames 1 and 5 of the sample scene at 320x180,
# its sun shadows from maps of 1024, 512 and 256 texels (0.16, 0.33, 0.65
# m; the pillars 0.6 m, the wall's slits 0.5 m) with --shadows map and
# map+screen (THICK 1, the default, and 0.3), and the walk alone, against
# a 4096-texel map's exact walk (0.04 m texels: 15 across the pillars)
# taken as the exact answer; error of the composite RGB (idiff, both
# frames), CPU time of one frame (OpenCL).  Then what the map check says
# of each map.  Prints a markdown section.
#   tests/bench_shadows.sh TMPDIR   (FOGPIPE, FP_SCENE; IDIFF)
set -eu
tmp=$1
idiff=${IDIFF:-idiff}
for n in 4096 1024 512 256; do
  "$FP_SCENE" -o "$tmp/m$n" --width 320 --height 180 --frames 1-5 --shadow-size $n >/dev/null
done
look="--preset ${FP_SRCDIR:-.}/samples/presets/low-sun-shafts.preset"
run() {  # run OUT MAPSIZE OPTIONS...: frames 1 and 5, CPU seconds of frame 1
  o=$1 n=$2; shift 2
  for f in 1 5; do
    # shellcheck disable=SC2086
    /usr/bin/time -f %U -o "$tmp/t.$o.$f" "$FOGPIPE" -q --progress off $look \
      --shadow-map "$tmp/m$n/shadow.####.exr" -i "$tmp/m4096/scene.####.exr" --frames $f \
      -o "$tmp/$o.####.exr" "$@"
  done
}
run truth 4096 --shadows map
stats() {  # stats OUT: mean, RMS, max of both frames (mean of the frames' means and RMS)
  for f in 0001 0005; do
    "$idiff" -v -a "$tmp/truth.$f.exr" "$tmp/$1.$f.exr" 2>&1 |
      sed -n 's/.*Mean error = *\([^ ]*\).*/m \1/p; s/.*RMS error = *\([^ ]*\).*/r \1/p; s/.*Max error *= *\([^ ]*\).*/x \1/p'
  done | awk '$1 == "m" { m += $2 / 2 } $1 == "r" { r += $2 / 2 } $1 == "x" && $2 > x { x = $2 }
              END { printf "%.2g | %.2g | %.2g", m, r, x }'
}
echo "## Issue 23: the user's shadow map (--shadows map+screen, the map check)"
echo
echo "The low-sun-shafts look on frames 1 and 5 of the sample scene (320x180), against the"
echo "exact walk along a 4096-texel sun map (0.04 m texels: 15 across the 0.6 m pillars), as"
echo "the exact answer; composite RGB error over both frames (idiff: mean and RMS of the two"
echo "frames' figures, the larger max); CPU seconds of frame 1 (user, OpenCL on PoCL, the"
echo "program's start included). The walk (--shadows screen) loses every caster outside the"
echo "frame; map+screen keeps them through the map, and adds the walk's shadows (its cells"
echo "THICK deep behind what each pixel shows, so it shadows a little more than there is)."
echo
echo "| sun map | --shadows | mean \\|err\\| | RMS | max | CPU s |"
echo "|---|---|---|---|---|---|"
run none 4096 --shadows none
echo "| - | none | $(stats none) | $(cat "$tmp/t.none.1") |"
run screen 4096 --shadows screen
echo "| - | screen | $(stats screen) | $(cat "$tmp/t.screen.1") |"
for n in 1024 512 256; do
  texel=$(awk -v n=$n 'BEGIN { printf "%.2f", 167 / n }')
  run map$n $n --shadows map
  echo "| $n ($texel m) | map | $(stats map$n) | $(cat "$tmp/t.map$n.1") |"
  run ms$n $n --shadows map+screen
  echo "| $n ($texel m) | map+screen | $(stats ms$n) | $(cat "$tmp/t.ms$n.1") |"
  run mt$n $n --shadows map+screen --screen-shadow 20,0.3
  echo "| $n ($texel m) | map+screen, THICK 0.3 | $(stats mt$n) | $(cat "$tmp/t.mt$n.1") |"
done
echo
echo "What the map check says of each map (fogpipe -v, frame 1):"
echo
for n in 1024 512 256 4096; do
  "$FOGPIPE" -v --progress off $look --shadow-map "$tmp/m$n/shadow.####.exr" \
    -i "$tmp/m4096/scene.####.exr" --frames 1 -o "$tmp/v.####.exr" 2>&1 |
    sed -n 's/^fogpipe: .*shadow\.0001\.exr: frame 1: \(shadow map .*\)/- \1/p'
done
