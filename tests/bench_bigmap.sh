#!/bin/sh
# make bench (issue 26, the fogmap half): a detailed 4096x4096 fogmap
# (fractal noise: 11 octaves of value noise, gain 0.5, lacunarity 2, not
# an upsampled map): its set-up with and without the decomposition cache
# (filters/fogmap_cache.h), peak RSS, and its marginal cost per pixel
# against the 64x64 sample map, exact, at --lod-bound 1e-4 and at
# --lod-footprint 1.  Markdown on stdout; figures, never pass/fail.
#   tests/bench_bigmap.sh FRAME.exr FOG64.exr WORKDIR   (FOGPIPE, OIIOTOOL set)
set -eu
frame=$1
fog64=$2
w=$3
oiio=${OIIOTOOL:-oiiotool}
mkdir -p "$w"
gtime=/usr/bin/time
[ -x "$gtime" ] || { echo "(tests/bench_bigmap.sh: no $gtime, skipped)"; exit 0; }

# The map: octave k (k = 2..12) is 2^k x 2^k uniform noise upsampled with
# the triangle filter, amplitude 2^-(k-2); 0.06 added so that no pixel is
# negative.
map=$w/fbm4096.exr
if [ ! -f "$map" ]; then
  set -- --pattern noise:type=uniform:min=0:max=1:seed=1 4x4 1 --resize:filter=triangle 4096x4096
  for k in 3 4 5 6 7 8 9 10 11; do
    s=$((1 << k))
    a=$(awk -v k="$k" 'BEGIN { printf "%.10g", 2 ^ -(k - 2) }')
    set -- "$@" --pattern "noise:type=uniform:min=-0.5:max=0.5:seed=$k" "${s}x${s}" 1 \
      --resize:filter=triangle 4096x4096 --mulc "$a" --add
  done
  "$oiio" "$@" --pattern noise:type=uniform:min=-0.5:max=0.5:seed=12 4096x4096 1 \
    --mulc 0.0009765625 --add --addc 0.06 -d float -o "$map"
fi
"$oiio" "$frame" --resize 320x180 -o "$w/f.0001.exr"
for f in 2 3 4 5 6 7 8 9; do cp "$w/f.0001.exr" "$w/f.000$f.exr"; done
LOOK="--fog-rect -60,-20,60,160 --density 0.1 --height 0,5"
export FOGPIPE_CACHE_DIR="$w/cache"
rm -rf "$w/cache"

# run FRAMES MAP ARGS...: "user+sys wall maxrss_kb setup_ms" of one run.
run() {
  local frames=$1 m=$2; shift 2
  # shellcheck disable=SC2086
  "$gtime" -f '%U %S %e %M' -o "$w/time.txt" "$FOGPIPE" -v -i "$w/f.####.exr" \
    -o "$w/o.####.exr" --frames "1-$frames" --fogmap "$m" $LOOK "$@" 2>"$w/log.txt"
  local setup
  setup=$(sed -n 's/.*levels, \(decomposed\|loaded from the fogmap cache\) in \([0-9.]*\) ms.*/\2/p' \
    "$w/log.txt" | head -n 1)
  awk -v s="${setup:--}" '{ printf "%.3f %.2f %d %s\n", $1 + $2, $3, $4, s }' "$w/time.txt"
}

echo "## A detailed 4096x4096 fogmap: set-up cached across runs, cost (issue 26)"
echo
echo "The map: fractal noise (11 octaves of value noise, 4x4 to 4096x4096, gain 0.5, each"
echo "upsampled with the triangle filter; not an upsampled smooth map), linear, 9 levels, on the"
echo "look of the fogmap rows above (fog rectangle -60,-20,60,160, density 0.1, height 0,5), the"
echo "320x180 frames of the sample scene. CPU: getrusage user+sys of the whole run (/usr/bin/time),"
echo "PoCL's threads included; set-up: the decomposition, or the cache file's hash check and read"
echo "(fogpipe -v); RSS: the run's peak."
echo
echo "| run | set-up ms | CPU s | wall s | peak RSS MB |"
echo "|---|---|---|---|---|"
for c in "decomposed (--fogmap-cache off)|--fogmap-cache off" \
         "decomposed, the cache file written|" "loaded from the cache|"; do
  set -- $(run 1 "$map" ${c#*|})
  printf '| %s | %s | %s | %s | %.0f |\n' "${c%%|*}" "$4" "$1" "$2" "$(($3 / 1024))"
done
echo
echo "Marginal CPU per pixel: [run of N frames - run of 1 frame] / (N - 1) / 57600 pixels, each"
echo "run's least CPU over 3 interleaved rounds (the set-up, cached, cancels; N = 9 for the 64x64"
echo "map, 2 for the 4096)."
echo
echo "| map | mode | CPU us/px | x 64x64 exact |"
echo "|---|---|---|---|"
base=
for c in "64x64 sample map|exact|$fog64|" "4096 fractal|exact|$map|" \
         "4096 fractal|--lod-bound 1e-4|$map|--lod-bound 1e-4" \
         "4096 fractal|--lod-footprint 1 (not bounded)|$map|--lod-footprint 1"; do
  name=${c%%|*}; r=${c#*|}; mode=${r%%|*}; r=${r#*|}; m=${r%%|*}; args=${r#*|}
  n=2
  [ "$m" != "$fog64" ] || n=9
  one=; many=
  for round in 1 2 3; do
    one=$(run 1 "$m" $args | awk -v b="$one" '{ print (b == "" || $1 < b) ? $1 : b }')
    many=$(run "$n" "$m" $args | awk -v b="$many" '{ print (b == "" || $1 < b) ? $1 : b }')
  done
  best=$(awk -v a="$one" -v b="$many" -v n="$n" 'BEGIN { print (b - a) / (n - 1) / 57600 * 1e6 }')
  [ -n "$base" ] || base=$best
  awk -v n="$name" -v mo="$mode" -v v="$best" -v b="$base" \
    'BEGIN { printf "| %s | %s | %.2f | %.1fx |\n", n, mo, v, (b > 0 ? v / b : 0) }'
done
