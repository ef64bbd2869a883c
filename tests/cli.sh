#!/bin/sh
# Command-line behaviour: help, devices, sequences, every bad input (one
# line naming file and frame, non-zero exit, no partial output), parity of
# OpenCL and the C reference on whole frames, install.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES

check "--help lists options with defaults and ranges" \
  sh -c 'COLUMNS=1000 "$FOGPIPE" --help | grep -q -- "--density SIGMA.*default: 0.02.*range: 0..1e+06"'
check "the sample scene's matrices reproject every pixel (fogpipe-scene --check)" "$FP_SCENE" --check
check "--version" sh -c '"$FOGPIPE" --version | grep -q "^fogpipe "'
check "--list-devices shows PoCL's CPU device" sh -c '"$FOGPIPE" --list-devices | grep -qi "pthread\|cpu"'
fails "unknown option: exit 2" 2 "unknown option --bogus" - "$FOGPIPE" --bogus
fails "out-of-range value: exit 2" 2 "density.*out of range" - "$FOGPIPE" --density -3 -i "$S/scene.0001.exr" -o "$T/x.exr"
fails "unknown device" 1 "device" "$T/dev.exr" "$FOGPIPE" --device nosuchdevice -i "$S/scene.0001.exr" -o "$T/dev.exr"

# A sequence, with the pass-through depth channel and the alpha kept.
check "fog a sequence of 3 frames" "$FOGPIPE" -i "$S/scene.####.exr" -o "$T/seq.####.exr" --frames 1-3
check "-o into missing directories makes them (as Nuke's and Blender's Write do)" sh -c '
  "$1" -i "$2" --frames 1-2 -o "$3/made/dirs/out.####.exr" && test -f "$3/made/dirs/out.0002.exr"' \
  sh "$FOGPIPE" "$S/scene.####.exr" "$T"
: > "$T/notadir"
fails "-o under a file: one line naming the frame and the directory" 1 \
  "notadir/x.0001.exr: frame 1: cannot create the directory .*notadir" "$T/notadir/x.0001.exr" \
  "$FOGPIPE" -i "$S/scene.####.exr" --frames 1 -o "$T/notadir/x.####.exr"
check "3 frames written" test -f "$T/seq.0001.exr" -a -f "$T/seq.0002.exr" -a -f "$T/seq.0003.exr" -a ! -e "$T/seq.0004.exr"
check "output keeps channels, windows and camera attributes" sh -c '
  "$OIIOTOOL" --info -v "$1" > "$2/info.txt" &&
  grep -q "channel list: R (half), G (half), B (half), A (half), Z (float)" "$2/info.txt" && grep -q "worldToCamera" "$2/info.txt" &&
  grep -q "worldToNDC" "$2/info.txt" && grep -q "320 x  180" "$2/info.txt"' sh "$T/seq.0002.exr" "$T"
check "depth passes through unchanged" same_channels 0 Z "$S/scene.0002.exr" "$T/seq.0002.exr"
check "fog changes the color" sh -c '! "$IDIFF" -q -fail 0.01 "$1" "$2" >/dev/null' sh \
  "$S/scene.0002.exr" "$T/seq.0002.exr"
check "no temporary files left" sh -c '! ls -a "$1" | grep -q "\.tmp\."' sh "$T"
check "frames found on disk without --frames" "$FOGPIPE" -i "$S/scene.%04d.exr" -o "$T/all.@@@@.exr"
check "all 8 found" test -f "$T/all.0008.exr" -a -f "$T/all.0001.exr"

fails "missing frame in a range names it, writes nothing" 1 "scene.0009.exr: frame 9: missing input" \
  "$T/miss.0001.exr" "$FOGPIPE" -i "$S/scene.####.exr" -o "$T/miss.####.exr" --frames 1-9
