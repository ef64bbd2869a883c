#!/bin/sh
# A sequence's shadow map packed once (filters/scatter_frame.c): a frame
# whose map holds the same depths as the one packed last (the sample
# scene's maps differ only in a header note naming the frame), seen by the
# same sun camera under the same sun, bias and up axis, keeps the packed
# map and its device copy.  Each frame must still be the frame run alone,
# and a map whose depths change between frames (same size and camera)
# must be taken up, not the kept one.
. "${FP_SRCDIR:-.}/tests/lib.sh"
"$FP_SCENE" -o "$T/a" --width 64 --height 36 --frames 1-2 --shadow-size 1024 >/dev/null
# c: a's frames, frame 2's map 0.5 deeper everywhere (its header kept).
mkdir -p "$T/c"
cp "$T/a/scene.0001.exr" "$T/a/scene.0002.exr" "$T/a/shadow.0001.exr" "$T/c/"
"$OIIOTOOL" "$T/a/shadow.0002.exr" --addc 0.5 -d float -o "$T/c/shadow.0002.exr"
look="-q --progress off --preset ${FP_SRCDIR:-.}/samples/presets/low-sun-shafts.preset"
run() { # run DIR OUT FRAMES
  "$FOGPIPE" $look --shadow-map "$1/shadow.####.exr" -i "$1/scene.####.exr" \
    -o "$2/o.####.exr" --frames "$3"
}
check "frames 1-2, the same map twice: exit 0" run "$T/a" "$T/seq" 1-2
check "frame 2 alone: exit 0" run "$T/a" "$T/one" 2-2
check "... frame 2 of the sequence is frame 2 alone, bit for bit" \
  cmp "$T/seq/o.0002.exr" "$T/one/o.0002.exr"
check "frames 1-2, frame 2's map another: exit 0" run "$T/c" "$T/seqc" 1-2
check "frame 2 alone with that map: exit 0" run "$T/c" "$T/onec" 2-2
check "... the sequence took the new map up: frame 2 alone, bit for bit" \
  cmp "$T/seqc/o.0002.exr" "$T/onec/o.0002.exr"
check "... and that map changes the frame (the check can fail)" \
  sh -c "! cmp -s '$T/seqc/o.0002.exr' '$T/seq/o.0002.exr'"
finish
