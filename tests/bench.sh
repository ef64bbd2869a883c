#!/bin/sh
# make bench: figures, never pass/fail on time.  Writes BENCHMARKS.md.
#   tests/bench.sh BENCHMARKS.md   (FOGPIPE, FP_SCENE, FP_BENCH_FOG set by make)
set -eu
out=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$FP_SCENE" -o "$tmp/seed" --width 800 --height 600 --frames 1-1 --shadow-size 0 >/dev/null
# 24 frames (bench_looks' height fog and sequence rows); the whole-pipeline
# section below uses the first 8.
"$FP_SCENE" -o "$tmp/hd" --width 1920 --height 1080 --frames 1-24 --shadow-size 0 >/dev/null
"$FP_SCENE" -o "$tmp/light" --width 400 --height 300 --frames 1-1 >/dev/null
{
  echo "# fogpipe benchmarks"
  echo
  echo "Written by \`make bench\` on $(date -u +%Y-%m-%d) ($(uname -m), $(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'))."
  echo "Load average when it started: $(cut -d' ' -f1-3 /proc/loadavg) (other work on the machine slows the figures down)."
  echo "Timings are figures, not pass/fail thresholds. Fog stage times include the upload of"
  echo "the depth and the read-back of the fog layer. 800x600 is the resolution of seed 000."
  echo
  cat "$(dirname "$0")/bench-before.md"
  "$FP_BENCH_FOG" "$tmp/seed/scene.0001.exr"
  echo
  "$FP_BENCH_FOGMAP" "$tmp/hd/scene.0001.exr" "$tmp/seed/scene.0001.exr"
  echo
  "$FP_BENCH_LIGHT" "$tmp/light/scene.0001.exr" "$tmp/light/shadow.0001.exr" "$tmp/light/fogmap.exr"
  [ -z "${FP_BENCH_LAMP_SHADOW:-}" ] || "$FP_BENCH_LAMP_SHADOW" "$tmp/light/scene.0001.exr"
  echo
  "$FP_BENCH_LOOKS" "$tmp/hd" "$tmp/looks" && echo   # issue 12: the looks against their goals
  # Issue 12 (b): --lod-bound on the looks' 4096x4096 map against the 64x64.
  if [ -n "${FP_BENCH_LOD:-}" ]; then
    "$FP_BENCH_LOD" "$tmp/looks/mid/scene.0001.exr" "$tmp/looks/mid/fogmap.exr" \
      "$tmp/looks/fog4096.exr" && echo
  fi
  # Issue 26: a detailed 4096x4096 fogmap, its set-up cached across runs.
  sh "$(dirname "$0")/bench_bigmap.sh" "$tmp/seed/scene.0001.exr" "$tmp/seed/fogmap.exr" \
    "$tmp/bigmap" && echo
  # Issue 26: the cubic basis with exact self-shadowing against the linear.
  "$FP_SCENE" -o "$tmp/cubic" --width 160 --height 90 --frames 1-1 >/dev/null
  sh "$(dirname "$0")/bench_cubic.sh" "$tmp/cubic" "$tmp/cubicw" && echo
  # Fog self-shadowing: the default grid's cost and error (the looks' frames).
  if [ -n "${FP_BENCH_SELFSHADOW:-}" ]; then
    "$FP_BENCH_SELFSHADOW" "$tmp/looks/small" "$tmp/looks/mid" && echo
  fi
  # The accuracy of light in the fog: each line is printed by a test of
  # make check that fails when its figure leaves the stated tolerance.
  echo "### Accuracy of light in the fog (figures printed by the tests)"
  echo
  echo "Each line comes from a test in \`make check\` that fails when the figure leaves its tolerance."
  echo
  run_test() {  # run_test NAME: the test's output (figures on stdout and stderr)
    CMOCKA_MESSAGE_OUTPUT=TAP FP_SCENE="$FP_SCENE" FP_SAMPLES="$tmp/light" FP_TMP="$tmp/tests" \
      FP_SRCDIR="${FP_SRCDIR:-.}" "$FP_BUILDDIR/tests/$1" 2>&1 || true
  }
  mkdir -p "$tmp/tests"
  run_test test_phase | grep -E '^(normalization|pdf vs phase|mean cosine|sampled mu)' | sed 's/^/- phase functions, /'
  run_test test_ms | grep -E '^(slab tau\* [0-9]+: largest|fp_ms_ray against)' | sed 's/^/- multiple scattering, /'
  { run_test test_scatter; run_test test_selfshadow; run_test test_lightfast; run_test test_shafts; } | grep -E '^(ambient only|sun single scattering|point light vs|halos at|self-shadowing \(exact\)|self-shadow map|OpenCL vs C|shafts vs brute force|thin casters|--shadows screen|--shadows map\+screen|against the scene)' |
    sed 's/^/- /'
  if [ -x "$FP_BUILDDIR/tests/test_reference" ]; then
    { run_test test_reference; run_test test_bounces; } |
      grep -E '^(ray [0-9]+: T =|ray [0-9]+: ratio|48 rays|default: |plain: |[0-9]+x[0-9]+, reference)' |
      sed 's/^ray /slab, ray /; s/^48 rays/fogmap transmittance, 48 rays/; s/^default: /sun single scattering vs quadrature (stratified, residual tracking): /; s/^plain: /the same, plain delta and ratio tracking: /; s/^\([0-9]*x[0-9]*\), reference/deterministic against the reference on the sample scene, \1: reference/; s/^/- Monte Carlo reference, /'
  fi
  echo
  # The user's shadow map (issue 23): map, map+screen, the walk against a
  # fine map; what the map check says.
  mkdir -p "$tmp/shadows"
  FP_SRCDIR="${FP_SRCDIR:-.}" sh "${FP_SRCDIR:-.}/tests/bench_shadows.sh" "$tmp/shadows" && echo
  # Issue 28: the fast multiple-scattering path against single scattering.
  sh "${FP_SRCDIR:-.}/tests/bench_ms.sh" "$tmp/light" && echo
  # Whole pipeline: frames/s from --stats (the frame loop's wall time: the
  # device and program set-up before the first frame are left out), best of
  # two runs.  The I/O floor is the same run with the fog stage skipped
  # (--no-fog, a hidden benchmark option): read, decode, encode, write.
  echo "## Whole pipeline: the sample sequence at 1920x1080 (8 frames), against the I/O floor"
  echo
  echo "Read, decode, fog (OpenCL), composite, encode (half, the input's ZIP) and write each"
  echo "frame atomically. The I/O floor is the same run without the fog (\`--no-fog\`, a hidden"
  echo "benchmark option): reading and writing the same EXRs. Pipelined (the default): a reader"
  echo "thread decodes frame N+1 and a writer thread encodes frame N-1 while the device computes"
  echo "frame N; \`--pipeline off\`: one frame at a time. Frames/s of the frame loop (\`--stats\`;"
  echo "device set-up excluded), best of two runs; the outputs are the same bytes either way."
  echo
  fps_of() {  # fps_of STATS.json
    sed -n 's/^  "fps": \([0-9.]*\),$/\1/p' "$1"
  }
  best_fps() {  # best_fps NAME OPTIONS...: best frames/s of two runs
    name=$1; shift
    best=0
    for rep in 1 2; do
      rm -rf "$tmp/$name" && mkdir "$tmp/$name"
      "$FOGPIPE" -q -i "$tmp/hd/scene.####.exr" -o "$tmp/$name/out.####.exr" --frames 1-8 \
        --stats "$tmp/$name.json" "$@"
      best=$(awk -v a="$best" -v b="$(fps_of "$tmp/$name.json")" 'BEGIN { print (b > a ? b : a) }')
    done
    echo "$best"
  }
  io_on=$(best_fps io_on --no-fog)
  fog_on=$(best_fps fog_on)
  io_off=$(best_fps io_off --no-fog --pipeline off)
  fog_off=$(best_fps fog_off --pipeline off)
  same=yes
  for f in 1 2 3 4 5 6 7 8; do
    cmp -s "$tmp/fog_on/out.000$f.exr" "$tmp/fog_off/out.000$f.exr" || same=no
  done
  echo "| run | pipelined, frames/s | one at a time, frames/s | pipelined speed-up |"
  echo "|---|---|---|---|"
  awk -v a="$io_on" -v b="$io_off" 'BEGIN { printf "| I/O floor (read + write only) | %.2f | %.2f | %.2fx |\n", a, b, a / b }'
  awk -v a="$fog_on" -v b="$fog_off" 'BEGIN { printf "| height fog, OpenCL | %.2f | %.2f | %.2fx |\n", a, b, a / b }'
  awk -v a="$fog_on" -v b="$io_on" -v c="$fog_off" -v d="$io_off" \
    'BEGIN { printf "| fog against the I/O floor | %.0f%% | %.0f%% | |\n", 100 * a / b, 100 * c / d }'
  echo
  echo "Pipelined and one-at-a-time outputs byte-identical: $same."
  echo "Mean time per frame of each stage, one at a time (ms; pipelined, the stages overlap):"
  echo
  echo "| read | decode | fog | composite | encode | write |"
  echo "|---|---|---|---|---|---|"
  sed -n 's/^  "totals_ms": {\(.*\)},$/\1/p' "$tmp/fog_off.json" | tr -d '",:' |
    awk '{ for (i = 1; i < NF; i += 2) t[$i] = $(i + 1) / 8
           printf "| %.1f | %.1f | %.1f | %.1f | %.1f | %.1f |\n", t["read"], t["decode"], t["fog"],
                  t["composite"], t["encode"], t["write"] }'
  # The EXR ZIP codec (src/exr/exr_zip.c) against OpenEXR's zlib, on the frames
  # of this section as read and as fogged.
  if [ -n "${FP_BENCH_ZIP:-}" ]; then
    echo
    "$FP_BENCH_ZIP" "$tmp"/hd/scene.000?.exr -- "$tmp"/fog_off/out.000?.exr
  fi
  # Animation (filters/animate.c): the quality of wind (the change between
  # frames is the motion itself) and the per-frame decomposition's time.
  oiio=${OIIOTOOL:-oiiotool}
  echo
  echo "## Animation"
  echo
  echo "Wind, seen from straight above: a ground plane 1000 units below the camera, 256 pixels"
  echo "over 256 units, a fog layer 1 unit thick over it (a smooth random 256x256 fogmap, one"
  echo "unit per pixel), a wind of 24 units/s at 24 fps: one pixel per frame. Mean |difference|"
  echo "of R, G, B between consecutive frames (float output), as they are and after undoing the"
  echo "one-pixel shift (what is left: perspective, the layer being 1 unit thick, and rounding)."
  echo
  "$oiio" --pattern constant:color=0.2,0.3,0.4,1,1000 256x256 5 --chnames R,G,B,A,Z -d float \
    -o "$tmp/top.0001.exr"
  cp "$tmp/top.0001.exr" "$tmp/top.0002.exr"
  "$oiio" --pattern noise:type=uniform:min=0:max=1 256x256 1 --blur 9x9 -d float -o "$tmp/fog256.exr"
  vfov=$(awk 'BEGIN { print 2 * atan2(128, 1000) * 45 / atan2(1, 1) }')
  "$FOGPIPE" -q -i "$tmp/top.####.exr" -o "$tmp/w.####.exr" --float --camera-pos 0,1000,0 \
    --camera-rot -90,0,0 --vfov "$vfov" --height 0,inf,1 --density 1 --fogmap "$tmp/fog256.exr" \
    --fog-rect -128,-128,128,128 --wind 24,0
  mean_diff() {
    "$oiio" "$1" --ch R,G,B --cut 255x256+$3+0 "$2" --ch R,G,B --cut 255x256+$4+0 --diff 2>&1 |
      sed -n 's/.*Mean error = *//p'
  }
  raw=$(mean_diff "$tmp/w.0002.exr" "$tmp/w.0001.exr" 0 0)
  undone=$(mean_diff "$tmp/w.0002.exr" "$tmp/w.0001.exr" 1 0)
  echo "| frames 1 -> 2 | mean \\|diff\\| as they are | after undoing the shift | ratio |"
  echo "|---|---|---|---|"
  awk -v r="$raw" -v u="$undone" 'BEGIN { printf "| wind 1 px/frame | %.3g | %.3g | %.2g%% |\n", r, u, 100 * u / r }'
  echo
  echo "Per-frame decomposition of an animated fogmap (512x512, 4 levels, cubic, --turbulence 0.3),"
  echo "4 frames of 200x150 (the decomposition does not depend on the frame's size), mean per"
  echo "frame (fogpipe -v):"
  echo
  "$oiio" --pattern noise:type=uniform:min=0:max=1 512x512 1 --blur 9x9 -d float -o "$tmp/fog512.exr"
  "$oiio" "$tmp/seed/scene.0001.exr" --resize 200x150 -o "$tmp/seed/anim.0001.exr"
  for f in 2 3 4; do cp "$tmp/seed/anim.0001.exr" "$tmp/seed/anim.000$f.exr"; done
  "$FOGPIPE" -v -i "$tmp/seed/anim.####.exr" -o "$tmp/anim.####.exr" --fogmap "$tmp/fog512.exr" \
    --levels 4 --basis cubic --turbulence 0.3 --fog-rect -60,-20,60,160 --density 0.05 \
    --height 0,5 2> "$tmp/anim.txt" || true
  echo "| decomposition | device | fogmap work in all (noise, decomposition, tables) |"
  echo "|---|---|---|"
  sed -n 's/.*fogmap decomposed in \([0-9.]*\) ms ([0-9]*, \([A-Za-z]*\)), \([0-9.]*\) ms .*/\1 \2 \3/p' \
    "$tmp/anim.txt" | awk '{ d += $1; a += $3; dev = $2; n++ }
      END { if (n) printf "| %.1f ms | %s | %.1f ms |\n", d / n, dev, a / n; else print "| - | - | - |" }'
  # Contexts on two threads at once (issue 27).
  if [ -n "${FP_BENCH_THREADS:-}" ]; then
    echo
    "$FP_BENCH_THREADS"
  fi
} > "$out.tmp"
mv "$out.tmp" "$out"
cat "$out"
