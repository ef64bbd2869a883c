#!/bin/sh
# make bench: figures, never pass/fail on time.  Writes BENCHMARKS.md.
#   tests/bench.sh BENCHMARKS.md   (FOGPIPE, FP_SCENE, FP_BENCH_FOG set by make)
set -eu
out=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$FP_SCENE" -o "$tmp/seed" --width 800 --height 600 --frames 1-1 --shadow-size 0 >/dev/null
"$FP_SCENE" -o "$tmp/hd" --width 1920 --height 1080 --frames 1-4 --shadow-size 0 >/dev/null
{
  echo "# fogpipe benchmarks"
  echo
  echo "Written by \`make bench\` on $(date -u +%Y-%m-%d) ($(uname -m), $(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'))."
  echo "Load average when it started: $(cut -d' ' -f1-3 /proc/loadavg) (other work on the machine slows the figures down)."
  echo "Timings are figures, not pass/fail thresholds. Fog stage times include the upload of"
  echo "the depth and the read-back of the fog layer. 800x600 is the resolution of seed 000."
  echo
  "$FP_BENCH_FOG" "$tmp/seed/scene.0001.exr"
  echo
  echo "## Whole pipeline, 4 frames of 1920x1080 (read, fog, composite, write half ZIP)"
  echo
  echo "| run | seconds | frames/s |"
  echo "|---|---|---|"
  for mode in io fog; do
    s=$(date +%s.%N)
    if [ "$mode" = io ]; then
      "$FOGPIPE" -q -i "$tmp/hd/scene.####.exr" -o "$tmp/io.####.exr" --density 0 --frames 1-4
      label="density 0 (close to the I/O floor)"
    else
      "$FOGPIPE" -q -i "$tmp/hd/scene.####.exr" -o "$tmp/fog.####.exr" --frames 1-4
      label="height fog, OpenCL"
    fi
    e=$(date +%s.%N)
    awk -v s="$s" -v e="$e" -v l="$label" 'BEGIN { printf "| %s | %.2f | %.2f |\n", l, e - s, 4 / (e - s) }'
  done
} > "$out.tmp"
mv "$out.tmp" "$out"
cat "$out"
