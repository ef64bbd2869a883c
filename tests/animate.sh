#!/bin/sh
# Animated fog from the command line: still camera and still fog give
# byte-identical frames; under wind a frame is the previous one moved by
# wind / fps (mean |difference| after undoing the shift, reported); a
# fogmap sequence's key frames equal the still fogmap; advection and
# turbulence make frame N the same whichever frame a run starts at (with
# and without --cache-dir); per-frame decomposition times under -v; usage
# errors.
. "${FP_SRCDIR:-.}/tests/lib.sh"
FM=$FP_SAMPLES/fogmap.exr
# The sample frames at a quarter of their size (the header's camera holds).
S=$T/in
mkdir -p "$S"
for f in 1 2 3 4 5 6 7 8 9 10; do
  "$OIIOTOOL" "$FP_SAMPLES/scene.000$((f < 9 ? f : 8)).exr" --resize 80x45 -o "$S/scene.$(printf %04d $f).exr"
done

# A still camera: the same frame four times.
for f in 1 2 3 4; do cp "$S/scene.0001.exr" "$T/still.000$f.exr"; done
check "still camera, still fog" "$FOGPIPE" -i "$T/still.####.exr" -o "$T/s.####.exr" \
  --fogmap "$FM" --fog-rect -20,-10,20,30 --density 0.2 --height 0,3
check "... consecutive frames are byte-identical" sh -c \
  'cmp "$1/s.0001.exr" "$1/s.0002.exr" && cmp "$1/s.0002.exr" "$1/s.0003.exr" && cmp "$1/s.0003.exr" "$1/s.0004.exr"' sh "$T"
check "still fog with the animation options at rest: the same bytes" "$FOGPIPE" \
  -i "$T/still.####.exr" -o "$T/r.####.exr" --fogmap "$FM" --fog-rect -20,-10,20,30 \
  --density 0.2 --height 0,3 --wind 0,0 --turbulence 0 --fps 30
check "... equal to the plain run" sh -c 'cmp "$1/s.0001.exr" "$1/r.0001.exr" && cmp "$1/s.0004.exr" "$1/r.0004.exr"' sh "$T"
check "turbulence at speed 0 is still too" "$FOGPIPE" -i "$T/still.####.exr" -o "$T/z.####.exr" \
  --fogmap "$FM" --fog-rect -20,-10,20,30 --density 0.2 --height 0,3 --turbulence 0.7 \
  --turbulence-speed 0
check "... consecutive frames are byte-identical" sh -c 'cmp "$1/z.0001.exr" "$1/z.0002.exr" && cmp "$1/z.0003.exr" "$1/z.0004.exr"' sh "$T"

# Wind, seen from straight above: a ground plane 1000 units below the
# camera fills 64 pixels with 64 units, a fog layer 1 unit thick on it, and
# a wind of 24 units/s at 24 fps moves it one pixel per frame.
"$OIIOTOOL" --pattern constant:color=0.2,0.3,0.4,1,1000 64x64 5 --chnames R,G,B,A,Z -d float \
  -o "$T/top.0001.exr"
for f in 2 3; do cp "$T/top.0001.exr" "$T/top.000$f.exr"; done
check "wind seen from above" "$FOGPIPE" -i "$T/top.####.exr" -o "$T/w.####.exr" --float \
  --camera-pos 0,1000,0 --camera-rot -90,0,0 --vfov 3.66544 --height 0,inf,1 --density 1 \
  --fogmap "$FM" --fog-rect -32,-32,32,32 --wind 24,0
# mean_diff A B XA XB: mean |A - B| over R,G,B of the 63-column windows
# starting at columns XA and XB.
mean_diff() {
  "$OIIOTOOL" "$1" --ch R,G,B --cut 63x64+$3+0 "$2" --ch R,G,B --cut 63x64+$4+0 --diff 2>&1 |
    sed -n 's/.*Mean error = *//p'
}
raw=$(mean_diff "$T/w.0003.exr" "$T/w.0002.exr" 0 0)
undone=$(mean_diff "$T/w.0003.exr" "$T/w.0002.exr" 1 0)
back=$(mean_diff "$T/w.0003.exr" "$T/w.0002.exr" 0 1)
echo "# wind 1 px/frame, consecutive frames: mean |diff| $raw as they are, $undone after undoing the shift ($back shifting the wrong way)"
check "wind: the change between frames is the motion (mean |diff| $raw, $undone after undoing the shift)" \
  awk -v r="$raw" -v u="$undone" -v b="$back" 'BEGIN { exit !(r > 1e-3 && u < 0.01 * r && b > r) }'

