#!/bin/sh
# Color management, fog layers and previews from the command line: round
# trips between color spaces within 1e-4, chromaticities read and written,
# no conversion = bit-identical output, a grey fog stays grey in every space,
# the fog layers merged over the plate (oiiotool --over) equal the composite
# within half-float precision, previews of the right size matching
# oiiotool --ociodisplay within 1 LSB (the dither) on all but 0.5% of the
# pixels and 2 LSB on all, contact sheets, every bad name, and the config
# found by the installed binary.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES
CFG="$FP_SRCDIR/samples/ocio/config.ocio"
IN="$S/scene.0001.exr"
unset OCIO

check "--list-spaces describes fogpipe's config" sh -c '"$FOGPIPE" --list-spaces > "$1" &&
  grep -q "^  ACEScg" "$1" && grep -q "^  Linear Rec.709 (sRGB) \[lin_rec709" "$1" &&
  grep -q "scene_linear: Linear Rec.709 (sRGB)" "$1" && grep -q "sRGB (default view Standard)" "$1" &&
  grep -q "chosen by fogpipe.s config" "$1" && grep -q "samples/ocio/config.ocio" "$1"' sh "$T/list.txt"

# No conversion asked for: the same bytes as without color management.
"$FOGPIPE" -i "$IN" -o "$T/plain.exr"
check "all spaces the same: bit-identical output" sh -c '"$FOGPIPE" -i "$1" -o "$2" --ocio "$3" \
  --input-space lin_rec709 --working-space scene_linear --output-space "Linear Rec.709 (sRGB)" &&
  cmp "$2" "$4"' sh "$IN" "$T/same.exr" "$CFG" "$T/plain.exr"
check "--aov leaves the color bit-identical" sh -c '"$FOGPIPE" -i "$1" -o "$2" --aov &&
  "$OIIOTOOL" "$2" --ch R,G,B,A -d half -o "$2.rgba.exr" && "$OIIOTOOL" "$3" --ch R,G,B,A -d half -o "$3.rgba.exr" &&
  "$IDIFF" -q -fail 0 -warn 0 "$2.rgba.exr" "$3.rgba.exr"' sh "$IN" "$T/aov.exr" "$T/plain.exr"

# Round trips (no fog: --density 0 leaves the plate as it is).
check "lin_rec709 -> ACEScg (float)" "$FOGPIPE" --density 0 --float -i "$IN" -o "$T/cg.exr" --output-space ACEScg
check "the output's chromaticities are ACEScg's (AP1)" sh -c '"$OIIOTOOL" --info -v "$1" |
  grep -q "chromaticities: 0.713, 0.293, 0.165, 0.83, 0.128, 0.044, 0.32168, 0.33767"' sh "$T/cg.exr"
check "ACEScg identified by its chromaticities, back to lin_rec709" \
  "$FOGPIPE" --density 0 --float -i "$T/cg.exr" -o "$T/back.exr" --output-space lin_rec709
check "round trip lin_rec709 -> ACEScg -> lin_rec709 within 1e-4" same_channels 1e-4 R,G,B "$IN" "$T/back.exr"
check "round trip keeps alpha and depth exactly" same_channels 0 A,Z "$IN" "$T/back.exr"
check "the output's chromaticities are Rec.709's" sh -c '"$OIIOTOOL" --info -v "$1" |
  grep -q "chromaticities: 0.64, 0.33, 0.3, 0.6, 0.15, 0.06, 0.3127, 0.329"' sh "$T/back.exr"
check "ACEScg -> ACES2065-1 -> lin_rec709 (explicit spaces) within 1e-4" sh -c '
  "$FOGPIPE" --density 0 --float -i "$1" -o "$2/ap0.exr" --input-space ACEScg --output-space aces2065_1 &&
  "$FOGPIPE" --density 0 --float -i "$2/ap0.exr" -o "$2/ap0back.exr" --input-space ACES2065-1 --output-space lin_rec709' \
  sh "$T/cg.exr" "$T"
