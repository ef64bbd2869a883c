#!/bin/sh
# Every compression in and out, files and streams, with OpenImageIO as the
# outside judge: DWAA/DWAB files made by oiiotool (scanline, tiled,
# multipart, decreasing line order) go through fogpipe, and what fogpipe
# writes in each compression is read back by oiiotool and idiff.
#
# Tolerances: lossless codecs must give the uncompressed result exactly;
# pxr24 rounds float channels (Z) to 24 bits (idiff -failrelative 3e-5);
# b44, b44a, dwaa and dwab are lossy for half colour: -fail 0.05 (measured
# on the fogged sample frame: worst 0.031 for b44, 0.033 for DWA at level
# 45, at values near 0.7; mean 0.0017 and 0.0006).  Their Z (float) is
# lossless.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES
ALL="none rle zips zip piz pxr24 b44 b44a dwaa dwab"

if [ -z "${OIIOTOOL:-}" ] || [ -z "${IDIFF:-}" ]; then
  skip "oiiotool and idiff are not installed"
  finish
  exit
fi

tol() {
  case $1 in
    pxr24) echo "-fail 1e-6 -failrelative 3e-5 -warn 1e-6 -warnrelative 3e-5" ;;
    b44|b44a|dwaa|dwab) echo "-fail 0.05 -warn 0.05" ;;
    *) echo "-fail 0 -warn 0" ;;
  esac
}

# compression_is FILE NAME: oiiotool reads FILE and reports that compression
compression_is() {
  "$OIIOTOOL" --info -v "$1" > "$T/info.txt" 2>&1 &&
    grep -q "compression: \"$2\"" "$T/info.txt"
}

# The references: fogged from uncompressed input, written uncompressed.
"$FOGPIPE" -q -i "$S/scene.####.exr" --frames 1-2 --compression none -o "$T/ref.####.exr"

# ---------------------------------------------------------------- out
for c in $ALL; do
  check "$c out (files): frames written" \
    "$FOGPIPE" -q -i "$S/scene.####.exr" --frames 1-2 --compression "$c" -o "$T/out_$c.####.exr"
  check "$c out: oiiotool reads it as $c" compression_is "$T/out_$c.0002.exr" "$c"
  check "$c out: matches the uncompressed result ($(tol "$c"))" \
    sh -c '"$IDIFF" -q $1 "$2" "$3" && "$IDIFF" -q $1 "$4" "$5"' sh "$(tol "$c")" \
    "$T/ref.0001.exr" "$T/out_$c.0001.exr" "$T/ref.0002.exr" "$T/out_$c.0002.exr"
  check "$c out (stream): the file-mode frames, byte for byte" \
    sh -c 'cat "$1" "$2" | "$FOGPIPE" -q --compression "$3" > "$4" && cat "$5" "$6" | cmp - "$4"' sh \
    "$S/scene.0001.exr" "$S/scene.0002.exr" "$c" "$T/out_$c.stream" \
    "$T/out_$c.0001.exr" "$T/out_$c.0002.exr"
done

# ---------------------------------------------------------------- in
# Inputs made by oiiotool in every compression; the judge is fogpipe on
# oiiotool's own uncompressed decoding of the same file, which must give
# the same pixels exactly (our decoding is OpenImageIO's).
for c in $ALL; do
  for f in 1 2; do
    "$OIIOTOOL" "$S/scene.000$f.exr" --compression "$c" -o "$T/in_$c.000$f.exr"
    "$OIIOTOOL" "$T/in_$c.000$f.exr" --compression none -o "$T/dec_$c.000$f.exr"
  done
  "$FOGPIPE" -q -i "$T/dec_$c.####.exr" --frames 1-2 --compression none -o "$T/fdec_$c.####.exr"
  check "$c in (files): same pixels as from oiiotool's decoding" \
    sh -c '"$FOGPIPE" -q -i "$1" --frames 1-2 --compression none -o "$2" &&
      "$IDIFF" -q -fail 0 -warn 0 "$3" "$4" && "$IDIFF" -q -fail 0 -warn 0 "$5" "$6"' sh \
    "$T/in_$c.####.exr" "$T/fin_$c.####.exr" "$T/fdec_$c.0001.exr" "$T/fin_$c.0001.exr" \
    "$T/fdec_$c.0002.exr" "$T/fin_$c.0002.exr"
  check "$c in (stream): split into the file-mode frames" \
    sh -c 'cat "$1" "$2" | "$FOGPIPE" -q --compression none -o "$3" && cmp "$4" "$5" && cmp "$6" "$7"' sh \
    "$T/in_$c.0001.exr" "$T/in_$c.0002.exr" "$T/sin_$c.####.exr" \
    "$T/sin_$c.0001.exr" "$T/fin_$c.0001.exr" "$T/sin_$c.0002.exr" "$T/fin_$c.0002.exr"
done

# ---------------------------------------------------------------- Nuke-like DWAA
# A DWAA comp as Nuke writes it (level 45 by default), with custom
# attributes: through fogpipe it stays DWAA, keeps them, and its colour is
# the uncompressed result within the tolerance.
"$OIIOTOOL" "$S/scene.0001.exr" --attrib "nuke/node_hash" "3f2a9c" --attrib:type=int "nuke/version" 13 \
  --compression dwaa -o "$T/nuke.exr"
