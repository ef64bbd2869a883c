#!/bin/sh
# The user's shadow map judged (filters/shadowcheck.h): the sample scene's
# 1024-texel sun map (0.16 m texels) holds the pillars seen through the
# wall's gaps 5 texels across: one warning per run, naming the map, the
# frame, the caster's width and place and the map that would hold it; -v
# prints every frame's report; at 2048 texels (10 across) nothing is said.
# Presets that want a shadow map (wants = shadow-map) warn once when run
# without one, naming what to give and whose sun theirs is.
. "${FP_SRCDIR:-.}/tests/lib.sh"
"$FP_SCENE" -o "$T/a" --width 64 --height 36 --frames 1-2 --shadow-size 1024 >/dev/null
"$FP_SCENE" -o "$T/b" --width 64 --height 36 --frames 1-1 --shadow-size 2048 >/dev/null

check "two frames with a coarse map: exit 0" sh -c \
  "\"\$0\" --progress off --sun -0.4,0.35,0.6 --shadow-map '$T/a/shadow.####.exr' \
   -i '$T/a/scene.####.exr' -o '$T/o.####.exr' 2>'$T/warn.txt'" "$FOGPIPE"
check "... one warning for the run" test "$(grep -c 'warning' "$T/warn.txt")" = 1
check "... naming the map and frame, the caster 5 texels (0.816 units) across, where" \
  grep -Eq "shadow\.0001\.exr: frame 1: the shadow map's thinnest caster is 5 texels \(0\.816 scene units\) across, [0-9]+ long, at texel \([0-9]+, [0-9]+\), world \(2\.9[0-9]*, [0-9.]+, 34\.[0-9]+\)" "$T/warn.txt"
check "... and the map that holds it, 8 texels across" \
  grep -Eq "a map of 0\.102 scene units a texel \(1639x1639 over the same area\) holds it 8 texels across, or --shadows map\+screen" "$T/warn.txt"
check "-v: every frame's report" sh -c \
  "\"\$0\" -v --progress off --sun -0.4,0.35,0.6 --shadow-map '$T/a/shadow.####.exr' \
   -i '$T/a/scene.####.exr' -o '$T/o.####.exr' 2>'$T/v.txt' &&
   test \$(grep -c 'shadow map 1024x1024, texels 0.1631 x 0.1631 scene units' '$T/v.txt') = 2" "$FOGPIPE"
check "a 2048-texel map: silent" sh -c \
  "\"\$0\" --progress off --sun -0.4,0.35,0.6 --shadow-map '$T/b/shadow.####.exr' \
   -i '$T/b/scene.####.exr' -o '$T/o.####.exr' 2>'$T/quiet.txt' && ! test -s '$T/quiet.txt'" "$FOGPIPE"
check "-q: no warning" sh -c \
  "\"\$0\" -q --progress off --sun -0.4,0.35,0.6 --shadow-map '$T/a/shadow.####.exr' \
   -i '$T/a/scene.####.exr' -o '$T/o.####.exr' 2>'$T/q.txt' && ! test -s '$T/q.txt'" "$FOGPIPE"
P="$FP_SRCDIR/samples/presets"
for look in low-sun-shafts morning-valley-mist; do
  check "$look without a shadow map, two frames: exit 0" sh -c \
    "\"\$0\" --progress off --preset '$P/$look.preset' -i '$T/a/scene.####.exr' \
     -o '$T/o.####.exr' 2>'$T/want.txt'" "$FOGPIPE"
  check "... one warning, naming the preset, what to give and whose sun it is" sh -c \
    "test \$(wc -l <'$T/want.txt') = 1 &&
     grep -q '$look.preset wants the sun.s shadow map .*give --shadow-map PATTERN.*its sun is the sample scene.s, which a frame.s own sun (its rig) or --sun replaces' '$T/want.txt'"
done
check "with its map: no such warning" sh -c \
  "\"\$0\" --progress off --preset '$P/low-sun-shafts.preset' --shadow-map '$T/b/shadow.####.exr' \
   -i '$T/b/scene.####.exr' -o '$T/o.####.exr' 2>'$T/w2.txt' && ! grep -q wants '$T/w2.txt'" "$FOGPIPE"
check "--shadows none chosen: no warning" sh -c \
  "\"\$0\" --progress off --preset '$P/low-sun-shafts.preset' --shadows none \
   -i '$T/b/scene.####.exr' -o '$T/o.####.exr' 2>'$T/w3.txt' && ! test -s '$T/w3.txt'" "$FOGPIPE"
check "night-street-lamps wants nothing: no warning" sh -c \
  "\"\$0\" --progress off --preset '$P/night-street-lamps.preset' \
   -i '$T/b/scene.####.exr' -o '$T/o.####.exr' 2>'$T/w4.txt' && ! test -s '$T/w4.txt'" "$FOGPIPE"
finish