check "... equals the plate" same_channels 1e-4 R,G,B "$IN" "$T/ap0back.exr"
check "through an ACES2065-1 working space and back within 1e-4" sh -c '
  "$FOGPIPE" --density 0 --float -i "$1" -o "$2" --working-space ACES2065-1 &&
  "$5" "$1" --ch R,G,B -o "$3" && "$5" "$2" --ch R,G,B -o "$4" && "$6" -q -fail 1e-4 -warn 1e-4 "$3" "$4"' \
  sh "$IN" "$T/work0.exr" "$T/work0.a.exr" "$T/work0.b.exr" "$OIIOTOOL" "$IDIFF"

# Chromaticities that match no space of the config: a warning, scene_linear.
"$OIIOTOOL" "$IN" --attrib:type=float[8] chromaticities 0.68,0.32,0.265,0.69,0.15,0.06,0.3127,0.329 -o "$T/p3.exr"
check "unknown chromaticities: one warning, scene_linear assumed" sh -c '
  "$FOGPIPE" -i "$1" -o "$2" --output-space ACEScg 2> "$3" && test "$(wc -l < "$3")" = 1 &&
  grep -q "p3.exr: frame 1: its chromaticities.*match no linear color space.*Linear Rec.709 (sRGB)" "$3"' \
  sh "$T/p3.exr" "$T/p3out.exr" "$T/p3.txt"
check "--input-space wins over the chromaticities (no warning)" sh -c '
  "$FOGPIPE" -i "$1" -o "$2" --input-space lin_rec709 --output-space ACEScg 2> "$3" && ! test -s "$3"' \
  sh "$T/p3.exr" "$T/p3out.exr" "$T/p3.txt"

# A grey fog over a black plate stays grey whatever the spaces.
"$OIIOTOOL" "$IN" --ch R=0.0,G=0.0,B=0.0,A,Z -o "$T/black.exr"
grey_case() {
  "$FOGPIPE" -i "$T/black.exr" -o "$T/grey.exr" --float --density 0.05 --fog-color 0.5,0.5,0.5 \
    --input-space lin_rec709 --working-space "$1" --output-space "$2" &&
  "$OIIOTOOL" "$T/grey.exr" --ch R -o "$T/grey.r.exr" && "$OIIOTOOL" "$T/grey.exr" --ch R=G -o "$T/grey.g.exr" &&
  "$OIIOTOOL" "$T/grey.exr" --ch R=B -o "$T/grey.b.exr" &&
  "$IDIFF" -q -fail 1e-5 -warn 1e-5 "$T/grey.r.exr" "$T/grey.g.exr" &&
  "$IDIFF" -q -fail 1e-5 -warn 1e-5 "$T/grey.r.exr" "$T/grey.b.exr" &&
  "$OIIOTOOL" --stats "$T/grey.exr" | awk '/Stats Max/ { exit !($3 > 0.4) }'  # there is fog
}
for w in lin_rec709 ACEScg ACES2065-1; do
  for o in lin_rec709 ACEScg ACES2065-1; do
    check "grey fog over black, working $w, output $o: R = G = B within 1e-5" grey_case "$w" "$o"
  done
done

# Fog layers: plate * (1 - fog.A) + fog.RGB is the composite.
check "--aov adds fog.R/G/B/A and transmittance.R/G/B" sh -c '"$OIIOTOOL" --info -v "$1" > "$2" &&
  for c in fog.R fog.G fog.B fog.A transmittance.R transmittance.G transmittance.B Z; do
    grep -q "channel list:.* $c (float)" "$2" || exit 1; done' sh "$T/aov.exr" "$T/aovinfo.txt"
# idiff: a channel fails when off by more than 1e-5 and by more than 2^-11
# relative (half precision: the composite is stored as half).
check "fog over the plate (oiiotool --over) = the composite within half precision" sh -c '
  "$OIIOTOOL" "$1" --ch R=fog.R,G=fog.G,B=fog.B,A=fog.A "$2" --ch R,G,B,A --over --ch R,G,B -o "$3/merged.exr" &&
  "$OIIOTOOL" "$1" --ch R,G,B -o "$3/comp.exr" &&
  "$4" -q -fail 1e-5 -failrelative 4.9e-4 -warn 1e-5 -warnrelative 4.9e-4 "$3/merged.exr" "$3/comp.exr"' \
  sh "$T/aov.exr" "$IN" "$T" "$IDIFF"
