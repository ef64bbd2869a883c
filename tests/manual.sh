#!/bin/sh
# The user's manual as the program gives it: --help wrapped to the
# terminal (80 columns when not a terminal).
. "${FP_SRCDIR:-.}/tests/lib.sh"

# longest FILE: the longest line's length.
longest() { awk '{ if (length > m) m = length } END { print m + 0 }' "$1"; }

env -u COLUMNS "$FOGPIPE" --help > "$T/help.txt"
check "--help not to a terminal: 80 columns at most, and some lines that wide" \
  sh -c 'n=$(awk "{ if (length > m) m = length } END { print m }" "$1"); [ "$n" -le 80 ] && [ "$n" -ge 70 ]' sh "$T/help.txt"
bad=""
for w in 40 57 72 100 160; do
  COLUMNS=$w "$FOGPIPE" --help > "$T/help$w.txt"
  n=$(longest "$T/help$w.txt")
  [ "$n" -le "$w" ] || bad="$bad $w:$n"
done
check "--help with COLUMNS=40, 57, 72, 100, 160: no line wider (got$bad)" test -z "$bad"
# Every option at every width, and nothing lost in the wrapping.
check "--help at 40 columns names every option that 160 columns does" sh -c '
  grep -o -- "--[a-z][a-z0-9-]*" "$1" | sort -u > "$1.o"
  grep -o -- "--[a-z][a-z0-9-]*" "$2" | sort -u > "$2.o"
  cmp "$1.o" "$2.o" && [ "$(tr -d " \n" < "$1")" = "$(tr -d " \n" < "$2")" ]' \
  sh "$T/help40.txt" "$T/help160.txt"
# A terminal's width (TIOCGWINSZ), through script(1)'s pseudo-terminal.
if command -v script >/dev/null 2>&1 && command -v stty >/dev/null 2>&1; then
  env -u COLUMNS script -qc "stty cols 100 rows 40; '$FOGPIPE' --help" /dev/null \
    < /dev/null | tr -d '\r' > "$T/tty.txt" 2>&1
  check "--help on a 100-column terminal: its width, not 80" \
    sh -c 'n=$(awk "{ if (length > m) m = length } END { print m }" "$1"); [ "$n" -le 100 ] && [ "$n" -gt 80 ]' sh "$T/tty.txt"
else
  skip "--help on a terminal (no script(1))"
fi

finish