fails "missing file" 1 "nope.exr" "$T/o1.exr" "$FOGPIPE" -i "$T/nope.exr" -o "$T/o1.exr"
echo "this is not an EXR file at all" > "$T/text.exr"
fails "not an EXR" 1 "text.exr.*frame 1.*(not an EXR|magic)" "$T/o2.exr" "$FOGPIPE" -i "$T/text.exr" -o "$T/o2.exr"
head -c 20000 "$S/scene.0001.exr" > "$T/trunc.exr"
fails "truncated file" 1 "trunc.exr.*frame 1" "$T/o3.exr" "$FOGPIPE" -i "$T/trunc.exr" -o "$T/o3.exr"
# Line order: a decreasing input (as OpenImageIO writes it) gives an output
# that OpenImageIO reads, with the same pixels as the increasing input's.
"$OIIOTOOL" "$S/scene.0001.exr" --attrib openexr:lineOrder decreasingY -o "$T/dec.exr"
check "decreasing line order: fogged" "$FOGPIPE" -i "$T/dec.exr" -o "$T/dec.out.exr"
check "decreasing line order: the output reads back (oiiotool)" "$OIIOTOOL" "$T/dec.out.exr" -o "$T/dec.back.exr"
check "decreasing line order: the same pixels as from increasing" sh -c '"$FOGPIPE" -i "$1" -o "$2" &&
  "$IDIFF" -q -fail 0 -warn 0 "$2" "$3"' sh "$S/scene.0001.exr" "$T/inc.out.exr" "$T/dec.out.exr"