check "transmittance is grey and fog.A = 1 - transmittance" sh -c '
  "$2" "$1" --ch R=transmittance.R -o "$3/tr.exr" && "$2" "$1" --ch R=transmittance.B -o "$3/tb.exr" &&
  "$4" -q -fail 0 -warn 0 "$3/tr.exr" "$3/tb.exr" &&
  "$2" "$1" --ch R=fog.A --mulc -1 --addc 1 -o "$3/fa.exr" && "$4" -q -fail 1e-7 -warn 1e-7 "$3/tr.exr" "$3/fa.exr"' \
  sh "$T/aov.exr" "$OIIOTOOL" "$T" "$IDIFF"
check "in other spaces: working ACEScg, output ACES2065-1, over the converted plate" sh -c '
  "$FOGPIPE" -i "$1" -o "$2/aov0.exr" --aov --working-space ACEScg --output-space ACES2065-1 &&
  "$FOGPIPE" -i "$1" -o "$2/plate0.exr" --density 0 --float --output-space ACES2065-1 &&
  "$3" "$2/aov0.exr" --ch R=fog.R,G=fog.G,B=fog.B,A=fog.A "$2/plate0.exr" --ch R,G,B,A --over --ch R,G,B -o "$2/merged0.exr" &&
  "$3" "$2/aov0.exr" --ch R,G,B -o "$2/comp0.exr" &&
  "$4" -q -fail 1e-5 -failrelative 4.9e-4 -warn 1e-5 -warnrelative 4.9e-4 "$2/merged0.exr" "$2/comp0.exr"' \
  sh "$IN" "$T" "$OIIOTOOL" "$IDIFF"
check "--aov-only writes only the fog layers" sh -c '"$FOGPIPE" -i "$1" -o "$2" --aov-only &&
  "$3" --info -v "$2" > "$2.txt" && grep -q "7 channel" "$2.txt" && ! grep -q " R (half)\| Z (float)" "$2.txt"' \
  sh "$IN" "$T/aovonly.exr" "$OIIOTOOL"
check "--aov-only layers = --aov layers" same_channels 0 \
  fog.R,fog.G,fog.B,fog.A,transmittance.R,transmittance.G,transmittance.B "$T/aov.exr" "$T/aovonly.exr"
check "--aov on a file with fog layers replaces them" sh -c '"$FOGPIPE" -i "$1" -o "$2" --aov &&
  "$3" --info -v "$2" | grep -q "12 channel"' sh "$T/aov.exr" "$T/aov2.exr" "$OIIOTOOL"

# Previews, compared with OpenImageIO's own display transform of the frame.
check "previews and a contact sheet of 3 frames" "$FOGPIPE" -i "$S/scene.####.exr" --frames 1-3 \
  -o "$T/pv.####.exr" --preview "$T/pv.####.png" --contact-sheet "$T/sheet.png"
check "previews: 320x180 RGB, 8-bit" sh -c 'for f in 1 2 3; do
  "$1" --info "$(printf "$2/pv.%04d.png" $f)" | grep -q "320 x  180, 3 channel, uint8 png" || exit 1; done' \
  sh "$OIIOTOOL" "$T"
check "preview = oiiotool --ociodisplay sRGB Standard (1 LSB but 0.5%, 2 LSB)" sh -c '
  "$1" --colorconfig "$2" "$3/pv.0002.exr" --ch R,G,B --ociodisplay:from=lin_rec709 sRGB Standard -d uint8 -o "$3/ref.png" &&
  "$4" -q -fail 0.0040 -failpercent 0.5 -hardfail 0.0079 -warn 0.0040 -warnpercent 0.5 "$3/ref.png" "$3/pv.0002.png"' \
  sh "$OIIOTOOL" "$CFG" "$T" "$IDIFF"
