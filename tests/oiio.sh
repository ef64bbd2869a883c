#!/bin/sh
# Images through OpenImageIO from the command line: broken fogmaps are one
# line naming the file; previews and contact sheets on a full disk fail
# cleanly and leave nothing under their names; two outputs in one file are
# refused before any frame.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES
IN="$S/scene.0001.exr"

# Fogmaps cut in the middle (before: the JPEG gave garbage and exit 0, the
# PNG a second line from libpng).
"$OIIOTOOL" --pattern noise:type=uniform:min=0:max=1 256x256 1 -d uint8 -o "$T/fm.png"
"$OIIOTOOL" "$T/fm.png" -o "$T/fm.jpg"
for e in png jpg; do
  head -c "$(($(wc -c < "$T/fm.$e") / 2))" "$T/fm.$e" > "$T/cut.$e"
done
check "the whole fogmaps read" sh -c '"$1" --fogmap "$2" -i "$4" -o "$5/w1.exr" &&
  "$1" --fogmap "$3" -i "$4" -o "$5/w2.exr"' sh "$FOGPIPE" "$T/fm.png" "$T/fm.jpg" "$IN" "$T"
fails "a truncated PNG fogmap: one line naming it" 1 "cut\.png: truncated PNG" "$T/o1.exr" \
  "$FOGPIPE" --fogmap "$T/cut.png" -i "$IN" -o "$T/o1.exr"
fails "a truncated JPEG fogmap: one line naming it, no frame" 1 \
  "cut\.jpg: cannot read the pixels: truncated or corrupt" "$T/o2.exr" \
  "$FOGPIPE" --fogmap "$T/cut.jpg" -i "$IN" -o "$T/o2.exr"

# Two outputs in one file.
fails "--preview and --contact-sheet in one file: a usage error before any frame" 2 \
  "--contact-sheet .*p\.png: the same file as --preview .*p\.png" "$T/o3.exr" \
  "$FOGPIPE" -i "$IN" -o "$T/o3.exr" --preview "$T/p.png" --contact-sheet "$T/./p.png"
fails "a contact sheet named like one of the previews: refused" 2 \
  "--contact-sheet .*p\.0002\.png: the same file as --preview" "$T/o4.0001.exr" \
  "$FOGPIPE" -i "$S/scene.####.exr" --frames 1-2 -o "$T/o4.####.exr" \
  --preview "$T/p.####.png" --contact-sheet "$T/p.0002.png"

# A full disk: a file size limit (SIGXFSZ ignored, so a write past it fails
# with EFBIG as one past the end of a disk fails with ENOSPC).
if command -v prlimit >/dev/null 2>&1; then
  limited() { sh -c 'trap "" XFSZ; lim=$1; shift; exec prlimit --fsize="$lim" "$@" > /dev/null' sh "$@"; }
  fails "a preview on a full disk: one line, exit 1, no file, no temporary" 1 \
    "pd\.png: cannot write \(File too large\)" "$T/pd.png" \
    limited 16000 "$FOGPIPE" -i "$IN" -o - --preview "$T/pd.png"
  mkdir -p "$T/sheet"
  "$FOGPIPE" -i "$S/scene.####.exr" --frames 1-2 -o - --preview "$T/sheet/p.####.png" \
    --contact-sheet "$T/sheet/s.png" > /dev/null
  big=$(wc -c < "$T/sheet/p.0002.png"); sheet=$(wc -c < "$T/sheet/s.png")
  rm -rf "$T/sheet"; mkdir -p "$T/sheet"
  if [ "$sheet" -gt $((big + big / 4)) ]; then
    fails "a contact sheet on a full disk: one line, exit 1, no sheet, no temporary" 1 \
      "s\.png: cannot write \(File too large\)" "$T/sheet/s.png" \
      limited $(((big + sheet) / 2)) "$FOGPIPE" -i "$S/scene.####.exr" --frames 1-2 -o - \
      --preview "$T/sheet/p.####.png" --contact-sheet "$T/sheet/s.png"
  else
    skip "the contact sheet ($sheet bytes) is not larger than a preview ($big bytes)"
  fi
else
  skip "prlimit (util-linux)"
