#!/bin/sh
# Hostile EXR frames (tests/exr_mangle makes them from the sample frames):
# the image budget checked from the header before anything is allocated,
# the same on the C path and on the C++ codec path (DWA, float B44);
# headers that claim more than the file can hold; chunks that hold fewer
# bytes than their lines need; a codec failure is an error, in a stream
# too, before any byte of the bad frame goes out.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES
M="$FP_BUILDDIR/tests/exr_mangle"

# One input per path: none and zip (the C library), dwaa, dwab and b44 with
# a float Z (OpenEXR's C++ library).
for c in none zip dwaa dwab b44; do
  "$FOGPIPE" -q -i "$S/scene.0001.exr" --compression "$c" -o "$T/$c.exr"
done

# measured FILE MAXKB MAXMS: read in a child (exr_mangle measure); it
# fails, within MAXMS ms and MAXKB KiB above a child that reads nothing.
measured() {
  "$M" measure "$1" > "$T/m.txt" 2> "$T/m.err" || return 1
  cat "$T/m.txt" >&2
  set -- $(sed 's/[a-z_]*=//g' "$T/m.txt") "$2" "$3"
  test "$1" = 1 && test $(($2 - $3)) -lt "$5" && test "$4" -lt "$6"
}

# ---------------------------------------------------------------- budget
for c in none zip dwaa dwab b44; do
  "$M" window "$T/$c.exr" "$T/huge_$c.exr" 0 0 99999 99999
  fails "$c claiming 100000x100000: refused from its header" 1 \
    "huge_$c\.exr: frame 1: part 0: data window 100000x100000 exceeds the image budget of 268435456 pixels" \
    "$T/huge_$c.out.exr" "$FOGPIPE" -i "$T/huge_$c.exr" -o "$T/huge_$c.out.exr"
  sed "s/huge_$c/huge/" "$T/stderr.txt" > "$T/msg_$c.txt"
  check "$c claiming 100000x100000: under 0.5 s and 40 MB above a no-op" \
    measured "$T/huge_$c.exr" 40000 500
done
check "the same message on the C and the C++ paths" sh -c \
  'for c in zip dwaa dwab b44; do cmp "$1/msg_none.txt" "$1/msg_$c.txt" || exit 1; done' sh "$T"
"$M" window "$T/dwaa.exr" "$T/long.exr" 0 0 11999999 39
fails "DWAA claiming 12000000x40: refused" 1 "long\.exr: frame 1: part 0: data window 12000000x40 exceeds" \
  "$T/long.out.exr" "$FOGPIPE" -i "$T/long.exr" -o "$T/long.out.exr"
check "DWAA claiming 12000000x40: cheap" measured "$T/long.exr" 40000 500
"$M" window "$T/b44.exr" "$T/b44_2g.exr" 0 0 65535 32767
fails "float B44 claiming 2^31 pixels: refused" 1 "data window 65536x32768 exceeds" \
  "$T/b44_2g.out.exr" "$FOGPIPE" -i "$T/b44_2g.exr" -o "$T/b44_2g.out.exr"

# --max-image-pixels: lowers and raises the budget (the sample is 320x180).
fails "--max-image-pixels 50000 refuses 320x180" 1 "data window 320x180 exceeds the image budget of 50000" \
  "$T/lo.exr" "$FOGPIPE" -i "$S/scene.0001.exr" --max-image-pixels 50000 -o "$T/lo.exr"
check "--max-image-pixels 57600 takes it" \
  "$FOGPIPE" -q -i "$S/scene.0001.exr" --max-image-pixels 57600 -o "$T/lo_ok.exr"
fails "--max-image-pixels 12x is a usage error" 2 "max-image-pixels: '12x' is not a pixel count" \
  "$T/bad.exr" "$FOGPIPE" -i "$S/scene.0001.exr" --max-image-pixels 12x -o "$T/bad.exr"
fails "--max-image-pixels 16G lets 100000x100000 DWAB past the budget, not past its size" 1 \
  "huge_dwab\.exr: frame 1: corrupt or truncated EXR \(its header claims 120000000000 bytes" \
  "$T/raised.exr" "$FOGPIPE" -i "$T/huge_dwab.exr" --max-image-pixels 16G -o "$T/raised.exr"

