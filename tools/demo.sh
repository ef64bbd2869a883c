#!/bin/sh
# The demo: fog the sample sequence and say where the frames are.
#   tools/demo.sh ./fogpipe samples/out
set -eu
bin=$1 samples=$2
out=demo-out
mkdir -p "$out"
# Patches of wavelet fog over the ground from the sample fogmap, a thin haze.
"$bin" -i "$samples/scene.####.exr" -o "$out/fogged.####.exr" --frames 1-8 \
  --fogmap "$samples/fogmap.exr" --fog-rect -60,-20,60,160 --basis quadratic --levels 3 \
  --density 0.1 --height 0,5 --haze 0.004 --fog-color 0.75,0.78,0.82
"$bin" --fogmap "$samples/fogmap.exr" --basis quadratic --levels 3 --fogmap-preview "$out/levels" >/dev/null
# Light in the fog: the named looks of samples/presets (the sun's shadow
# maps come from the sample generator).
presets=$(dirname "$0")/../samples/presets
for look in morning-valley-mist low-sun-shafts night-street-lamps; do
  shadow=""
  grep -q '^sun *=' "$presets/$look.preset" && shadow="--shadow-map $samples/shadow.####.exr"
  # shellcheck disable=SC2086
  "$bin" --preset "$presets/$look.preset" $shadow -i "$samples/scene.####.exr" \
    -o "$out/$look.####.exr" --frames 1,8
done
if command -v oiiotool >/dev/null; then
  for f in 1 8; do
    n=$(printf %04d "$f")
    for look in fogged morning-valley-mist low-sun-shafts night-street-lamps; do
      oiiotool "$out/$look.$n.exr" --ch R,G,B --colorconvert linear sRGB -d uint8 -o "$out/$look.$n.png" 2>/dev/null || true
    done
  done
fi
echo "demo: sample frames in $samples/scene.0001.exr .. scene.0008.exr"
echo "demo: fogged frames in $(pwd)/$out/fogged.0001.exr .. fogged.0008.exr (PNG previews of 1 and 8 beside them)"
echo "demo: the fogmap's wavelet levels in $(pwd)/$out/levels/"
echo "demo: the preset looks (samples/presets) in $(pwd)/$out/<look>.0001.exr and .0008.exr"
