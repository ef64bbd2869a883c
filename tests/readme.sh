#!/bin/sh
# The README is the front page and doc/ the user's manual: the option
# reference (doc/options.md) must be the one the option tables generate,
# the set-up commands the real ones, and every option the command lines of
# the README and doc/ give fogpipe one it has.
. "${FP_SRCDIR:-.}/tests/lib.sh"
R="$FP_SRCDIR/README.md"
O="$FP_SRCDIR/doc/options.md"
"$FOGPIPE" --help-markdown > "$T/options.md"
sed -n '/<!-- options:begin -->/,/<!-- options:end -->/p' "$O" | sed '1d;$d' > "$T/doc-options.md"
check "doc/options.md matches the tables (make readme-options)" diff -u "$T/options.md" "$T/doc-options.md"
check "README gives the two set-up commands" sh -c 'grep -q "./bootstrap demo" "$1" && grep -q "./bootstrap check" "$1"' sh "$R"
check "README quotes the benchmark file" sh -c 'grep -q "BENCHMARKS.md" "$1"' sh "$R"
check "README is a front page (under 250 lines)" sh -c 'test "$(wc -l < "$1")" -lt 250' sh "$R"
# Every page the README sends the reader to is there.
for page in $(grep -o '(doc/[a-z/-]*\.md)' "$R" | tr -d '()' | sort -u); do
  check "README's link $page is a page" test -s "$FP_SRCDIR/$page"
done
# Every option the manual's command lines give fogpipe is one it has (a
# renamed option left in the manual, as --list-color-spaces was, fails).
"$FOGPIPE" --help-markdown | grep -o -- '--[a-z][a-z0-9-]*' | sort -u > "$T/known.txt"
for f in "$R" "$FP_SRCDIR"/doc/*.md "$FP_SRCDIR"/doc/hosts/*.md; do
  case $f in */doc/options.md|*/doc/design.md) continue ;; esac
  awk '/^    / && /fogpipe/ && !/blender|oiiotool|idiff|ffmpeg|python|import|fogpipe-golden-check|fogpipe-scene|PYTHONPATH|pkg-config/' "$f" |
    grep -o -- '--[a-z][a-z0-9-]*' | sort -u > "$T/used.txt"
  name=${f#"$FP_SRCDIR"/}
  [ -s "$T/used.txt" ] || continue
  check "$name: its fogpipe command lines use only fogpipe's options ($(wc -l < "$T/used.txt") of them)" \
    sh -c 'test -z "$(comm -23 "$1" "$2")" || { comm -23 "$1" "$2"; exit 1; }' \
    sh "$T/used.txt" "$T/known.txt"
done
finish