# ---------------------------------------------------------------- the file's size
"$M" window "$T/none.exr" "$T/wide.exr" 0 0 999999 39
fails "uncompressed claiming 1000000x40 in $(($(wc -c < "$T/none.exr") / 1024)) KB: refused" 1 \
  "wide\.exr: frame 1: corrupt or truncated EXR \(its header claims 480000000 bytes of pixels, which need at least 480000320 bytes of none data" \
  "$T/wide.out.exr" "$FOGPIPE" -i "$T/wide.exr" -o "$T/wide.out.exr"
check "uncompressed claiming 1000000x40: cheap" measured "$T/wide.exr" 40000 500
"$M" window "$T/zip.exr" "$T/zbig.exr" 0 0 15999 15999
fails "ZIP claiming 16000x16000: more than deflate can pack in the file" 1 \
  "zbig\.exr: frame 1: corrupt or truncated EXR .* of zip data" \
  "$T/zbig.out.exr" "$FOGPIPE" -i "$T/zbig.exr" -o "$T/zbig.out.exr"
check "ZIP claiming 16000x16000: cheap" measured "$T/zbig.exr" 40000 500

# ---------------------------------------------------------------- chunks
"$M" chunk "$T/none.exr" "$T/short.exr" 5 -8
fails "an uncompressed chunk 8 bytes short: named" 1 \
  "short\.exr: frame 1: part 0: chunk 5 \(lines 5-5\) holds 3832 bytes; its 3840 bytes of pixels need 3840 uncompressed" \
  "$T/short.out.exr" "$FOGPIPE" -i "$T/short.exr" -o "$T/short.out.exr"
"$M" chunk "$T/zip.exr" "$T/zshort.exr" 3 -1000000
fails "a ZIP chunk with a negative size: named" 1 "zshort\.exr: frame 1" \
  "$T/zshort.out.exr" "$FOGPIPE" -i "$T/zshort.exr" -o "$T/zshort.out.exr"

# A chunk whose size field is one too large: its last byte is the next
# chunk's first (ZIP's deflate stops at its stream's end, so the bytes
# decode; OpenEXR's C++ library finds the next chunk one byte late).
for c in zip dwaa; do
  "$M" chunk "$T/$c.exr" "$T/over_$c.exr" 0 1
  fails "$c: a chunk that runs into the next: refused" 1 \
    "over_$c\.exr: frame 1: part 0: chunk 0 \(at byte [0-9]+, [0-9]+ bytes with its header\) runs into the chunk at byte [0-9]+ \(corrupt EXR" \
    "$T/over_$c.out.exr" "$FOGPIPE" -i "$T/over_$c.exr" -o "$T/over_$c.out.exr"
done
cat "$S/scene.0001.exr" "$T/over_zip.exr" > "$T/over.stream"
fails "in a stream: the frame whose chunks overlap named" 1 "<stdin>: frame 2: part 0: chunk 0 .* runs into" - \
  sh -c '"$FOGPIPE" < "$1" > "$2"' sh "$T/over.stream" "$T/over.out.stream"

# ---------------------------------------------------------------- headers
# What OpenEXR's C library reads one way and its C++ library another is
# refused on both paths, with what is wrong; a corrupt header never
# reaches the C++ library, which allocates the sizes it reads from one
# ("out of memory" from a 9 KB file).
for c in zip dwaa b44; do
  "$M" attr-cut "$T/$c.exr" "$T/chl_$c.exr" channels 1
  fails "$c: a channel list without its closing NUL: refused" 1 \
    "chl_$c\.exr: frame 1: part 0: channel list of [0-9]+ bytes does not end with the NUL after its last channel" \
    "$T/chl_$c.out.exr" "$FOGPIPE" -i "$T/chl_$c.exr" -o "$T/chl_$c.out.exr"
  "$M" attr-type "$T/$c.exr" "$T/box_$c.exr" worldToNDC m33f
  fails "$c: worldToNDC typed m33f (64 bytes): the attribute named" 1 \
    "box_$c\.exr: frame 1: cannot read EXR header \(Attribute 'worldToNDC': Invalid size 64" \
    "$T/box_$c.out.exr" "$FOGPIPE" -i "$T/box_$c.exr" -o "$T/box_$c.out.exr"
  "$M" attr-cut "$T/$c.exr" "$T/disp_$c.exr" displayWindow 16
  fails "$c: a displayWindow of no bytes: the attribute named" 1 \
    "disp_$c\.exr: frame 1: cannot read EXR header \(Attribute 'displayWindow': Invalid size 0" \
    "$T/disp_$c.out.exr" "$FOGPIPE" -i "$T/disp_$c.exr" -o "$T/disp_$c.out.exr"