check "contact sheet: 2 columns of 320x180 (ceil(sqrt(3)))" sh -c '"$1" --info "$2" | grep -q "640 x  360, 3 channel, uint8"' \
  sh "$OIIOTOOL" "$T/sheet.png"
check "contact sheet cell 2 = preview 2" sh -c '"$1" "$2/sheet.png" --cut 320x180+320+0 -o "$2/cell2.png" &&
  "$3" -q -fail 0 -warn 0 "$2/cell2.png" "$2/pv.0002.png"' sh "$OIIOTOOL" "$T" "$IDIFF"
check "--contact-sheet-size 200: 3 cells of 320x180 in 2 columns scaled to 100x56" sh -c '"$1" -i "$2" --frames 1-3 \
  -o "$3/ps.####.exr" --preview "$3/ps.####.png" --contact-sheet "$3/sheet-small.png" --contact-sheet-size 200 &&
  "$4" --info "$3/sheet-small.png" | grep -q "200 x  112, 3 channel, uint8"' sh "$FOGPIPE" "$S/scene.####.exr" "$T" "$OIIOTOOL"
check "--contact-sheet-columns 3" sh -c '"$1" -i "$2" --frames 1-3 -o "$3/pc.####.exr" --preview "$3/pc.####.png" \
  --contact-sheet "$3/sheet3.png" --contact-sheet-columns 3 && "$4" --info "$3/sheet3.png" | grep -q "960 x  180"' \
  sh "$FOGPIPE" "$S/scene.####.exr" "$T" "$OIIOTOOL"
check "ACES view from an ACEScg output = oiiotool --ociodisplay (1 LSB but 0.5%, 2 LSB)" sh -c '
  "$1" -i "$2" -o "$3/acesv.exr" --output-space ACEScg --view "ACES 1.0 - SDR Video" --preview "$3/acesv.png" &&
  "$4" --colorconfig "$5" "$3/acesv.exr" --ch R,G,B --ociodisplay:from=ACEScg sRGB "ACES 1.0 - SDR Video" -d uint8 -o "$3/acesref.png" &&
  "$6" -q -fail 0.0040 -failpercent 0.5 -hardfail 0.0079 -warn 0.0040 -warnpercent 0.5 "$3/acesref.png" "$3/acesv.png"' \
  sh "$FOGPIPE" "$IN" "$T" "$OIIOTOOL" "$CFG" "$IDIFF"
check "JPEG preview from a stream" sh -c 'cat "$1" "$2" | "$3" --preview "$4/st.####.jpg" > "$4/st.exrs" &&
  "$5" --info "$4/st.0002.jpg" | grep -q "320 x  180, 3 channel, uint8 jpeg"' \
  sh "$IN" "$S/scene.0002.exr" "$FOGPIPE" "$T" "$OIIOTOOL"

# Every bad name: one line, the right status, nothing written.
fails "unknown --output-space names the config and some spaces" 2 \
  "--output-space: no color space \"nope\" in the OpenColorIO config .*config.ocio.*ACEScg" \
  "$T/e1.exr" "$FOGPIPE" -i "$IN" -o "$T/e1.exr" --output-space nope
fails "--ocio that does not exist" 1 "missing.ocio: cannot open the OpenColorIO config" \
  "$T/e2.exr" "$FOGPIPE" -i "$IN" -o "$T/e2.exr" --ocio "$T/missing.ocio" --output-space ACEScg
printf 'ocio_profile_version: 2\nroles: [\n' > "$T/bad.ocio"
fails "a broken config" 1 "bad.ocio: not a valid OpenColorIO config" \
  "$T/e3.exr" "$FOGPIPE" -i "$IN" -o "$T/e3.exr" --ocio "$T/bad.ocio" --output-space ACEScg
fails "\$OCIO is used" 1 "bad.ocio: not a valid OpenColorIO config" \
  "$T/e4.exr" env OCIO="$T/bad.ocio" "$FOGPIPE" -i "$IN" -o "$T/e4.exr" --output-space ACEScg