# Invalid enum values: refused, from a file and from a stream.
poke() { # poke FILE ATTRNAME TYPENAME VALUE OUT: the attribute's first value byte set
  at=$(grep -obUaP "$2\\x00$3\\x00" "$1" | head -1 | cut -d: -f1)
  cp "$1" "$5" && printf "\\$(printf %o "$4")" |
    dd of="$5" bs=1 seek=$((at + ${#2} + ${#3} + 6)) conv=notrunc 2>/dev/null
}
for e in "lineOrder lineOrder 99" "lineOrder lineOrder 3" "compression compression 99"; do
  set -- $e
  poke "$S/scene.0001.exr" "$1" "$2" "$3" "$T/enum.exr"
  fails "$1 $3: refused" 1 "enum\.exr: frame 1: .*$1.*$3" "$T/enum.out.exr" \
    "$FOGPIPE" -i "$T/enum.exr" -o "$T/enum.out.exr"
  fails "$1 $3 in a stream: refused" 1 "<stdin>: frame 1: .*$1.*$3" - sh -c '"$FOGPIPE" < "$1" > /dev/null' sh "$T/enum.exr"
done
fails "no color channel" 1 "shadow.0001.exr.*frame 1.*no color" "$T/o4.exr" \
  "$FOGPIPE" -i "$S/shadow.0001.exr" -o "$T/o4.exr"
"$OIIOTOOL" "$S/scene.0001.exr" --ch R,G,B,A -o "$T/nodepth.exr"
fails "no depth channel" 1 "nodepth.exr.*frame 1.*no depth channel.*--depth-channel" "$T/o5.exr" \
  "$FOGPIPE" -i "$T/nodepth.exr" -o "$T/o5.exr"
fails "color/depth size mismatch names both files" 1 "nodepth.exr.*shadow.0001.exr|shadow.0001.exr.*nodepth.exr" \
  "$T/o6.exr" "$FOGPIPE" -i "$T/nodepth.exr" --depth "$S/shadow.0001.exr" -o "$T/o6.exr"
# A missing directory is made (below); one that cannot be made, even as root, is an error.
fails "unwritable output" 1 "/proc/fogpipe-none/o7.exr.*cannot create the directory" - "$FOGPIPE" -i "$S/scene.0001.exr" -o /proc/fogpipe-none/o7.exr
fails "output over its own input" 2 "overwrite" - "$FOGPIPE" -i "$T/seq.0001.exr" -o "$T/seq.0001.exr"
fails "a sequence into one file" 2 "sequence pattern" - "$FOGPIPE" -i "$S/scene.####.exr" -o "$T/one.exr" --frames 1-2

# A failed run leaves an existing output as it was.
cp "$T/seq.0001.exr" "$T/keep.exr"
fails "failed run keeps the old output" 1 "trunc.exr" - "$FOGPIPE" -i "$T/trunc.exr" -o "$T/keep.exr"
check "old output intact" cmp "$T/seq.0001.exr" "$T/keep.exr"

# NaN or negative depth: sky, and a warning that counts them.
"$OIIOTOOL" "$S/scene.0001.exr" --ch "R,G,B,A,Z=-1" -o "$T/negdepth.exr"
check "negative depth is sky, with a warning" sh -c '
  "$FOGPIPE" -i "$1" -o "$2" 2> "$3" && grep -q "57600 pixels with NaN or negative depth" "$3"' sh \
  "$T/negdepth.exr" "$T/negdepth.out.exr" "$T/warn.txt"
check "-q silences warnings" sh -c '"$FOGPIPE" -q -i "$1" -o "$2" 2> "$3" && ! test -s "$3"' sh \
  "$T/negdepth.exr" "$T/negdepth.out.exr" "$T/warn.txt"

# Separate depth sequence and Blender multilayer input give the same fog.
"$OIIOTOOL" "$S/scene.0001.exr" --ch Z -o "$T/d.0001.exr"
check "--depth PATTERN" "$FOGPIPE" -i "$T/nodepth.exr" --depth "$T/d.####.exr" --frames 1 -o "$T/sep.exr"
check "separate depth = embedded depth" same_channels 0 R,G,B,A "$T/seq.0001.exr" "$T/sep.exr"
mkdir -p "$T/blender"
"$FP_SCENE" -o "$T/blender" --layout blender --frames 1-1 --shadow-size 0 >/dev/null
check "Blender multilayer input" "$FOGPIPE" -i "$T/blender/scene.0001.exr" -o "$T/blender-out.exr"
check "Blender output keeps layer names" sh -c '"$OIIOTOOL" --info -v "$1" | grep -q "ViewLayer.Combined.R"' \
  sh "$T/blender-out.exr"
"$OIIOTOOL" "$T/blender-out.exr" --ch "R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B" -o "$T/blender-rgb.exr"
check "Blender layout fogs like the plain one" same_channels 0 R,G,B "$T/seq.0001.exr" "$T/blender-rgb.exr"
check "--color-layer/--depth-channel overrides" "$FOGPIPE" -i "$T/blender/scene.0001.exr" \
  -o "$T/blender-ovr.exr" --color-layer ViewLayer.Combined --depth-channel ViewLayer.Depth.Z
fails "--depth-channel that does not exist" 1 "scene.0001.exr.*frame 1.*(Nope.Z|depth)" "$T/o8.exr" \
  "$FOGPIPE" -i "$T/blender/scene.0001.exr" -o "$T/o8.exr" --depth-channel Nope.Z

# OpenCL against the C double-precision reference on whole frames.
check "--cpu reference" "$FOGPIPE" --cpu --float -i "$S/scene.0003.exr" -o "$T/cpu.exr"
check "OpenCL" "$FOGPIPE" --float -i "$S/scene.0003.exr" -o "$T/cl.exr"
check "OpenCL within 1e-5 of the C reference (float output)" "$IDIFF" -q -fail 1e-5 -warn 1e-5 \
  "$T/cpu.exr" "$T/cl.exr"

# --print-camera and camera overrides.
check "--print-camera" sh -c '"$FOGPIPE" --print-camera -i "$1" --frames 1-2 > "$2" &&
  test "$(grep -c "^  position" "$2")" = 2 && grep -q "header worldToCamera" "$2"' sh "$S/scene.####.exr" "$T/cam.txt"
printf '1 0 2 -10 0 180 0 45\n' > "$T/cam.chan"
check "--camera-chan" sh -c '"$FOGPIPE" --print-camera -i "$1" --camera-chan "$2" | grep -Eq "forward +-?0.000000 -?0.000000 1.000000"' \
  sh "$S/scene.0001.exr" "$T/cam.chan"
# A .chan is checked as the camera options are: one line naming file:line.
printf '1 0 2 -10 0 180 0 45\n2 0 2 nan 0 180 0 45\n' > "$T/nan.chan"
fails "--camera-chan with NaN" 1 "nan.chan:2: tz is nan \(expected a finite number\)" "$T/chan-nan.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/chan-nan.exr" --camera-chan "$T/nan.chan"
printf '1 0 2 -10 0 180 0 0\n' > "$T/fov0.chan"
fails "--camera-chan with a vertical FOV of 0" 1 \
  "fov0.chan:1: vertical FOV 0 is out of range \(expected 0.01..179, as --vfov\)" "$T/chan-fov0.exr" \
  "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/chan-fov0.exr" --camera-chan "$T/fov0.chan"
fails "--chan-order that does not exist" 2 "--chan-order: unknown value 'xxy'" - \
  "$FOGPIPE" --print-camera -i "$S/scene.0001.exr" --camera-chan "$T/cam.chan" --chan-order xxy

# Presets: key = value lines; the command line wins.
printf 'density = 0.5\nfog-color = 1,0,0\n' > "$T/look.preset"
check "--preset" "$FOGPIPE" --preset "$T/look.preset" --density 0.02 -i "$S/scene.0001.exr" -o "$T/preset.exr"
check "--preset NAME from the build tree is the shipped file" sh -c '
  "$FOGPIPE" --preset low-sun-shafts -i "$1" -o "$3/preset-name.exr" &&
  "$FOGPIPE" --preset "$2/samples/presets/low-sun-shafts.preset" -i "$1" -o "$3/preset-file.exr" &&
  "$IDIFF" -q -fail 0 "$3/preset-name.exr" "$3/preset-file.exr"' sh "$S/scene.0001.exr" "$FP_SRCDIR" "$T"
fails "--preset with an unknown name: the names there are" 2 "preset nosuch: no such file.*low-sun-shafts" \
  "$T/preset-bad.exr" "$FOGPIPE" --preset nosuch -i "$S/scene.0001.exr" -o "$T/preset-bad.exr"
check "command line wins over the preset" sh -c '"$FOGPIPE" --fog-color 1,0,0 -i "$1" -o "$2" &&
  "$IDIFF" -q -fail 0 "$2" "$3"' sh "$S/scene.0001.exr" "$T/preset-cli.exr" "$T/preset.exr"

# The wavelet fogmap.
FMAP="$S/fogmap.exr"
check "--fogmap-preview writes the levels and the reconstruction" sh -c '"$FOGPIPE" --fogmap "$1" \
  --levels 2 --fogmap-preview "$2/prev" > "$2/prev.txt" && test -f "$2/prev/level00.png" &&
  test -f "$2/prev/level02.png" && test ! -e "$2/prev/level03.png" && test -f "$2/prev/reconstructed.png" &&
  "$OIIOTOOL" --info "$2/prev/reconstructed.png" | grep -q "64 x   64"' sh "$FMAP" "$T"
for basis in haar linear quadratic cubic; do
  check "--fogmap --basis $basis: OpenCL within 1e-5 of the C reference on a whole frame" sh -c '
    "$FOGPIPE" --float --fogmap "$1" --fog-rect -60,-20,60,160 --density 0.1 --height 0,5 --basis "$2" -i "$3" -o "$4/fm-cl.exr" &&
    "$FOGPIPE" --cpu --float --fogmap "$1" --fog-rect -60,-20,60,160 --density 0.1 --height 0,5 --basis "$2" -i "$3" -o "$4/fm-cpu.exr" &&
    "$IDIFF" -q -fail 1e-5 -warn 1e-5 "$4/fm-cl.exr" "$4/fm-cpu.exr"' sh "$FMAP" "$basis" "$S/scene.0002.exr" "$T"
done
"$OIIOTOOL" --pattern constant:color=1 16x16 1 -d float -o "$T/const.exr"
check "a constant fogmap (repeat) equals homogeneous fog" sh -c '
  "$FOGPIPE" --float --fogmap "$1" --fog-wrap repeat --basis cubic -i "$2" -o "$3/const-fm.exr" &&
  "$FOGPIPE" --float -i "$2" -o "$3/const-plain.exr" &&
  "$IDIFF" -q -fail 1e-5 -warn 1e-5 "$3/const-fm.exr" "$3/const-plain.exr"' sh "$T/const.exr" "$S/scene.0003.exr" "$T"
fails "missing fogmap" 1 "nofog.png" "$T/o9.exr" "$FOGPIPE" --fogmap "$T/nofog.png" -i "$S/scene.0001.exr" -o "$T/o9.exr"
fails "bad --fog-rect" 2 "fog-rect" "$T/o10.exr" "$FOGPIPE" --fogmap "$FMAP" --fog-rect 5,0,1,1 -i "$S/scene.0001.exr" -o "$T/o10.exr"
fails "unknown basis" 2 "basis.*expected haar.linear" - "$FOGPIPE" --basis septic
# Fogmaps from noise dip below 0: clamped to 0 (as an offline renderer
# clamps density) with one warning; a huge value (a corrupt file) is refused,
# where it once turned every pixel into NaN.
"$OIIOTOOL" --pattern constant:color=0.5 16x16 1 --fill:color=-0.25 2x2+3+3 --fill:color=-0.5 1x1+9+9 -d float -o "$T/neg.exr"
"$OIIOTOOL" --pattern constant:color=0.5 16x16 1 --fill:color=0 2x2+3+3 --fill:color=0 1x1+9+9 -d float -o "$T/neg0.exr"
check "negative fogmap values: clamped to 0, one warning with the count and the lowest" sh -c '
  "$FOGPIPE" --float --fogmap "$1" --density 0.1 -i "$3" -o "$4/neg-out.exr" 2> "$4/neg.txt" &&
  test "$(wc -l < "$4/neg.txt")" = 1 && grep -q "5 pixels below 0 (the lowest -0.5) clamped to 0" "$4/neg.txt" &&
  "$FOGPIPE" --float --fogmap "$2" --density 0.1 -i "$3" -o "$4/neg0-out.exr" &&
  "$IDIFF" -q -fail 0 "$4/neg-out.exr" "$4/neg0-out.exr"' sh "$T/neg.exr" "$T/neg0.exr" "$S/scene.0001.exr" "$T"
"$OIIOTOOL" --pattern constant:color=0.5 16x16 1 --fill:color=3e38 2x2+3+3 -d float -o "$T/huge.exr"
fails "a fogmap value whose optical depth overflows is refused (it gave NaN)" 1 \
  "huge.exr: pixel \(3, 3\) is 3e\+38.*optical depth across one fogmap pixel" "$T/o-huge.exr" \
  "$FOGPIPE" --fogmap "$T/huge.exr" --density 0.1 -i "$S/scene.0001.exr" -o "$T/o-huge.exr"
mkdir -p "$T/hseq"; cp "$T/neg0.exr" "$T/hseq/fog.0001.exr"; cp "$T/huge.exr" "$T/hseq/fog.0003.exr"
fails "the same in a key of a fogmap sequence, named" 1 "fog.0003.exr: pixel \(3, 3\) is 3e\+38" "$T/o-hseq.0002.exr" \
  "$FOGPIPE" --fogmap "$T/hseq/fog.####.exr" --density 0.1 -i "$S/scene.####.exr" --frames 2 -o "$T/o-hseq.####.exr"

# --sky keep: a frame of sky only (depth 1e30) comes out as it went in,
# with the sun lighting the fog; --sky fog (the default) fogs it.
"$OIIOTOOL" "$S/scene.0001.exr" --ch "R,G,B,A,Z=1e30" -o "$T/sky.exr"
check "--sky keep leaves sky pixels untouched" sh -c '
  "$FOGPIPE" --float --sky keep --sun 0,1,1 --density 0.05 -i "$1" -o "$2/sky-keep.exr" &&
  "$IDIFF" -q -fail 0 "$1" "$2/sky-keep.exr"' sh "$T/sky.exr" "$T"
check "--sky fog fogs them" sh -c '
  "$FOGPIPE" --float --sun 0,1,1 --density 0.05 -i "$1" -o "$2/sky-fog.exr" &&
  ! "$IDIFF" -q -fail 0.01 "$1" "$2/sky-fog.exr"' sh "$T/sky.exr" "$T"

# --fog-resolution 1/2 with the depth-edge pixels computed again at full
# resolution (--fog-edges exact, the default) against full resolution on
# the sample scene with sun and shadow map: off by more than 2/255 on at
# most 0.05% of the pixels; the upsampling alone is off on more.
check "--fog-resolution 1/2 (--fog-edges exact) within 2/255 of full resolution" sh -c '
  fog() { "$FOGPIPE" -i "$1" --sun -0.4,0.35,0.6 --phase hg:0.6 --shadow-map "$2" -o "$3" "$4" "$5" "$6" "$7"; }
  fog "$1" "$2" "$3/res-full.exr" --fog-resolution 1 --fog-edges exact &&
  fog "$1" "$2" "$3/res-half.exr" --fog-resolution 1/2 --fog-edges exact &&
  fog "$1" "$2" "$3/res-half-up.exr" --fog-resolution 1/2 --fog-edges upsample &&
  "$IDIFF" -q -fail 0.0079 -failpercent 0.05 -warn 0.0079 -warnpercent 0.05 "$3/res-full.exr" "$3/res-half.exr" &&
  ! "$IDIFF" -q -fail 0.0079 -failpercent 0.05 -warn 0.0079 -warnpercent 0.05 "$3/res-full.exr" "$3/res-half-up.exr"' sh \
  "$S/scene.0001.exr" "$S/shadow.0001.exr" "$T"

fails "missing shadow map" 1 "nowhere\.0001\.exr.*frame 1" "$T/o11.exr" "$FOGPIPE" --sun 0,1,1 \
  --shadow-map "$T/nowhere.####.exr" -i "$S/scene.0001.exr" -o "$T/o11.exr"
"$OIIOTOOL" --pattern constant:color=5 64x64 1 --chnames Z -d float -o "$T/nomat.0001.exr"
fails "shadow map without its matrices" 1 "nomat\.0001\.exr.*frame 1.*worldToCamera" "$T/o12.exr" \
  "$FOGPIPE" --sun 0,1,1 --shadow-map "$T/nomat.####.exr" -i "$S/scene.0001.exr" -o "$T/o12.exr"
fails "perspective shadow map" 1 "scene\.0001\.exr.*frame 1.*perspective.*orthographic" "$T/o13.exr" \
  "$FOGPIPE" --sun 0,1,1 --shadow-map "$S/scene.####.exr" -i "$S/scene.0001.exr" -o "$T/o13.exr"
fails "bad --light" 2 "light.*expected point" - "$FOGPIPE" --light lamp:1,2,3

# make install with DESTDIR: the installed binary runs from anywhere.
if [ -n "${FP_BUILDDIR:-}" ] && env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$FP_BUILDDIR" install DESTDIR="$T/dest" prefix=/opt/fp >"$T/install.txt" 2>&1; then
  check "installed fogpipe runs from / with embedded kernels" sh -c 'cd / &&
    "$1/opt/fp/bin/fogpipe" -i "$2" -o "$3"' sh "$T/dest" "$S/scene.0001.exr" "$T/installed.exr"
  check "installed fogpipe finds --preset NAME beside itself" sh -c 'cd / &&
    "$1/opt/fp/bin/fogpipe" -v --preset night-street-lamps -i "$2" -o "$3" 2>&1 |
    grep -q "preset: $1/opt/fp/share/fogpipe/presets/night-street-lamps.preset"' \
    sh "$T/dest" "$S/scene.0001.exr" "$T/installed-preset.exr"
  # OpenImageIO: a module loaded when first needed (src/bridges/oiio_bridge.h).
  check "installed: lib/fogpipe/fogpipe_oiio.so; fogpipe itself does not link OpenImageIO" sh -c '
    test -f "$1/opt/fp/lib/fogpipe/fogpipe_oiio.so" && ldd "$1/opt/fp/bin/fogpipe" > "$2/ldd.txt" &&
    ! grep -q libOpenImageIO "$2/ldd.txt"' sh "$T/dest" "$T"
  "$OIIOTOOL" --pattern constant:color=0.5 32x32 1 -d uint8 -o "$T/fm.png"
  check "installed fogpipe reads a PNG fogmap through its module, from /" sh -c 'cd / &&
    "$1/opt/fp/bin/fogpipe" --fogmap "$2" -i "$3" -o "$4"' \
    sh "$T/dest" "$T/fm.png" "$S/scene.0001.exr" "$T/installed-fm.exr"
  rm -f "$T/dest/opt/fp/lib/fogpipe/fogpipe_oiio.so"
  if [ ! -e "${FP_MODULE_DIR:-/nonexistent}/fogpipe_oiio.so" ]; then
    fails "installed fogpipe without its module: the fogmap, named with the module" 1 \
      "fm\.png.*fogpipe_oiio\.so" "$T/installed-nomod.exr" \
      "$T/dest/opt/fp/bin/fogpipe" --fogmap "$T/fm.png" -i "$S/scene.0001.exr" -o "$T/installed-nomod.exr"
    echo "not a module" > "$T/dest/opt/fp/lib/fogpipe/fogpipe_oiio.so"
    fails "installed fogpipe with a broken module: the fogmap, named with why it did not load" 1 \
      "fm\.png.*fogpipe_oiio\.so, which did not load: .*fogpipe_oiio\.so" "$T/installed-badmod.exr" \
      "$T/dest/opt/fp/bin/fogpipe" --fogmap "$T/fm.png" -i "$S/scene.0001.exr" -o "$T/installed-badmod.exr"
    rm -f "$T/dest/opt/fp/lib/fogpipe/fogpipe_oiio.so"
  else
    skip "a fogpipe_oiio.so is installed in $FP_MODULE_DIR"
  fi
  check "... and fogs EXR frames without it" \
    "$T/dest/opt/fp/bin/fogpipe" -i "$S/scene.0001.exr" -o "$T/installed-nomod2.exr"
else
  not_ok "make install DESTDIR"; diag "$T/install.txt" 2>/dev/null || true
fi
finish
