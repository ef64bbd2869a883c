#!/bin/sh
# The user's manual as the program gives it: --help wrapped to the
# terminal (80 columns when not a terminal); the manual page and the bash
# and zsh completion, generated from the option tables, name every option
# --help names and are installed where man, bash-completion and zsh look.
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

# The options as --help lists them (one a line at 200 columns).
COLUMNS=200 "$FOGPIPE" --help |
  sed -n 's/^  \(-[A-Za-z], \)\{0,1\}\(--[a-z0-9-]*\).*/\2/p' | sort > "$T/options.txt"
check "--help lists over 100 options" test "$(wc -l < "$T/options.txt")" -gt 100
# The short ones, from the same lines.
COLUMNS=200 "$FOGPIPE" --help | sed -n 's/^  \(-[A-Za-z]\), --.*/\1/p' | sort > "$T/short.txt"

D="$T/dest"
if env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -C "$FP_BUILDDIR" install DESTDIR="$D" \
     prefix=/opt/fp >"$T/install.txt" 2>&1; then
  ok "make install DESTDIR"
else
  not_ok "make install DESTDIR"; diag "$T/install.txt"
fi
P="$D/opt/fp"
MAN="$P/share/man/man1/fogpipe.1"
BASH_C="$P/share/bash-completion/completions/fogpipe"
ZSH_C="$P/share/zsh/site-functions/_fogpipe"
check "installed: share/man/man1/fogpipe.1, bash-completion/completions/fogpipe, zsh/site-functions/_fogpipe" \
  test -s "$MAN" -a -s "$BASH_C" -a -s "$ZSH_C"

# What the README says comes with fogpipe: the sample scene maker under the
# name it is installed as, the farm scripts.
check "installed: bin/fogpipe-scene (its usage under that name), share/fogpipe/farm/{parallel,slurm-array}.sh, share/fogpipe/golden/fogpipe-golden-check executable" sh -c '
  "$1/bin/fogpipe-scene" --help | grep -q "^usage: fogpipe-scene -o DIR" &&
  test -x "$1/share/fogpipe/farm/parallel.sh" -a -x "$1/share/fogpipe/farm/slurm-array.sh" -a \
    -x "$1/share/fogpipe/golden/fogpipe-golden-check"' sh "$P"
check "installed: share/doc/fogpipe/LICENSE (BSD-3-Clause) and NEWS" sh -c '
  grep -q "BSD 3-Clause License" "$1/share/doc/fogpipe/LICENSE" && test -s "$1/share/doc/fogpipe/NEWS"' sh "$P"
check "no message names fp-scene, which is not installed" sh -c '
  ! COLUMNS=500 "$1" --help | grep fp-scene && ! "$2/bin/fogpipe-scene" --help | grep fp-scene &&
  ! "$2/bin/fogpipe-scene" --width 0 2>&1 | grep fp-scene' sh "$FOGPIPE" "$P"

# The Python module of a custom prefix: where the README says, imported
# with PYTHONPATH set to it (the library from the DESTDIR tree).
PY=${PYTHON3:-python3}
if command -v "$PY" >/dev/null 2>&1; then
  pyver=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
  check "prefix=/opt/fp: PYTHONPATH=/opt/fp/lib/python$pyver/dist-packages imports fogpipe (README)" sh -c '
    FOGPIPE_LIBRARY="$2/lib/libfogpipe.so.0" PYTHONPATH="$2/lib/python$3/dist-packages" \
      "$1" -c "import fogpipe, sys; sys.exit(not fogpipe.__file__.startswith(\"$2/lib/python$3/dist-packages/fogpipe/\"))"' \
    sh "$PY" "$P" "$pyver"
  check "doc/library.md names PREFIX/lib/python3.X/dist-packages and PYTHONPATH" sh -c '
    grep -q "PREFIX/lib/python3.X/dist-packages" "$1" && grep -q "export PYTHONPATH=" "$1"' sh "$FP_SRCDIR/doc/library.md"
else
  skip "the Python module (no python3)"
fi

# man -l formats it (man-db), groff finds nothing to warn about.
if command -v man >/dev/null 2>&1; then
  check "man -l fogpipe.1 formats the page" sh -c '
    MANWIDTH=200 MANPAGER=cat PAGER=cat man -l "$1" > "$2/man.txt" 2>"$2/man.err" &&
    grep -q "^NAME" "$2/man.txt" && grep -q "fogpipe - add physically based fog" "$2/man.txt" &&
    ! test -s "$2/man.err"' sh "$MAN" "$T"
  sed -n 's/^       \(-[A-Za-z], \)\{0,1\}\(--[a-z0-9-]*\).*/\2/p' "$T/man.txt" | sort -u > "$T/man-options.txt"
  check "the manual page documents every option --help lists, and no other" \
    diff -u "$T/options.txt" "$T/man-options.txt"
else
  skip "man -l (no man-db)"
  skip "the manual page's options (no man-db)"
fi
if command -v groff >/dev/null 2>&1; then
  check "groff -man -ww: no warnings" sh -c '
    groff -man -ww -z -Tutf8 "$1" 2>"$2/groff.err" && ! test -s "$2/groff.err"' sh "$MAN" "$T"
else
  skip "groff (not installed)"
fi

# bash: the completion function offers every option for "-", the choices
# of an enum, and the installed named looks for --preset.
if command -v bash >/dev/null 2>&1; then
  complete_bash() {
    PATH="$P/bin:$PATH" bash -c '. "$1"; shift; COMP_WORDS=(fogpipe "$@"); COMP_CWORD=$#
      _fogpipe; printf "%s\n" "${COMPREPLY[@]}"' sh "$BASH_C" "$@"
  }
  complete_bash - | grep -- "^--" | sort > "$T/bash-options.txt"
  check "bash completion offers every option --help lists, and no other" \
    diff -u "$T/options.txt" "$T/bash-options.txt"
  complete_bash - | grep -- "^-[A-Za-z]$" | sort > "$T/bash-short.txt"
  check "bash completion offers the short options" diff -u "$T/short.txt" "$T/bash-short.txt"
  complete_bash --shadows "" | tr '\n' ' ' > "$T/bash-enum.txt"
  check "bash completion: --shadows offers its five choices" grep -qx "auto none map screen map+screen " "$T/bash-enum.txt"
  complete_bash --preset m > "$T/bash-preset.txt"
  check "bash completion: --preset m offers morning-valley-mist (installed, found beside fogpipe in PATH)" \
    grep -qx morning-valley-mist "$T/bash-preset.txt"
else
  skip "bash completion (no bash)"
fi
# zsh: every option in the _arguments specs (zsh itself when installed).
sed -n "s/^  '\(--[a-z0-9-]*\)[=[].*/\1/p; s/^  '(-[A-Za-z] \(--[a-z0-9-]*\)).*/\1/p" "$ZSH_C" |
  sort > "$T/zsh-options.txt"
check "zsh completion specifies every option --help lists, and no other" \
  diff -u "$T/options.txt" "$T/zsh-options.txt"
if command -v zsh >/dev/null 2>&1; then
  check "zsh parses _fogpipe and passes _arguments one spec an option" zsh -c '
    _arguments() { shift 2; print -l -- "$@" > "$SPECS" }
    SPECS=$2.specs; . "$1"; cat "$SPECS"
    test $(wc -l < "$SPECS") -eq $(( $(wc -l < "$3") + $(wc -l < "$4") ))' \
    zsh "$ZSH_C" "$T/zsh" "$T/options.txt" "$T/short.txt"
else
  skip "zsh (not installed)"
fi

finish