done
check "worldToNDC typed m33f in DWAA: cheap" measured "$T/box_dwaa.exr" 40000 500
# Parts of a multipart file that disagree on their displayWindow (OpenEXR's
# C++ library refuses the file; its C library reads it).
for c in zip dwaa; do
  "$OIIOTOOL" "$S/scene.0001.exr" "$S/scene.0002.exr" --chnames other.R,other.G,other.B,other.A,other.Z \
    --siappend --compression "$c" -o "$T/mp_$c.exr"
  "$M" attr-int "$T/mp_$c.exr" "$T/mpdisp_$c.exr" 1 displayWindow 3 4000
  fails "$c multipart: part 1's displayWindow differs from part 0's: refused" 1 \
    "mpdisp_$c\.exr: frame 1: part 1: displayWindow differs from part 0's \(the parts of a multipart EXR share it" \
    "$T/mpdisp_$c.out.exr" "$FOGPIPE" -i "$T/mpdisp_$c.exr" -o "$T/mpdisp_$c.out.exr"
done

# ---------------------------------------------------------------- codec failures
# The last chunk of float B44 longer than its data: OpenEXR's C++ library
# refuses it, and no other decoder is tried.
"$M" chunk "$T/b44.exr" "$T/b44_long.exr" 5 64
fails "float B44 the C++ library refuses: an error naming it" 1 \
  "b44_long\.exr: frame 1: cannot decode B44-compressed EXR \(.*longer than expected" \
  "$T/b44_long.out.exr" "$FOGPIPE" -i "$T/b44_long.exr" -o "$T/b44_long.out.exr"
"$FOGPIPE" -q -i "$S/scene.0001.exr" -o "$T/ref1.exr"
cat "$S/scene.0001.exr" "$T/b44_long.exr" "$S/scene.0002.exr" > "$T/bad.stream"
fails "in a stream: frame 2 named" 1 "<stdin>: frame 2: cannot decode B44" - \
  sh -c '"$FOGPIPE" < "$1" > "$2"' sh "$T/bad.stream" "$T/bad.out.stream"
check "in a stream: frame 1 whole, nothing of frame 2" cmp "$T/bad.out.stream" "$T/ref1.exr"

# ---------------------------------------------------------------- attributes
# dwaCompressionLevel of another type (renamed to an unknown one): the
# input is named in a warning, and the output is written with the level
# in use.
"$FOGPIPE" -q -i "$S/scene.0001.exr" --compression dwaa --dwa-level 60 -o "$T/lv.exr"
"$M" attr-type "$T/lv.exr" "$T/lv_odd.exr" dwaCompressionLevel zloat
check "dwaCompressionLevel of type zloat: a warning naming the input, the frame written" sh -c '
  "$FOGPIPE" -i "$1" -o "$2" 2> "$3" && grep -q "lv_odd\.exr: frame 1: .*dwaCompressionLevel.*zloat" "$3" &&
  ! grep -q "lv_odd\.out" "$3" && test -s "$2"' sh "$T/lv_odd.exr" "$T/lv_odd.out.exr" "$T/lv.err"
# An attribute of a type OpenEXR does not know, with no bytes: copied, and
# (under AddressSanitizer) nothing leaks.
"$M" empty-attr "$S/scene.0001.exr" "$T/blob.exr" fpEmpty fpblob
check "an empty attribute of an unknown type is copied" sh -c '
  "$FOGPIPE" -q -i "$1" --no-fog -o "$2" && grep -q fpblob "$2" &&
  "$FOGPIPE" -q -i "$1" --no-fog --compression dwab -o "$3" && grep -q fpblob "$3"' sh \
  "$T/blob.exr" "$T/blob.out.exr" "$T/blob.dwab.exr"
finish
