#!/bin/sh
# --deep (issue 25): the fog as OpenEXR deep samples, judged by a
# reference deep compositor (tests/deep_ref, OpenEXR's C++ library, which
# splits samples as "Interpreting OpenEXR Deep Pixels" says) and by
# oiiotool --flatten:
#
# - flattening the deep output equals the flat output (--cpu --float, the
#   same double-precision fog) within 1e-4 of the composite's range, for
#   height fog, a fogmap, the sun with shafts (the sample scene's shadow
#   map) and lamps; every pixel tidy;
# - an opaque element merged inside the fog at depths sweeping through it
#   (the deep fog of a sky plate, split by the reference at the element)
#   equals fogpipe's flat result of a plate holding the element at that
#   depth, within the bound (--deep-bound 1e-4 times max(1, the pixel's
#   brightest channel));
# - a deep render (oiiotool --deepen, and samples written by deep_ref:
#   a point, a volume and an opaque surface per pixel) fogged deep then
#   flattened equals the flat path where that is exact (opaque), and the
#   reference's merge of the fog with the render's samples where it is not;
# - streams, sequences, farm chunks, --skip-existing, --stats, compression
#   (none, rle, zips) and bad deep inputs.
. "${FP_SRCDIR:-.}/tests/lib.sh"
REF="$FP_BUILDDIR/tests/deep_ref"
P="$FP_SRCDIR/samples/presets"

if [ -z "${OIIOTOOL:-}" ]; then
  skip "oiiotool is not installed"
  finish
  exit
fi

# A small scene (the deep fog is computed per ray in double precision).
"$FP_SCENE" -o "$T/s" --width 32 --height 18 --frames 1-2 --shadow-size 256 >/dev/null
S="$T/s"
FM="--fogmap $S/fogmap.exr --fog-rect -60,-20,60,160 --density 0.1 --height 0,5 --levels 3"
SUN="--preset $P/low-sun-shafts.preset --shadow-map $S/shadow.####.exr"
LAMPS="--preset $P/night-street-lamps.preset"

# The element plates: the scene's camera, sky (no colour) or one colour at
# one depth everywhere.
"$OIIOTOOL" "$S/scene.0001.exr" --ch "R=0,G=0,B=0,A=0,Z=1e10" -o "$T/sky.exr"

