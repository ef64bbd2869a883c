#!/bin/sh
# Sequences: the pipelined frame loop gives the bytes of the one-at-a-time
# loop; --stats; the progress line (a terminal only); --skip-existing;
# SIGTERM and SIGINT in the middle of a run leave only whole frames, and a
# rerun with --skip-existing completes it byte for byte; the first error
# stops the run in order.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$FP_SAMPLES

# --- pipelined = one at a time, byte for byte -------------------------------
"$FOGPIPE" -i "$S/scene.####.exr" -o "$T/off.####.exr" --pipeline off
check "pipelined run: the bytes of --pipeline off, every frame" sh -c '
  "$FOGPIPE" -i "$1/scene.####.exr" -o "$2/on.####.exr" &&
  for f in 1 2 3 4 5 6 7 8; do cmp "$2/on.000$f.exr" "$2/off.000$f.exr" || exit 1; done' sh "$S" "$T"
check "pipelined stream in and out: the same bytes" sh -c '
  cat "$1"/scene.000[1-8].exr | "$FOGPIPE" > "$2/on.stream" &&
  cat "$2"/off.000[1-8].exr | cmp - "$2/on.stream"' sh "$S" "$T"
check "--no-fog writes the frames through unfogged" sh -c '
  "$FOGPIPE" --no-fog -i "$1/scene.0002.exr" -o "$2/nofog.exr" &&
  "$IDIFF" -q -fail 0.001 "$1/scene.0002.exr" "$2/nofog.exr"' sh "$S" "$T"

# --- --stats -----------------------------------------------------------------
check "--stats FILE: per-frame timings as JSON" sh -c '
  "$FOGPIPE" -i "$1/scene.####.exr" -o "$2/st.####.exr" --frames 2-4 --stats "$2/stats.json" &&
  grep -q "\"status\": \"ok\"" "$2/stats.json" && grep -q "\"frames_done\": 3," "$2/stats.json" &&
  test "$(grep -c "\"frame\": " "$2/stats.json")" = 3 &&
  grep "\"frame\": 3," "$2/stats.json" | grep "scene.0003.exr" | grep "st.0003.exr" |
    grep "read_ms" | grep "decode_ms" | grep "fog_ms" | grep "composite_ms" | grep "encode_ms" |
    grep -q "write_ms" && grep -q "\"totals_ms\": { \"read\": " "$2/stats.json"' sh "$S" "$T"
if command -v python3 >/dev/null; then
  check "--stats is valid JSON, with the host, the device and the command line" python3 -c 'import json, socket, sys; d = json.load(open(sys.argv[1]));
assert len(d["frames"]) == 3 and d["frames"][0]["frame"] == 2 and d["fps"] > 0
assert d["host"] == socket.gethostname(), d["host"]
assert "Portable Computing Language" in d["device"] or "pthread" in d["device"], d["device"]
assert d["argv"][1:] == ["-i", sys.argv[2] + "/scene.####.exr", "-o", sys.argv[3] + "/st.####.exr", "--frames", "2-4", "--stats", sys.argv[3] + "/stats.json"], d["argv"]
assert d["fogpipe"]' "$T/stats.json" "$S" "$T"
else
  skip "python3 not installed"
fi

# --- progress: one updating line on a terminal, a line per frame in logs -----
# (make check sets FOGPIPE_PROGRESS=off for the other tests; these unset it.)
check "progress for farm logs: one line per frame, N of M and a percentage" sh -c '
  env -u FOGPIPE_PROGRESS "$FOGPIPE" -i "$1/scene.####.exr" -o "$2/pp.####.exr" --frames 1-3 2> "$2/pipe.txt" &&
  test "$(wc -l < "$2/pipe.txt")" = 3 &&
  grep -Eq "^fogpipe: progress: 1 of 3 frames \(33%\), frame 1 in [0-9.]+ s, [0-9:]+ left$" "$2/pipe.txt" &&
  grep -Eq "^fogpipe: progress: 3 of 3 frames \(100%\), frame 3 in [0-9.]+ s, 0:00 left$" "$2/pipe.txt"' sh "$S" "$T"
check "progress lines for a stream: the count, no percentage" sh -c '
  cat "$1/scene.0001.exr" "$1/scene.0002.exr" | env -u FOGPIPE_PROGRESS "$FOGPIPE" > "$2/pp.stream" 2> "$2/pipes.txt" &&
  grep -Eq "^fogpipe: progress: 2 frames, frame 2 in [0-9.]+ s$" "$2/pipes.txt"' sh "$S" "$T"
check "--progress off, -q and \$FOGPIPE_PROGRESS=off: nothing on stderr" sh -c '
  env -u FOGPIPE_PROGRESS "$FOGPIPE" --progress off -i "$1/scene.####.exr" -o "$2/po.####.exr" --frames 1-2 2> "$2/off1.txt" &&
  env -u FOGPIPE_PROGRESS "$FOGPIPE" -q -i "$1/scene.####.exr" -o "$2/po.####.exr" --frames 1-2 2> "$2/off2.txt" &&
  FOGPIPE_PROGRESS=off "$FOGPIPE" -i "$1/scene.####.exr" -o "$2/po.####.exr" --frames 1-2 2> "$2/off3.txt" &&
  ! test -s "$2/off1.txt" && ! test -s "$2/off2.txt" && ! test -s "$2/off3.txt"' sh "$S" "$T"
