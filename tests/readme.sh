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
finish
