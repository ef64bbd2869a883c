# fogpipe sh tests: TAP helpers.  Each test script sources this file.
# Environment (set by make check): FOGPIPE, FP_SCENE, FP_SAMPLES, FP_SRCDIR,
# FP_TMP, IDIFF, OIIOTOOL, FFMPEG, FOGPIPE_CACHE_DIR.
set -u
: "${FOGPIPE:?run through make check}"
tap_n=0
tap_failed=0
T="$FP_TMP/$(basename "$0" .sh)"
rm -rf "$T"
mkdir -p "$T"

ok() { tap_n=$((tap_n + 1)); echo "ok $tap_n - $*"; }
not_ok() { tap_n=$((tap_n + 1)); tap_failed=$((tap_failed + 1)); echo "not ok $tap_n - $*"; }
skip() { tap_n=$((tap_n + 1)); echo "ok $tap_n - # SKIP $*"; }
diag() { sed 's/^/# /' "$@"; }

# check DESC CMD...: passes when CMD exits 0; its output goes to the log.
check() {
  local desc=$1; shift
  if "$@" >"$T/out.txt" 2>&1; then ok "$desc"; else not_ok "$desc"; diag "$T/out.txt"; fi
}

# fails DESC STATUS REGEX OUTFILE CMD...: CMD must exit with STATUS, print
# exactly one line on stderr matching REGEX, and leave OUTFILE absent
# (OUTFILE "-" to skip that check).
fails() {
  local desc=$1 want=$2 re=$3 out=$4; shift 4
  local st=0
  "$@" >"$T/stdout.bin" 2>"$T/stderr.txt" || st=$?
  local lines; lines=$(wc -l <"$T/stderr.txt")
  if [ "$st" != "$want" ]; then
    not_ok "$desc (exit $st, expected $want)"; diag "$T/stderr.txt"
  elif [ "$lines" != 1 ]; then
    not_ok "$desc (expected one line on stderr, got $lines)"; diag "$T/stderr.txt"
  elif ! grep -Eq -- "$re" "$T/stderr.txt"; then
    not_ok "$desc (message does not match /$re/)"; diag "$T/stderr.txt"
  elif [ "$out" != - ] && [ -e "$out" ]; then
    not_ok "$desc (left an output file $out)"
  elif [ "$out" != - ] && ls -a "$(dirname "$out")" | grep -q '\.tmp\.'; then
    not_ok "$desc (left a temporary file)"
  else
    ok "$desc"
  fi
}

# same_channels FAILTOL CHANNELS A B: idiff on some channels only (idiff
# has no channel option, so oiiotool extracts them first).
same_channels() {
  local tol=$1 ch=$2 a=$3 b=$4 n=$((tap_n + 1))
  "$OIIOTOOL" "$a" --ch "$ch" -o "$T/sc$n.a.exr" &&
    "$OIIOTOOL" "$b" --ch "$ch" -o "$T/sc$n.b.exr" &&
    "$IDIFF" -q -fail "$tol" -warn "$tol" "$T/sc$n.a.exr" "$T/sc$n.b.exr"
}

finish() {
  echo "1..$tap_n"
  [ "$tap_failed" = 0 ]
}