fails "a bad \$FOGPIPE_PROGRESS is a usage error" 2 "FOGPIPE_PROGRESS.*expected auto" - \
  env FOGPIPE_PROGRESS=loud "$FOGPIPE" -i "$S/scene.0001.exr" -o "$T/pbad.exr"
if command -v script >/dev/null; then
  check "progress on a terminal: frame N/M, fps, a newline at the end" sh -c '
    script -qec "env -u FOGPIPE_PROGRESS \"$FOGPIPE\" -i \"$1/scene.####.exr\" -o \"$2/pt.####.exr\" --frames 1-8" /dev/null \
      < /dev/null > "$2/tty.txt" &&
    tr "\r" "\n" < "$2/tty.txt" | grep -Eq "^(.\[K)?frame 8/8  [0-9.]+ fps  done in 0:[0-9][0-9]" &&
    grep -q "frame [0-9]/8" "$2/tty.txt" && test "$(tail -c 2 "$2/tty.txt" | od -An -c | tr -d " ")" = "\r\n"' sh "$S" "$T"
  check "-q: no progress on a terminal either" sh -c '
    script -qec "env -u FOGPIPE_PROGRESS \"$FOGPIPE\" -q -i \"$1/scene.####.exr\" -o \"$2/pq.####.exr\" --frames 1-3" /dev/null \
      < /dev/null > "$2/ttyq.txt" && ! grep -q "frame" "$2/ttyq.txt"' sh "$S" "$T"
else
  skip "script(1) not installed"
  skip "script(1) not installed"
fi

# --- --skip-existing ---------------------------------------------------------
mkdir -p "$T/sk"
for f in 1 2 3 4; do cp "$S/scene.000$f.exr" "$T/sk/in.000$f.exr"; done
echo "not recomputed" > "$T/sk/out.0002.exr"
rm "$T/sk/in.0002.exr"
check "--skip-existing: frame 2's output is there, its input is not even needed" sh -c '
  "$FOGPIPE" -v --skip-existing -i "$1/in.####.exr" -o "$1/out.####.exr" --frames 1-4 2> "$1/v.txt" &&
  grep -q "out.0002.exr: frame 2: output exists, skipped (--skip-existing)" "$1/v.txt"' sh "$T/sk"
check "--skip-existing: the existing output is untouched, the others written" sh -c '
  grep -q "not recomputed" "$1/out.0002.exr" && cmp "$1/out.0001.exr" "$2/off.0001.exr" &&
  cmp "$1/out.0004.exr" "$2/off.0004.exr"' sh "$T/sk" "$T"
check "--skip-existing on a stream: skipped frames are read past" sh -c '
  cp "$2/off.0002.exr" "$2/ss.0002.exr" && cat "$1"/scene.000[1-3].exr |
  "$FOGPIPE" --skip-existing -o "$2/ss.####.exr" && cmp "$2/ss.0001.exr" "$2/off.0001.exr" &&
  cmp "$2/ss.0003.exr" "$2/off.0003.exr"' sh "$S" "$T"
fails "--skip-existing with a stream on stdout: exit 2" 2 "skip-existing.*stdout" - \
  sh -c '"$FOGPIPE" --skip-existing -i "$1" > /dev/null' sh "$S/scene.0001.exr"

# --- signals -------------------------------------------------------------------
# A long run: 120 frames of the C reference (--cpu, no device to start).
mkdir -p "$T/long" "$T/ref"
f=1
while [ $f -le 120 ]; do
  ln -s "$S/scene.000$(( (f - 1) % 8 + 1 )).exr" "$T/long/in.$(printf %04d $f).exr"
  f=$((f + 1))
done
"$FOGPIPE" -q --cpu -i "$T/long/in.####.exr" -o "$T/ref/out.####.exr"

# interrupted SIG DIR [OPTIONS...]: start the long run in the background
# (signals not ignored, as a shell's background job would have SIGINT),
# send SIG once frame 3 is written, leave the exit status in DIR/status.
interrupted() {
  sig=$1 dir=$2; shift 2
  mkdir -p "$dir"
  $defsig "$FOGPIPE" --cpu -i "$T/long/in.####.exr" -o "$dir/out.####.exr" --stats "$dir/stats.json" \
    "$@" 2> "$dir/stderr.txt" &
  pid=$!
  n=0
  while [ ! -e "$dir/out.0003.exr" ] && [ $n -lt 1000 ]; do sleep 0.01; n=$((n + 1)); done
  kill -s "$sig" $pid
  st=0
  wait $pid || st=$?
  echo $st > "$dir/status"
}

