#!/bin/sh
# The README is the user's manual: its option reference must be the one the
# option tables generate, and its set-up commands must be the real ones.
. "${FP_SRCDIR:-.}/tests/lib.sh"
R="$FP_SRCDIR/README.md"
"$FOGPIPE" --help-markdown > "$T/options.md"
sed -n '/<!-- options:begin -->/,/<!-- options:end -->/p' "$R" | sed '1d;$d' > "$T/readme-options.md"
check "README option reference matches the tables (make readme-options)" diff -u "$T/options.md" "$T/readme-options.md"
check "README gives the two set-up commands" sh -c 'grep -q "./bootstrap demo" "$1" && grep -q "./bootstrap check" "$1"' sh "$R"
check "README quotes the benchmark file" sh -c 'grep -q "BENCHMARKS.md" "$1"' sh "$R"
# Every option the README's command lines give fogpipe is one it has (a
# renamed option left in the manual, as --list-color-spaces was, fails).
"$FOGPIPE" --help-markdown | grep -o -- '--[a-z][a-z0-9-]*' | sort -u > "$T/known.txt"
awk '/^    / && /fogpipe/ && !/blender|oiiotool|idiff|ffmpeg|python|import|fogpipe-golden-check|fogpipe-scene|PYTHONPATH|pkg-config/' "$R" |
  grep -o -- '--[a-z][a-z0-9-]*' | sort -u > "$T/used.txt"
check "the README's fogpipe command lines use only fogpipe's options ($(wc -l < "$T/used.txt") of them)" \
  sh -c 'test -s "$1" && test -z "$(comm -23 "$1" "$2")" || { comm -23 "$1" "$2"; exit 1; }' \
  sh "$T/used.txt" "$T/known.txt"
finish