check "a DWAA comp from oiiotool goes through" "$FOGPIPE" -q -i "$T/nuke.exr" -o "$T/nuke_out.exr"
check "it stays DWAA" compression_is "$T/nuke_out.exr" dwaa
check "its attributes are kept" sh -c '"$OIIOTOOL" --info -v "$1" > "$2" &&
  grep -q "nuke/node_hash: \"3f2a9c\"" "$2" && grep -q "nuke/version: 13" "$2" &&
  grep -q "worldToCamera: -0.99846" "$2" && grep -q "fogpipe/scene: \"fogpipe sample scene" "$2" &&
  grep -q "openexr:dwaCompressionLevel: 45" "$2"' sh "$T/nuke_out.exr" "$T/nuke_info.txt"
check "its colour is the uncompressed result within 0.05 (two DWA generations)" \
  "$IDIFF" -q -fail 0.05 -warn 0.05 "$T/ref.0001.exr" "$T/nuke_out.exr"

# Tiled DWAB, multipart DWAA and DWAB, decreasing line order.
"$OIIOTOOL" "$S/scene.0001.exr" --tile 32 32 --compression dwab -o "$T/tiled.exr"
"$OIIOTOOL" "$T/tiled.exr" --compression none -o "$T/tiled_dec.exr"
check "tiled DWAB in: same pixels as from oiiotool's decoding" sh -c '
  "$FOGPIPE" -q -i "$1" --compression none -o "$2" && "$FOGPIPE" -q -i "$3" --compression none -o "$4" &&
  "$IDIFF" -q -fail 0 -warn 0 "$2" "$4"' sh "$T/tiled.exr" "$T/tiled_a.exr" "$T/tiled_dec.exr" "$T/tiled_b.exr"
check "tiled DWAB in: written as scanline DWAB" sh -c '"$FOGPIPE" -q -i "$1" -o "$2" &&
  "$OIIOTOOL" --info -v "$2" > "$3" && grep -q "compression: \"dwab\"" "$3" && ! grep -q "tile size" "$3"' \
  sh "$T/tiled.exr" "$T/tiled_out.exr" "$T/tiled_info.txt"

"$OIIOTOOL" "$S/scene.0001.exr" "$S/scene.0002.exr" --chnames other.R,other.G,other.B,other.A,other.Z \
  --siappend --compression dwaa -o "$T/mp.exr"
check "multipart DWA in and out: every part read back by oiiotool" sh -c '
  "$FOGPIPE" -q -i "$1" -o "$2" && "$OIIOTOOL" --info -a -v "$2" > "$3" &&
  test "$(grep -c "compression: \"dwa" "$3")" = 2 && grep -q "other.R" "$3" &&
  "$OIIOTOOL" "$2" --subimage 1 -o "$4" && "$OIIOTOOL" "$1" --subimage 1 -o "$5" &&
  "$IDIFF" -q -fail 0.05 -warn 0.05 "$4" "$5"' sh "$T/mp.exr" "$T/mp_out.exr" "$T/mp_info.txt" \
  "$T/mp_out1.exr" "$T/mp_in1.exr"

"$OIIOTOOL" "$S/scene.0001.exr" --attrib openexr:lineOrder decreasingY --compression dwaa -o "$T/decr.exr"
check "decreasing-line-order DWAA in and out: oiiotool reads it, within 0.05" sh -c '
  "$FOGPIPE" -q -i "$1" -o "$2" && "$OIIOTOOL" --info -v "$2" | grep -q "compression: \"dwaa\"" &&
  "$IDIFF" -q -fail 0.05 -warn 0.05 "$3" "$2"' sh "$T/decr.exr" "$T/decr_out.exr" "$T/ref.0001.exr"

# ---------------------------------------------------------------- levels, errors
check "--dwa-level: 5 is bigger than 45, 45 than 300, the level is written" sh -c '
  for l in 5 45 300; do "$FOGPIPE" -q -i "$1" --compression dwab --dwa-level $l -o "$2/lv$l.exr" || exit 1; done
  test $(wc -c < "$2/lv5.exr") -gt $(wc -c < "$2/lv45.exr") &&
  test $(wc -c < "$2/lv45.exr") -gt $(wc -c < "$2/lv300.exr") &&
  "$OIIOTOOL" --info -v "$2/lv300.exr" | grep -q "openexr:dwaCompressionLevel: 300"' sh "$S/scene.0001.exr" "$T"
fails "an unknown compression is refused before any frame" 2 "compression.*lzw" "$T/never.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" --compression lzw -o "$T/never.exr"
head -c 40000 "$T/nuke.exr" > "$T/cut.exr"
fails "a cut DWAA file: one line naming it and the frame" 1 "cut\.exr: frame 1: cannot decode DWA" \
  "$T/cut_out.exr" "$FOGPIPE" -i "$T/cut.exr" -o "$T/cut_out.exr"
{ cat "$T/in_dwaa.0001.exr"; head -c 30000 "$T/in_dwaa.0002.exr"; } > "$T/cut.stream"
fails "a cut DWAA stream: frame 2 named" 1 "<stdin>.*frame 2.*truncated" - \
  sh -c '"$FOGPIPE" --compression none -o "$2/cs.####.exr" < "$1"' sh "$T/cut.stream" "$T"
check "frame 1 of the cut stream was written whole" cmp "$T/cs.0001.exr" "$T/sin_dwaa.0001.exr"
finish
