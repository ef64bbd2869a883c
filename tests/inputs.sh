#!/bin/sh
# Text and side inputs that never end or are far too big (/dev/zero, a huge
# line, a 17 MiB preset, a sparse 5 GiB fogmap) fail within seconds with one
# line naming the file and the limit, and no output; a .chan line with more
# or fewer than 8 columns is refused with its file and line.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES
IN="$S/scene.0003.exr"
O="$T/out.exr"
# A hang is a failure (SIGKILL: the program catches SIGTERM to stop cleanly).
run() { timeout -s KILL "${FP_HANG_S:-60}" "$FOGPIPE" -q "$@"; }

fails "--camera-chan /dev/zero: refused at once" 1 \
  '^fogpipe: /dev/zero:1: .*\(expected a camera file: text of at most 16 MiB, lines of at most 64 KiB\)$' \
  "$O" run --camera-chan /dev/zero -i "$IN" -o "$O"
fails "--preset /dev/zero: refused at once" 2 \
  '^fogpipe: /dev/zero:1: .*\(expected a preset: text of at most 16 MiB, lines of at most 64 KiB\)$' \
  "$O" run --preset /dev/zero -i "$IN" -o "$O"
fails "--fogmap /dev/zero: refused (not a regular file)" 1 \
  '^fogpipe: /dev/zero: not a regular file \(expected a fogmap image file' \
  "$O" run --fogmap /dev/zero -i "$IN" -o "$O"
fails "-i /dev/zero: refused at its first bytes" 1 \
  '^fogpipe: /dev/zero: frame 1: not an EXR file' "$O" run -i /dev/zero -o "$O"

# A preset line of 70 KiB (fgets used to cut it into pieces silently).
awk 'BEGIN { printf "density = 0.1 #"; for (i = 0; i < 70 * 1024; i++) printf "x"; print "" }' \
  > "$T/long.preset"
fails "a preset line longer than 64 KiB: refused with its line" 2 \
  "^fogpipe: $T/long.preset:1: a line longer than 64 KiB" "$O" run --preset "$T/long.preset" -i "$IN" -o "$O"
# 17 MiB of comments.
awk 'BEGIN { for (i = 0; i < 17 * 16384; i++) print "# 64 bytes of comment, nothing else, again and again and again." }' \
  > "$T/big.preset"
fails "a preset of more than 16 MiB: refused" 2 \
  "^fogpipe: $T/big.preset: more than 16 MiB \(expected a preset" "$O" run --preset "$T/big.preset" -i "$IN" -o "$O"
rm -f "$T/big.preset"
printf '1 0 1 5 0 0 0 40\n2 0 1 5 0\0000 0 40\n' > "$T/nul.chan"
fails "a NUL byte in a .chan: refused with its line" 1 \
  "^fogpipe: $T/nul.chan:2: a NUL byte" "$O" run --camera-chan "$T/nul.chan" -i "$IN" -o "$O"
# Columns strtod reads but no .chan holds: hexadecimal (0x10 is 16, 0x1p3 8).
printf '1 0 2 0x10 0 180 0 45\n' > "$T/hex.chan"
fails "a hexadecimal .chan column: refused with its line and column" 1 \
  "^fogpipe: $T/hex.chan:1: column 4 '0x10' is not a number \(expected 8 decimal numbers" \
  "$O" run --camera-chan "$T/hex.chan" -i "$IN" -o "$O"
printf '3 0 2 -10 0x1p3 180 0 45\n' > "$T/hexf.chan"
fails "a hexadecimal float in a .chan: refused with its line and column" 1 \
  "^fogpipe: $T/hexf.chan:1: column 5 '0x1p3' is not a number" \
  "$O" run --camera-chan "$T/hexf.chan" -i "$IN" -o "$O"
# A sparse file beyond the image budget (4 GiB and 16 MiB by default).
if truncate -s 5G "$T/huge.exr" 2>/dev/null; then
  fails "a 5 GiB fogmap: refused before it is read" 1 \
    "^fogpipe: $T/huge.exr: 5368709120 bytes \(expected a fogmap image file of at most" \
    "$O" run --fogmap "$T/huge.exr" -i "$IN" -o "$O"
  rm -f "$T/huge.exr"
else
  skip "truncate -s 5G (sparse files)"
fi

# A good preset and .chan still work, with CRLF line ends.
printf 'density = 0.05\r\nheight = 0,4\r\n' > "$T/crlf.preset"
check "a preset with CRLF line ends is read" run --preset "$T/crlf.preset" -i "$IN" -o "$O"
finish