# whole_frames DIR: the run stopped cleanly (no temporary file, every frame
# written is the reference's frame, frames 1..N exactly with N the one the
# message names).
whole_frames() {
  dir=$1
  ! ls -a "$dir" | grep -q '\.tmp\.' || { echo "temporary file left"; return 1; }
  for o in "$dir"/out.*.exr; do
    cmp "$o" "$T/ref/$(basename "$o")" || return 1
  done
  last=$(sed -n 's/.*last complete frame \([0-9]*\) .*/\1/p' "$dir/stderr.txt")
  test -n "$last" && test "$last" -lt 120 &&
    test "$(ls "$dir" | grep -c '^out\.')" = "$last" &&
    test -e "$dir/out.$(printf %04d "$last").exr"
}

# complete DIR: a rerun with --skip-existing does the rest, byte for byte.
complete() {
  dir=$1; shift
  "$FOGPIPE" -q --cpu --skip-existing -i "$T/long/in.####.exr" -o "$dir/out.####.exr" "$@" &&
    for o in "$T"/ref/out.*.exr; do cmp "$o" "$dir/$(basename "$o")" || return 1; done
}

defsig=
interrupted TERM "$T/term"
check "SIGTERM mid-run: exit 143, one line naming the last complete frame" sh -c '
  test "$(cat "$1/status")" = 143 && test "$(wc -l < "$1/stderr.txt")" = 1 &&
  grep -Eq "^fogpipe: interrupted \(SIGTERM\): last complete frame [0-9]+ \(.*out\.[0-9]{4}\.exr\)" \
    "$1/stderr.txt"' sh "$T/term"
check "SIGTERM: no temporary or partial file, every frame written whole" whole_frames "$T/term"
check "SIGTERM: --stats written, status interrupted" grep -q '"status": "interrupted"' "$T/term/stats.json"
check "SIGTERM: a rerun with --skip-existing completes it, byte for byte" complete "$T/term"

if env --default-signal=INT true 2>/dev/null; then
  defsig="env --default-signal=INT"
  interrupted INT "$T/int" --pipeline off
  check "SIGINT mid-run (--pipeline off): exit 130, one line" sh -c '
    test "$(cat "$1/status")" = 130 && test "$(wc -l < "$1/stderr.txt")" = 1 &&
    grep -q "^fogpipe: interrupted (SIGINT): last complete frame" "$1/stderr.txt"' sh "$T/int"
  check "SIGINT: no temporary or partial file, every frame written whole" whole_frames "$T/int"
  check "SIGINT: a rerun with --skip-existing completes it, byte for byte" complete "$T/int" --pipeline off
else
  skip "env --default-signal not available (coreutils < 8.31)"
  skip "env --default-signal not available (coreutils < 8.31)"
  skip "env --default-signal not available (coreutils < 8.31)"
fi

# SIGTERM while the reader waits for a producer that has gone quiet.
mkfifo "$T/fifo"
mkdir -p "$T/quiet"
"$FOGPIPE" -o "$T/quiet/out.####.exr" < "$T/fifo" 2> "$T/quiet/stderr.txt" &
pid=$!
exec 3> "$T/fifo"
cat "$S/scene.0001.exr" "$S/scene.0002.exr" >&3
n=0
while [ ! -e "$T/quiet/out.0002.exr" ] && [ $n -lt 1000 ]; do sleep 0.01; n=$((n + 1)); done
sleep 0.1
kill -s TERM $pid
st=0
wait $pid || st=$?
exec 3>&-
check "SIGTERM while waiting on stdin: exit 143 at once, frames 1-2 whole" sh -c '
  test "$1" = 143 && grep -q "last complete frame 2 " "$2/quiet/stderr.txt" &&
  cmp "$2/quiet/out.0001.exr" "$2/off.0001.exr" && cmp "$2/quiet/out.0002.exr" "$2/off.0002.exr" &&
  ! ls -a "$2/quiet" | grep -q "\.tmp\."' sh "$st" "$T"

# --- the first error stops the run, in order ---------------------------------
mkdir -p "$T/bad"
for f in 1 2 4 5; do cp "$S/scene.000$f.exr" "$T/bad/in.000$f.exr"; done
head -c 20000 "$S/scene.0003.exr" > "$T/bad/in.0003.exr"
for mode in on off; do
  fails "a bad frame 3 (--pipeline $mode): one line, exit 1" 1 "in.0003.exr: frame 3" \
    "$T/bad/$mode.0003.exr" "$FOGPIPE" --pipeline $mode -i "$T/bad/in.####.exr" \
    -o "$T/bad/$mode.####.exr" --stats "$T/bad/$mode.json"
  check "a bad frame 3 (--pipeline $mode): frames 1-2 written whole, none after" sh -c '
    cmp "$1/$2.0001.exr" "$3/off.0001.exr" && cmp "$1/$2.0002.exr" "$3/off.0002.exr" &&
    test ! -e "$1/$2.0004.exr" && grep -q "\"status\": \"error\"" "$1/$2.json"' sh "$T/bad" "$mode" "$T"
done
finish