# A fogmap sequence: keys 1 and 5; the key frames are the still fogmaps.
"$OIIOTOOL" "$FM" -o "$T/key.0001.exr"
"$OIIOTOOL" "$FM" --flip --mulc 1.5 -o "$T/key.0005.exr"
check "fogmap sequence, interpolated" "$FOGPIPE" -i "$S/scene.####.exr" -o "$T/q.####.exr" \
  --frames 1-5 --fogmap "$T/key.####.exr" --fog-rect -20,-10,20,30 --density 0.2 --height 0,3
check "... key frame 1 equals the still first key" sh -c '
  "$FOGPIPE" -i "$1/scene.0001.exr" -o "$2/k1.exr" --fogmap "$2/key.0001.exr" --fog-rect -20,-10,20,30 --density 0.2 --height 0,3 &&
  cmp "$2/k1.exr" "$2/q.0001.exr"' sh "$S" "$T"
check "... key frame 5 equals the still last key" sh -c '
  "$FOGPIPE" -i "$1/scene.0005.exr" -o "$2/k5.exr" --frames 5 --fogmap "$2/key.0005.exr" --fog-rect -20,-10,20,30 --density 0.2 --height 0,3 &&
  cmp "$2/k5.exr" "$2/q.0005.exr"' sh "$S" "$T"
check "... held frames equal the key before them" sh -c '
  "$FOGPIPE" -i "$1/still.####.exr" -o "$1/h.####.exr" --frames 1-4 --fogmap "$1/key.####.exr" --fogmap-interp hold --fog-rect -20,-10,20,30 --density 0.2 --height 0,3 &&
  cmp "$1/h.0001.exr" "$1/h.0004.exr" && "$FOGPIPE" -i "$1/still.0001.exr" -o "$1/b.exr" --frames 3 --fogmap "$1/key.####.exr" --fog-rect -20,-10,20,30 --density 0.2 --height 0,3 &&
  ! cmp -s "$1/b.exr" "$1/h.0003.exr"' sh "$T"

# Advection and turbulence: frame 10 alone equals frame 10 of a run from 1,
# recomputed or resumed from the cache (which holds frame 9's state).
A="--fogmap $FM --fog-rect -20,-10,20,30 --density 0.2 --height 0,3 --wind 4,-2.5,3 --advect maccormack --turbulence 0.6 --seed 4"
# shellcheck disable=SC2086
check "advection + turbulence, frames 1-10, -v" sh -c '"$FOGPIPE" -v "$@" 2> "$0/v.txt"' "$T" \
  -i "$S/scene.####.exr" -o "$T/a.####.exr" --frames 1-10 $A --cache-dir "$T/cache"
check "... the decomposition time is reported per frame" grep -q "frame 10: fogmap decomposed in .* ms" "$T/v.txt"
# shellcheck disable=SC2086
check "... frame 10 alone, recomputed from the start" sh -c '"$FOGPIPE" "$@" && cmp "$0/a.0010.exr" "$0/b.0010.exr"' "$T" \
  -i "$S/scene.####.exr" -o "$T/b.####.exr" --frames 10 $A
# shellcheck disable=SC2086
check "... frame 10 alone, from the cache" sh -c '"$FOGPIPE" -v "$@" 2> "$0/c.txt" && cmp "$0/a.0010.exr" "$0/c.0010.exr"' "$T" \
  -i "$S/scene.####.exr" -o "$T/c.####.exr" --frames 10 $A --cache-dir "$T/cache"
check "... which was read" grep -q "state of frame 9 read from the cache" "$T/c.txt"
check "... frames differ from each other" sh -c '! cmp -s "$1/a.0005.exr" "$1/a.0006.exr"' sh "$T"

fails "--turbulence without --fogmap" 2 "turbulence needs --fogmap" "$T/u1.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/u1.exr" --turbulence 1
fails "--advect on a fogmap sequence" 2 "advect needs a still --fogmap" "$T/u2.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/u2.exr" --fogmap "$T/key.####.exr" --advect semi-lagrangian --wind 1,0
fails "a fogmap sequence with no keys" 1 "nokey.####.png: no frames found" "$T/u3.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/u3.exr" --fogmap "$T/nokey.####.png"
mkdir -p "$T/badkeys"
"$OIIOTOOL" "$FM" -o "$T/badkeys/k.0001.exr"
"$OIIOTOOL" "$FM" --resize 32x32 -o "$T/badkeys/k.0003.exr"
fails "a fogmap key of another size: named, with the frame" 1 "k.0003.exr: frame 2: fogmap key 3 is 32x32" \
  "$T/bk.0002.exr" "$FOGPIPE" -i "$S/scene.####.exr" -o "$T/bk.####.exr" --frames 2 --fogmap "$T/badkeys/k.####.exr"
fails "--wind needs two numbers" 2 "wind.*VX,VZ" "$T/u4.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/u4.exr" --wind 3
finish