# ---------------------------------------------------------------- flatten == flat
for c in "height|" "fogmap|$FM" "shafts|$SUN" "lamps|$LAMPS"; do
  n=${c%%|*}; a=${c#*|}
  # shellcheck disable=SC2086
  "$FOGPIPE" -q -i "$S/scene.0001.exr" -o "$T/flat_$n.exr" --cpu --float $a
  # shellcheck disable=SC2086
  check "$n: --deep writes a deep frame" "$FOGPIPE" -v -i "$S/scene.0001.exr" \
    -o "$T/deep_$n.exr" --deep $a
  grep "samples a pixel" "$T/out.txt" | tail -1 | sed 's/^/# /'
  check "$n: every pixel tidy (sorted, not overlapping)" "$REF" tidy "$T/deep_$n.exr"
  "$REF" flatten "$T/deep_$n.exr" "$T/rflat_$n.exr"
  check "$n: reference flatten == flat within 1e-4" \
    "$REF" diff "$T/rflat_$n.exr" "$T/flat_$n.exr" 1e-4 rel
  "$OIIOTOOL" "$T/deep_$n.exr" --flatten -o "$T/oflat_$n.exr"
  check "$n: oiiotool --flatten == flat within 1e-4" \
    "$REF" diff "$T/oflat_$n.exr" "$T/flat_$n.exr" 1e-4 rel
done

# ---------------------------------------------------------------- an element inside the fog
for c in "fogmap|$FM" "shafts|$SUN"; do
  n=${c%%|*}; a=${c#*|}
  # shellcheck disable=SC2086
  "$FOGPIPE" -q -i "$T/sky.exr" --frames 1 -o "$T/dsky_$n.exr" --deep $a
  # the range of the pixel's composite: its fog to the end, at least 1
  "$REF" flatten "$T/dsky_$n.exr" "$T/range_$n.exr"
  for z in 3 12 60; do
    "$OIIOTOOL" "$S/scene.0001.exr" --ch "R=0.3,G=0.5,B=0.7,A=1,Z=$z" -o "$T/el.exr"
    # shellcheck disable=SC2086
    "$FOGPIPE" -q -i "$T/el.exr" --frames 1 -o "$T/fel.exr" --cpu --float $a
    "$REF" merge "$T/dsky_$n.exr" "$z" 0.3 0.5 0.7 "$T/mel.exr"
    check "$n: an opaque element merged at Z $z == the flat plate at $z within the bound" \
      "$REF" diff "$T/mel.exr" "$T/fel.exr" 1e-4 rel "$T/range_$n.exr"
  done
done

# ---------------------------------------------------------------- deep in, deep out
"$OIIOTOOL" "$S/scene.0001.exr" --deepen -o "$T/oideep.exr"
check "oiiotool --deepen input: fogged deep" "$FOGPIPE" -q -i "$T/oideep.exr" -o "$T/oideep_out.exr" \
  --deep $SUN --frames 1
"$REF" flatten "$T/oideep_out.exr" "$T/oideep_flat.exr"
"$FOGPIPE" -q -i "$S/scene.0001.exr" -o "$T/flat_sun1.exr" --cpu --float $SUN --frames 1
check "oiiotool --deepen input: flattened == the flat path (opaque: exact)" \
  "$REF" diff "$T/oideep_flat.exr" "$T/flat_sun1.exr" 1e-4 rel
"$REF" deepen "$S/scene.0001.exr" "$T/glass.exr" glass
check "a render with a point, a volume and a surface per pixel: fogged deep" \
  "$FOGPIPE" -q -i "$T/glass.exr" -o "$T/glass_out.exr" --deep $SUN --frames 1
check "... tidy" "$REF" tidy "$T/glass_out.exr"
"$REF" flatten "$T/glass_out.exr" "$T/glass_flat.exr"
"$REF" union "$T/dsky_shafts.exr" "$T/glass.exr" "$T/glass_union.exr"
check "... flattened == the reference's merge of the fog with the render's samples" \
  "$REF" diff "$T/glass_flat.exr" "$T/glass_union.exr" 1e-4 rel
"$REF" deepen "$S/scene.0001.exr" "$T/opaque.exr"
"$FOGPIPE" -q -i "$T/opaque.exr" -o "$T/opaque_out.exr" --deep --frames 1
"$REF" flatten "$T/opaque_out.exr" "$T/opaque_flat.exr"
check "a deep render with the sky at infinity: flattened == flat (height fog)" \
  "$REF" diff "$T/opaque_flat.exr" "$T/flat_height.exr" 1e-4 rel

# ---------------------------------------------------------------- runs
check "a sequence of deep frames" "$FOGPIPE" -q -i "$S/scene.####.exr" -o "$T/seq.####.exr" \
  --deep --stats "$T/stats.json"
check "--stats written for a deep run" grep -q '"frames"' "$T/stats.json"
check "a farm chunk (--frames 2) is the same bytes" "$FOGPIPE" -q -i "$S/scene.####.exr" \
  -o "$T/chunk.####.exr" --deep --frames 2
check "... as the whole run's frame 2" cmp "$T/seq.0002.exr" "$T/chunk.0002.exr"
cat "$S/scene.0001.exr" "$S/scene.0002.exr" | "$FOGPIPE" -q --deep -o - > "$T/stream.bin"
cat "$T/seq.0001.exr" "$T/seq.0002.exr" > "$T/seq.bin"
check "a stream in, a stream of deep frames out, the same bytes as the files" \
  cmp "$T/stream.bin" "$T/seq.bin"
# (the deep frames fogged again: what matters is that each is found whole)
"$FOGPIPE" -q --deep -i - -o "$T/restream.####.exr" --frames 1-2 < "$T/stream.bin"
check "a stream of deep frames read back (deep stream framing)" test -s "$T/restream.0002.exr"
rm -f "$T/seq.0002.exr"
touch -d '2001-01-01' "$T/seq.0001.exr"
check "--skip-existing: the missing deep frame only" "$FOGPIPE" -q -i "$S/scene.####.exr" \
  -o "$T/seq.####.exr" --deep --skip-existing
check "... frame 1 left alone" test "$(date -r "$T/seq.0001.exr" +%Y)" = 2001
check "... frame 2 made again, the same bytes" cmp "$T/seq.0002.exr" "$T/chunk.0002.exr"
for z in none rle zips; do
  check "--compression $z" "$FOGPIPE" -q -i "$S/scene.0001.exr" -o "$T/c_$z.exr" --deep \
    --compression $z
  "$OIIOTOOL" --info -v "$T/c_$z.exr" > "$T/info.txt" 2>&1
  check "... oiiotool reads it as $z" grep -q "compression: \"$z\"" "$T/info.txt"
  "$REF" flatten "$T/c_$z.exr" "$T/cf_$z.exr"
  check "... the same pixels" "$REF" diff "$T/cf_$z.exr" "$T/rflat_height.exr" 0
done
check "deep input compressed with rle: read" "$FOGPIPE" -q -i "$T/c_rle.exr" -o "$T/c_rle2.exr" \
  --deep --sky keep --density 0

# ---------------------------------------------------------------- bad input
fails "--compression zip is refused before any frame" 2 "compression zip cannot hold deep data" \
  "$T/bad.exr" "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/bad.exr" --deep --compression zip
fails "an image output is refused" 2 "image outputs" "$T/bad.png" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/bad.png" --deep
fails "a deep input without --deep" 1 "oideep.exr: frame 1: a deep image \(use --deep" \
  "$T/bad.exr" "$FOGPIPE" -i "$T/oideep.exr" -o "$T/bad.exr"
head -c 3000 "$T/c_none.exr" > "$T/cut.exr"
fails "a truncated deep file" 1 "cut.exr: frame 1: .*deep" "$T/bad.exr" \
  "$FOGPIPE" -i "$T/cut.exr" -o "$T/bad.exr" --deep
fails "a truncated deep frame on stdin" 1 "<stdin>: frame 1: truncated" "-" \
  sh -c "\"$FOGPIPE\" --deep -o - < \"$T/cut.exr\" > /dev/null"
"$OIIOTOOL" "$T/c_none.exr" --ch R,G,B,A -o "$T/noz.exr" 2>/dev/null
fails "a deep input without Z" 1 "noz.exr: frame 1: deep input needs channels R, G, B and Z" \
  "$T/bad.exr" "$FOGPIPE" -i "$T/noz.exr" -o "$T/bad.exr" --deep
"$OIIOTOOL" "$T/c_none.exr" --tile 16 16 -o "$T/tiled.exr" 2>/dev/null
fails "a deep tiled input" 1 "tiled.exr: frame 1: deep input must be one deep scanline part" \
  "$T/bad.exr" "$FOGPIPE" -i "$T/tiled.exr" -o "$T/bad.exr" --deep
fails "a deep input beyond the image budget (samples)" 1 \
  "glass.exr: frame 1: .*samples.*--max-image-pixels" "$T/bad.exr" \
  "$FOGPIPE" -i "$T/glass.exr" -o "$T/bad.exr" --deep --max-image-pixels 700
# the sample count table's first entry made huge (uncompressed file: the
# table follows the chunk's 28-byte header at the first offset)
python_ok=0
if [ -n "${PYTHON3:-}" ]; then
  "$PYTHON3" - "$T/c_none.exr" "$T/mangled.exr" <<'EOF' && python_ok=1
import struct, sys
b = bytearray(open(sys.argv[1], "rb").read())
# the header ends at the first NUL NUL after the attributes; the offset
# table follows: its first entry is the first chunk
i = 8
while b[i] != 0:
    i = b.index(0, i) + 1          # name
    i = b.index(0, i) + 1          # type
    n = struct.unpack_from("<i", b, i)[0]
    i += 4 + n
off = struct.unpack_from("<Q", b, i + 1)[0]
struct.pack_into("<I", b, off + 28, 0x7fffffff)
open(sys.argv[2], "wb").write(b)
EOF
fi
if [ "$python_ok" = 1 ]; then
  fails "a corrupt sample count table" 1 "mangled.exr: frame 1: deep line .*sample count table" \
    "$T/bad.exr" "$FOGPIPE" -i "$T/mangled.exr" -o "$T/bad.exr" --deep
else
  skip "python3 is not installed (corrupt sample count table)"
fi
finish