fi
# Outputs by extension: -o x.png, .tif, .jpg are the display-referred frame
# written as --preview writes it (before: EXR bytes under a .png name, exit
# 0); an unknown extension and EXR-only options are usage errors before any
# frame.
check "-o x.png: a real PNG, the same bytes as --preview of the frame" sh -c '
  "$1" -i "$2" -o "$3/x.png" --preview "$3/xp.png" &&
  test "$(od -An -tx1 -N8 "$3/x.png" | tr -d " \n")" = 89504e470d0a1a0a &&
  "$4" --info "$3/x.png" | grep -q "3 channel, uint8 png" && cmp "$3/x.png" "$3/xp.png"' \
  sh "$FOGPIPE" "$IN" "$T" "$OIIOTOOL"
check "-o x.####.TIF and -o x.jpeg: TIFF and JPEG frames" sh -c '
  "$1" -i "$2/scene.####.exr" --frames 1-2 -o "$3/x.####.TIF" && "$1" -i "$2/scene.0001.exr" -o "$3/x.jpeg" &&
  "$4" --info "$3/x.0002.TIF" | grep -q "uint8 tiff" && "$4" --info "$3/x.jpeg" | grep -q "uint8 jpeg"' \
  sh "$FOGPIPE" "$S" "$T" "$OIIOTOOL"
check "-o x.exr and -o x (no extension) stay EXR" sh -c '
  "$1" -i "$2" -o "$3/y.exr" && "$1" -i "$2" -o "$3/y" &&
  test "$(od -An -tx1 -N4 "$3/y" | tr -d " \n")" = 762f3101 && cmp "$3/y" "$3/y.exr"' sh "$FOGPIPE" "$IN" "$T"
fails "-o x.ppm: an unknown extension, refused before any frame, listing what is accepted" 2 \
  "-o .*x\.ppm: unknown output extension \"\.ppm\" \(expected \.exr, or \.png, \.tif, \.tiff, \.jpg, \.jpeg" \
  "$T/x.ppm" "$FOGPIPE" -i "$IN" -o "$T/x.ppm"
fails "-o x.png with --aov: EXR-only, refused before any frame" 2 "-o .*z\.png: --aov shapes EXR output only" \
  "$T/z.png" "$FOGPIPE" -i "$IN" -o "$T/z.png" --aov

# The module checked before dlopen trusts it: the program copied with a
# module beside it (bin/../lib/fogpipe), the module cut, garbage, or of
# another ABI.  Before, a cut module crashed the process (SIGBUS in dlopen).
M="$T/inst/lib/fogpipe/fogpipe_oiio.so"
mkdir -p "$T/inst/bin" "$T/inst/lib/fogpipe"
cp "$FOGPIPE" "$T/inst/bin/fogpipe"
cp "$FP_BUILDDIR/.libs/fogpipe_oiio.so" "$T/good.so"
if [ -e "${FP_MODULE_DIR:-/nonexistent}/fogpipe_oiio.so" ]; then
  skip "a fogpipe_oiio.so is installed in $FP_MODULE_DIR (it would be found instead)"
else
  cp "$T/good.so" "$M"
  check "a copied fogpipe loads the module beside it" \
    "$T/inst/bin/fogpipe" --fogmap "$T/fm.png" -i "$IN" -o "$T/m0.exr"
  head -c "$(($(wc -c < "$T/good.so") / 2))" "$T/good.so" > "$M"
  fails "a cut module: one line naming it and why, no crash" 1 \
    "fm\.png: .*fogpipe_oiio\.so, which did not load: .*fogpipe_oiio\.so: .*cut" \
    "$T/m1.exr" "$T/inst/bin/fogpipe" --fogmap "$T/fm.png" -i "$IN" -o "$T/m1.exr"
  head -c 100000 /dev/urandom > "$M"
  fails "a module of random bytes: one line" 1 \
    "did not load: .*fogpipe_oiio\.so: not an ELF file" \
    "$T/m2.exr" "$T/inst/bin/fogpipe" --fogmap "$T/fm.png" -i "$IN" -o "$T/m2.exr"
  if printf '%s\n' '#include <stdlib.h>' \
      'struct abi { int abi; char version[60]; };' \
      '__attribute__((visibility("default"))) const struct abi fp_oiio_module_abi = { 999, "0" };' \
      '__attribute__((visibility("default"))) void *fp_oiio_module(void) { abort(); }' > "$T/other.c" &&
     ${CC:-cc} -shared -fPIC -o "$T/other.so" "$T/other.c" &&
     printf '%s\n' '#include <stdlib.h>' \
      '__attribute__((visibility("default"))) void *fp_oiio_module(void) { abort(); }' > "$T/old.c" &&
     ${CC:-cc} -shared -fPIC -o "$T/old.so" "$T/old.c"; then
    cp "$T/other.so" "$M"
    fails "a module of another ABI: refused from its version symbol, nothing in it called" 1 \
      "did not load: .*fogpipe_oiio\.so is of another fogpipe \(module ABI 999, expected [0-9]+\)" \
      "$T/m3.exr" "$T/inst/bin/fogpipe" --fogmap "$T/fm.png" -i "$IN" -o "$T/m3.exr"
    cp "$T/old.so" "$M"
    fails "a module without the version symbol: refused, nothing in it called" 1 \
      "did not load: .*fogpipe_oiio\.so is not a fogpipe OpenImageIO module" \
      "$T/m4.exr" "$T/inst/bin/fogpipe" --fogmap "$T/fm.png" -i "$IN" -o "$T/m4.exr"
  else
    skip "a C compiler to build stand-in modules"
  fi