check "--ocio wins over \$OCIO" env OCIO="$T/bad.ocio" "$FOGPIPE" -i "$IN" -o "$T/e5.exr" --ocio "$CFG" --output-space ACEScg
fails "a data space as working space" 2 "--working-space: \"raw\" is a data space" \
  "$T/e6.exr" "$FOGPIPE" -i "$IN" -o "$T/e6.exr" --working-space raw
fails "a non-linear working space" 2 "--working-space: \"srgb_tx\" is not a linear color space" \
  "$T/e7.exr" "$FOGPIPE" -i "$IN" -o "$T/e7.exr" --working-space srgb_tx
fails "--aov with a non-linear output space" 2 "--aov: the output space .* is not linear" \
  "$T/e8.exr" "$FOGPIPE" -i "$IN" -o "$T/e8.exr" --output-space srgb_tx --aov
check "a non-linear output space without --aov" "$FOGPIPE" -i "$IN" -o "$T/e9.exr" --output-space srgb_tx
fails "unknown display" 2 "--display: no display \"P3\" .*expected one of: sRGB" \
  "$T/pe.png" "$FOGPIPE" -i "$IN" -o "$T/e10.exr" --preview "$T/pe.png" --display P3
fails "unknown view" 2 "--view: display \"sRGB\" .* no view \"Filmic\" .*Standard" \
  "$T/pe.png" "$FOGPIPE" -i "$IN" -o "$T/e11.exr" --preview "$T/pe.png" --view Filmic
fails "--contact-sheet without --preview" 2 "--contact-sheet .* needs --preview" \
  "$T/e12.exr" "$FOGPIPE" -i "$IN" -o "$T/e12.exr" --contact-sheet "$T/s.png"
fails "--preview of an unknown format" 2 "--preview .*pe.gif: expected a .png, .jpg or .tif" \
  "$T/e13.exr" "$FOGPIPE" -i "$IN" -o "$T/e13.exr" --preview "$T/pe.gif"
fails "--preview without a frame number for a sequence" 2 "--preview .*one.png: .*frame number" \
  "$T/sq.0001.exr" "$FOGPIPE" -i "$S/scene.####.exr" --frames 1-2 -o "$T/sq.####.exr" --preview "$T/one.png"
check "--preview and --contact-sheet into missing directories make them" sh -c '
  "$1" -i "$2" -o "$3/e14.exr" --preview "$3/nodir/deeper/p.png" --contact-sheet "$3/sheets/s.png" &&
  test -f "$3/nodir/deeper/p.png" -a -f "$3/sheets/s.png"' sh "$FOGPIPE" "$IN" "$T"
: > "$T/afile"
fails "--preview where a file stands in for the directory" 1 "--preview .*afile/p.png: .*afile is not a directory" \
  "$T/e15.exr" "$FOGPIPE" -i "$IN" -o "$T/e15.exr" --preview "$T/afile/p.png"

# fogpipe's config: found in the build tree, and installed with the binary.
check "the build tree's fogpipe finds the config next to it" sh -c '"$1" -v -i "$2" -o "$3" --output-space ACEScg 2>&1 |
  grep -q "OpenColorIO config (fogpipe.s config): .*samples/ocio/config.ocio"' sh "$FOGPIPE" "$IN" "$T/bt.exr"
if [ -n "${FP_BUILDDIR:-}" ] && env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$FP_BUILDDIR" install DESTDIR="$T/dest" prefix=/opt/fp >"$T/install.txt" 2>&1; then
  check "make install puts the config in \$(pkgdatadir)/ocio" test -f "$T/dest/opt/fp/share/fogpipe/ocio/config.ocio"
  check "the installed fogpipe finds its config from /" sh -c 'cd / && "$1/opt/fp/bin/fogpipe" -v -i "$2" -o "$3" \
    --output-space ACEScg 2> "$3.txt" && grep -q "OpenColorIO config (fogpipe.s config): $1/opt/fp/share/fogpipe/ocio/config.ocio" "$3.txt"' \
    sh "$T/dest" "$IN" "$T/installed.exr"
else
  not_ok "make install DESTDIR"; diag "$T/install.txt" 2>/dev/null || true
fi
finish
