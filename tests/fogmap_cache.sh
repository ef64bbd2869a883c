#!/bin/sh
# The fogmap's decomposition cached across runs (filters/fogmap_cache.h):
# a 256x256 map is decomposed once and loaded by the next run with the
# same bytes out; another map, another rectangle (the cells' size in fog
# units is not in the key) and a corrupt or truncated file; where the
# files go (FOGPIPE_CACHE_DIR, --fogmap-cache DIR) and the ways to turn it
# off; small maps are never cached.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$T/in
mkdir -p "$S"
"$OIIOTOOL" "$FP_SAMPLES/scene.0001.exr" --resize 80x45 -o "$S/f.0001.exr"
"$OIIOTOOL" --pattern noise:type=uniform:min=0:max=1:seed=3 256x256 1 --blur 5x5 -d float \
  -o "$T/map.exr"
"$OIIOTOOL" --pattern noise:type=uniform:min=0:max=1:seed=4 256x256 1 --blur 5x5 -d float \
  -o "$T/map2.exr"
LOOK="--fog-rect -20,-10,20,30 --density 0.2 --height 0,3 --lod-footprint 1"
C=$T/cache
# run NAME EXTRA...: one frame with the 256 map into $T/NAME.exr, -v into $T/NAME.log.
run() {
  local name=$1; shift
  # shellcheck disable=SC2086
  "$FOGPIPE" -v -i "$S/f.0001.exr" -o "$T/$name.exr" --fogmap "$T/map.exr" $LOOK "$@" \
    2>"$T/$name.log"
}
nfiles() { find "$1" -name '*.fogmap' 2>/dev/null | wc -l; }

export FOGPIPE_CACHE_DIR="$C"
check "first run with a 256x256 map" run a
check "... decomposes it" grep -q 'decomposed in' "$T/a.log"
check "... and keeps one cache file under FOGPIPE_CACHE_DIR/fogmaps" test "$(nfiles "$C/fogmaps")" = 1
check "... no temporary file left" sh -c '! ls "$1" | grep -qv "\.fogmap$"' sh "$C/fogmaps"
check "second run" run b
check "... loads the tables from the cache" grep -q 'loaded from the fogmap cache' "$T/b.log"
check "... the same bytes out" cmp "$T/a.exr" "$T/b.exr"
check "without the cache (--fogmap-cache off)" run off --fogmap-cache off
check "... decomposes and the same bytes out" sh -c \
  'grep -q "decomposed in" "$1/off.log" && cmp "$1/a.exr" "$1/off.exr"' sh "$T"

# Another rectangle: the tables are the same, the level of detail's cells
# in fog units are not.
check "another --fog-rect, cached" run r1 --fog-rect -40,-10,40,70
check "another --fog-rect, not cached" run r2 --fog-rect -40,-10,40,70 --fogmap-cache off
check "... loaded, and the same bytes as without the cache" sh -c \
  'grep -q "loaded from the fogmap cache" "$1/r1.log" && cmp "$1/r1.exr" "$1/r2.exr"' sh "$T"
check "another map" "$FOGPIPE" -v -i "$S/f.0001.exr" -o "$T/m2.exr" --fogmap "$T/map2.exr" \
  $LOOK
check "... its own file" test "$(nfiles "$C/fogmaps")" = 2

# A damaged file is ignored with one warning, the same bytes out, and
# written again.
F=$(ls "$C"/fogmaps/*.fogmap | while read -r f; do
  if grep -q "$(basename "$f")" "$T/a.log"; then echo "$f"; fi; done | head -n 1)
check "the first map's file is named under -v" test -n "$F"
size=$(wc -c <"$F")
printf 'XXXXXXXX' | dd of="$F" bs=1 seek=$((size / 2)) conv=notrunc 2>/dev/null
check "a corrupt cache file" run c1
check "... warned about once, decomposed again, the same bytes" sh -c \
  'test "$(grep -c "ignoring the cached fogmap tables (checksum mismatch)" "$1/c1.log")" = 1 &&
   grep -q "decomposed in" "$1/c1.log" && cmp "$1/a.exr" "$1/c1.exr"' sh "$T"
check "... and written again" run c2
check "... loaded next time" grep -q 'loaded from the fogmap cache' "$T/c2.log"
head -c $((size - 100)) "$F" >"$T/trunc" && cat "$T/trunc" >"$F"
check "a truncated cache file" run c3
check "... warned, the same bytes" sh -c \
  'grep -q "ignoring the cached fogmap tables (truncated)" "$1/c3.log" && cmp "$1/a.exr" "$1/c3.exr"' sh "$T"

# Where and whether.
check "--fogmap-cache DIR" run d --fogmap-cache "$T/mine"
check "... keeps its file in DIR" test "$(nfiles "$T/mine")" = 1
FOGPIPE_CACHE_DIR=off check "FOGPIPE_CACHE_DIR=off" run e
check "... writes nothing" test ! -e off/fogmaps
touch "$T/notadir"
check "a cache directory that cannot be made: a warning, the run goes on" run g \
  --fogmap-cache "$T/notadir/sub"
check "... the same bytes, warned" sh -c \
  'cmp "$1/a.exr" "$1/g.exr" && grep -q "cannot use the fogmap cache directory" "$1/g.log"' sh "$T"
check "the 64x64 sample map" "$FOGPIPE" -i "$S/f.0001.exr" -o "$T/s.exr" --fogmap \
  "$FP_SAMPLES/fogmap.exr" $LOOK --fogmap-cache "$T/small"
check "... is not cached (it decomposes faster than a file reads)" test "$(nfiles "$T/small")" = 0
finish