fi
# One way of finding the install (src/base/install.h), from anywhere: `make
# install prefix=P` and `make install DESTDIR=D`, the program run from PATH
# in another directory (before, the module was looked for in
# <cwd>/fogpipe: dladdr's bare "fogpipe" made absolute against the working
# directory) reads a PNG fogmap, writes a PNG preview, finds its presets and
# its OpenColorIO config; the Python module from the prefix does the same.
mkdir -p "$T/elsewhere"
R=$(cd "$T" && pwd -P)
runs_from_path() {
  # $1 the installed prefix; the rest, fogpipe's arguments after the checks'.
  local bin="$1/bin"; shift
  ( cd "$T/elsewhere" && rm -f p.png o.exr &&
    PATH="$bin:$PATH" fogpipe -v --preset morning-valley-mist --output-space ACEScg \
      --print-camera -i "$IN" > "$T/elsewhere/found.txt" 2>&1 &&
    PATH="$bin:$PATH" fogpipe --fogmap "$T/fm.png" -i "$IN" -o o.exr --preview p.png &&
    test "$(od -An -tx1 -N8 p.png | tr -d ' \n')" = 89504e470d0a1a0a && test -s o.exr )
}
found_in() {
  grep -q "preset: $1/share/fogpipe/presets/morning-valley-mist\.preset" "$T/elsewhere/found.txt" &&
    grep -q "OpenColorIO config (fogpipe.s config): $1/share/fogpipe/ocio/config\.ocio" "$T/elsewhere/found.txt"
}
if [ -e "${FP_MODULE_DIR:-/nonexistent}/fogpipe_oiio.so" ]; then
  skip "a fogpipe_oiio.so is installed in $FP_MODULE_DIR (it would be found instead)"
elif env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$FP_BUILDDIR" install prefix="$R/P" >"$T/install.txt" 2>&1 &&
     env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$FP_BUILDDIR" install DESTDIR="$R/D" prefix=/opt/fp >>"$T/install.txt" 2>&1; then
  check "make install prefix=P: fogpipe from PATH elsewhere reads a PNG fogmap, writes a PNG preview" \
    runs_from_path "$R/P"
  check "... and finds its preset and OpenColorIO config under P/share/fogpipe" found_in "$R/P"
  check "make install DESTDIR=D: the same from PATH elsewhere" runs_from_path "$R/D/opt/fp"
  check "... and finds its preset and OpenColorIO config under D/opt/fp/share/fogpipe" found_in "$R/D/opt/fp"
  PY=${PYTHON3:-python3}
  if "$PY" -c "import numpy" 2>/dev/null; then
    check "the Python module from the prefix: PNG fogmap and preview through P/lib/fogpipe" sh -c '
      cd "$1/elsewhere" && rm -f py.png py.exr &&
      PYTHONPATH=$(echo "$1"/P/lib/python3*/*-packages) "$2" -c "import sys, fogpipe
fogpipe.apply_file(sys.argv[1], \"py.exr\", fogmap=sys.argv[2], preview=\"py.png\", quiet=True)" "$3" "$4" &&
      test "$(od -An -tx1 -N8 py.png | tr -d " \n")" = 89504e470d0a1a0a' sh "$R" "$PY" "$IN" "$T/fm.png"
  else
    skip "python3 with numpy"
  fi
else
  not_ok "make install prefix=P and DESTDIR=D"; diag "$T/install.txt" 2>/dev/null || true
fi
finish
