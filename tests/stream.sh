#!/bin/sh
# Streams: one frame through a pipe, concatenated EXR streams in and out,
# ffmpeg's image2pipe EXR output, truncated and corrupt streams.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES

# File mode is the reference: the encoder is deterministic, so a stream
# carries exactly the bytes the file mode writes.
"$FOGPIPE" -i "$S/scene.####.exr" -o "$T/ref.####.exr" --frames 1-3

check "one frame: fogpipe < in.exr > out.exr" sh -c '"$FOGPIPE" < "$1" > "$2"' sh "$S/scene.0001.exr" "$T/one.exr"
check "one frame: same bytes as file mode" cmp "$T/one.exr" "$T/ref.0001.exr"

cat "$S/scene.0001.exr" "$S/scene.0002.exr" "$S/scene.0003.exr" > "$T/in3.stream"
check "3-frame stream in, stream out" sh -c '"$FOGPIPE" < "$1" > "$2"' sh "$T/in3.stream" "$T/out3.stream"
cat "$T/ref.0001.exr" "$T/ref.0002.exr" "$T/ref.0003.exr" > "$T/ref3.stream"
check "3 frames out, each the file-mode frame" cmp "$T/out3.stream" "$T/ref3.stream"
check "stream through a pipe (cat |)" sh -c 'cat "$1" | "$FOGPIPE" | cmp - "$2"' sh "$T/in3.stream" "$T/ref3.stream"
check "stream in, sequence out" sh -c 'cat "$1" | "$FOGPIPE" -o "$2/split.####.exr" &&
  cmp "$2/split.0001.exr" "$2/ref.0001.exr" && cmp "$2/split.0003.exr" "$2/ref.0003.exr" &&
  test ! -e "$2/split.0004.exr"' sh "$T/in3.stream" "$T"
check "stream frames numbered by --frames" sh -c 'cat "$1" | "$FOGPIPE" --frames 101-103 -o "$2/num.####.exr" &&
  test -f "$2/num.0101.exr" -a -f "$2/num.0103.exr"' sh "$T/in3.stream" "$T"
check "sequence in, stream out" sh -c '"$FOGPIPE" -i "$1" --frames 1-3 | cmp - "$2"' sh "$S/scene.####.exr" "$T/ref3.stream"

# Names of 32-255 characters, as Cycles writes them through OpenImageIO:
# kept byte for byte through a file and through a stream.
L=$(printf 'ViewLayer%0221d' 0)
"$OIIOTOOL" "$S/scene.0001.exr" --attrib cycles.ViewLayer.synchronization_time "00:00.02" \
  --attrib "cycles.$L.render_time" "00:01.50" \
  --chnames "$L.Combined.R,$L.Combined.G,$L.Combined.B,$L.Combined.A,$L.Depth.Z" -o "$T/long.exr"
long_names() {
  "$OIIOTOOL" --info -v "$1" > "$1.txt" &&
    grep -q '^ *cycles\.ViewLayer\.synchronization_time: "00:00.02"$' "$1.txt" &&
    grep -q "^ *cycles\.$L\.render_time: \"00:01.50\"\$" "$1.txt" &&
    sed 's/ ([a-z]*)//g' "$1.txt" | grep -q "channel list: $L\.Combined\.R, $L\.Combined\.G, $L\.Combined\.B, $L\.Combined\.A, $L\.Depth\.Z"
}
check "long names: the input has them" long_names "$T/long.exr"
check "long names: file in, file out" "$FOGPIPE" -i "$T/long.exr" -o "$T/long.out.exr"
check "long names: kept in the file" long_names "$T/long.out.exr"
check "long names: 2-frame stream in, stream out" sh -c 'cat "$1" "$1" | "$FOGPIPE" > "$2"' sh "$T/long.exr" "$T/long.stream"
check "long names: each stream frame is the file-mode frame" sh -c 'cat "$1" "$1" | cmp - "$2"' sh "$T/long.out.exr" "$T/long.stream"

# A stream whose second frame is cut short, at several places.
size2=$(wc -c < "$S/scene.0002.exr")
for cut in 10 300 2000 $((size2 - 1)); do
  { cat "$S/scene.0001.exr"; head -c "$cut" "$S/scene.0002.exr"; } > "$T/trunc.stream"
  fails "stream truncated at byte $cut of frame 2" 1 "<stdin>.*frame 2.*truncated" - \
    sh -c '"$FOGPIPE" -o "$2/t.####.exr" < "$1"' sh "$T/trunc.stream" "$T"
done
check "frame 1 of the truncated stream was written whole" cmp "$T/t.0001.exr" "$T/ref.0001.exr"
check "nothing of frame 2" test ! -e "$T/t.0002.exr"
# An uncompressed frame cut short in the middle of a stream borrows the
# start of the next: the error names the frame cut, and nothing of it is
# written.
for f in 1 2; do "$OIIOTOOL" "$S/scene.000$f.exr" --compression none -o "$T/none.$f.exr"; done
nsize=$(wc -c < "$T/none.2.exr")
for cut in 1 4 5 100 5000; do
  rm -f "$T"/c.*.exr
  { cat "$T/none.1.exr"; head -c $((nsize - cut)) "$T/none.2.exr"; cat "$T/none.1.exr"; } > "$T/cut.stream"
  fails "uncompressed frame 2 of 3 cut $cut bytes short" 1 "<stdin>: frame 2: truncated" "$T/c.0002.exr" \
    sh -c '"$FOGPIPE" -o "$2/c.####.exr" < "$1"' sh "$T/cut.stream" "$T"
done
check "frame 1 before the cut frame was written" test -f "$T/c.0001.exr"
{ cat "$S/scene.0001.exr"; echo "garbage"; } > "$T/garbage.stream"
fails "garbage after a frame" 1 "<stdin>.*frame 2.*(not an EXR|magic)" - sh -c '"$FOGPIPE" < "$1" > /dev/null' sh "$T/garbage.stream"
fails "empty stdin" 1 "<stdin>.*empty" - sh -c '"$FOGPIPE" < /dev/null > /dev/null'
if command -v script >/dev/null; then
  check "EXR data is not written to a terminal (exit 2)" sh -c 'st=0; script -qec "\"$FOGPIPE\" -i \"$1\"" /dev/null < /dev/null > "$2" || st=$?
    test "$st" = 2 && grep -q terminal "$2"' sh "$S/scene.0001.exr" "$T/tty.txt"
else
  skip "script(1) not installed"
fi

# ffmpeg's image2pipe EXR encoder is a real producer of such streams.  It
# drops the depth and the camera, so those come from the originals.
if [ -n "${FFMPEG:-}" ]; then
  "$FFMPEG" -v error -y -start_number 1 -i "$S/scene.%04d.exr" -frames:v 3 -c:v exr -f image2pipe - > "$T/ffmpeg.stream" 2>"$T/ffmpeg.txt"
  check "ffmpeg made a stream" test -s "$T/ffmpeg.stream"
  check "ffmpeg stream: 3 frames in, 3 out" sh -c '"$FOGPIPE" --depth "$2/scene.####.exr" \
      --camera-pos 0,2,-10 --camera-target 0,2,0 --vfov 45 < "$1" > "$3/ff-out.stream" &&
    "$FOGPIPE" --print-camera --depth "$2/scene.####.exr" --camera-pos 0,2,-10 --camera-target 0,2,0 \
      --vfov 45 < "$3/ff-out.stream" | grep -c "^  position" | grep -qx 3' sh "$T/ffmpeg.stream" "$S" "$T"
else
  skip "ffmpeg not installed"
  skip "ffmpeg not installed"
fi
finish
