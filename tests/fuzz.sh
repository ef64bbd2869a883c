#!/bin/sh
# The fuzzing harness's short fixed-seed run (make fuzz runs the same for
# FUZZ_SECONDS): 150 mutated inputs from seed 1 (EXR files in every
# compression, scanline, tiled and multipart, streams, fogmaps, .chan,
# presets, camera text), the size-limit suite and the API misuse cases,
# one TAP line per failure class and per case (tests/fuzz/fuzz.py says
# what fails a run).  tests/fuzz/known-failures names the checks known to
# fail until their fixes land: they are reported as TODO, and pass as
# an unexpected pass (remove them from the file then).
. "${FP_SRCDIR:-.}/tests/lib.sh"
FUZZ_DIR="$T" FUZZ_BIN="$FP_BUILDDIR/tests/fuzz" exec "${PYTHON3:-python3}" "$FP_SRCDIR/tests/fuzz/fuzz.py" --tap --seed 1 --runs 150 \
  --seconds 1000000 --known "$FP_SRCDIR/tests/fuzz/known-failures"
