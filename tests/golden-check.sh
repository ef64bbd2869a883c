#!/bin/sh
# tools/fogpipe-golden-check, the golden-frame recipe the README gives
# users: goldens written with --update pass; the C path (--cpu) passes
# against the OpenCL goldens at the script's thresholds (the cross-device
# tolerance); a 1% change of a look fails, naming the case and leaving a
# diff image; a missing golden and a bad case fail; bad usage is status 2.
. "${FP_SRCDIR:-.}/tests/lib.sh"
GC="$FP_SRCDIR/tools/fogpipe-golden-check"
S=$FP_SAMPLES
export FOGPIPE IDIFF
cd "$T" || exit 1
cat > cases <<CASES
# the sample scene: height fog, a fogmap, the three named looks
height --density 0.03 --height 0,12 --fog-color 0.75,0.78,0.82 -i "$S/scene.####.exr" --frames 3
fogmap --fogmap "$S/fogmap.exr" --fog-rect -60,-20,60,160 --density 0.1 --height 0,5 --levels 3 -i "$S/scene.####.exr" --frames 5
lamps  --preset night-street-lamps -i "$S/scene.####.exr" --frames 1
shafts --preset low-sun-shafts --shadow-map "$S/shadow.####.exr" -i "$S/scene.####.exr" --frames 5
mist   --preset morning-valley-mist --shadow-map "$S/shadow.####.exr" -i "$S/scene.####.exr" --frames 1
CASES
check "--update writes one golden frame a case" sh -c '
  "$1" --update cases golden && test -s golden/height.exr -a -s golden/fogmap.exr -a \
    -s golden/lamps.exr -a -s golden/shafts.exr -a -s golden/mist.exr' sh "$GC"
check "the same build passes (5 passed, 0 failed)" sh -c '"$1" cases golden > same.txt && tail -n 1 same.txt | grep -qx "5 passed, 0 failed"' sh "$GC"
sed '/^#/!s/$/ --cpu/' cases > cases-cpu
check "the C path (--cpu) passes against the OpenCL goldens (the cross-device thresholds)" \
  sh -c '"$1" cases-cpu golden > cpu.txt' sh "$GC"
diag cpu.txt
sed 's/--density 0.03 /--density 0.0303 /' cases > cases-changed
st=0; "$GC" cases-changed golden > changed.txt 2>&1 || st=$?
check "a 1% denser look fails (status 1), names the case, leaves its diff image" sh -c '
  test "$1" = 1 && grep -q "^FAIL height: differs" changed.txt && grep -q "^ok   lamps" changed.txt &&
  test -s golden-diff/height.diff.exr -a -s golden-diff/height.new.exr' sh "$st"
rm golden/mist.exr
st=0; "$GC" cases golden > missing.txt 2>&1 || st=$?
check "a missing golden frame fails, saying how to write it" sh -c '
  test "$1" = 1 && grep -q "^FAIL mist: no golden frame golden/mist.exr (run fogpipe-golden-check --update once)" missing.txt' sh "$st"
echo "bad --no-such-option -i $S/scene.0001.exr" > cases-bad
st=0; "$GC" cases-bad golden > bad.txt 2>&1 || st=$?
check "a case fogpipe refuses fails with fogpipe's message" sh -c '
  test "$1" = 1 && grep -q "^FAIL bad: fogpipe failed: .*unknown option --no-such-option" bad.txt' sh "$st"
st=0; "$GC" cases > usage.txt 2>&1 || st=$?
check "bad usage: status 2" test "$st" = 2
finish
