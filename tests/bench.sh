#!/bin/sh
# make bench: figures, never pass/fail on time.  Writes BENCHMARKS.md.
#   tests/bench.sh BENCHMARKS.md   (FOGPIPE, FP_SCENE, FP_BENCH_FOG set by make)
set -eu
out=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$FP_SCENE" -o "$tmp/hd" --width 1920 --height 1080 --frames 1-4 --shadow-size 0 >/dev/null
"$FP_SCENE" -o "$tmp/seed" --width 800 --height 600 --frames 1-1 --shadow-size 0 >/dev/null
{
  echo "# fogpipe benchmarks"
  echo
  echo "Written by \`make bench\` on $(date -u +%Y-%m-%d) ($(uname -m), $(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'))."
  echo "Timings are figures, not pass/fail thresholds."
  echo
  echo "## Height fog stage (exact closed form), one frame"
  echo
  echo "Kernel time per frame (upload depth, integrate, read back), the C double-precision"
  echo "reference's time, and the OpenCL result's transmittance error against it."
  echo
  echo "| device | size | OpenCL ms/frame | Mpixel/s | C reference ms | max abs error tau | RMS error tau |"
  echo "|---|---|---|---|---|---|---|"
  "$FP_BENCH_FOG" "$tmp/seed/scene.0001.exr" 20
  "$FP_BENCH_FOG" "$tmp/hd/scene.0001.exr" 10
  echo
  echo "## Whole pipeline, 4 frames of 1920x1080 (read, fog, composite, write half ZIP)"
  echo
  echo "| run | seconds | frames/s |"
  echo "|---|---|---|"
  for mode in io fog; do
    s=$(date +%s.%N)
    if [ "$mode" = io ]; then
      "$FOGPIPE" -i "$tmp/hd/scene.####.exr" -o "$tmp/io.####.exr" --density 0 --frames 1-4
      label="density 0 (close to the I/O floor)"
    else
      "$FOGPIPE" -i "$tmp/hd/scene.####.exr" -o "$tmp/fog.####.exr" --frames 1-4
      label="height fog, OpenCL"
    fi
    e=$(date +%s.%N)
    awk -v s="$s" -v e="$e" -v l="$label" 'BEGIN { printf "| %s | %.2f | %.2f |\n", l, e - s, 4 / (e - s) }'
  done
} > "$out.tmp"
mv "$out.tmp" "$out"
cat "$out"
