#!/bin/sh
# The layers (doc/design.md): no file includes or calls one from a layer
# above it, no circle between modules, every library file in a layer's
# folder, no source file over 1000 lines (tools/layers.py says what it
# counts).  Then the checker itself, on a copy of the tree with one
# violation planted at a time: each must be caught.
. "${FP_SRCDIR:-.}/tests/lib.sh"
PY=${PYTHON3:-python3}
L="$FP_SRCDIR/tools/layers.py"

check "no file includes one from a layer above it" "$PY" "$L" "$FP_SRCDIR" includes
check "no file calls or uses a symbol from a layer above it" "$PY" "$L" "$FP_SRCDIR" calls
check "no circle between modules (includes and calls)" "$PY" "$L" "$FP_SRCDIR" cycles
check "every library source sits in a layer's folder" "$PY" "$L" "$FP_SRCDIR" placed
check "no source file over 1000 lines" "$PY" "$L" "$FP_SRCDIR" lines

# A copy of the layered folders to plant violations in.
C="$T/tree"
fresh() {
  rm -rf "$C" && mkdir -p "$C/src" &&
    cp -R "$FP_SRCDIR/kernels" "$FP_SRCDIR/filters" "$FP_SRCDIR/lib" "$FP_SRCDIR/cli" "$C/" &&
    for d in base exr bridges cl scene; do cp -R "$FP_SRCDIR/src/$d" "$C/src/"; done &&
    chmod -R u+w "$C"
}
# caught DESC CHECK REGEX: the checker fails CHECK on the planted copy and
# names the violation.
caught() {
  local desc=$1 what=$2 re=$3 st=0
  "$PY" "$L" "$C" "$what" >"$T/planted.txt" 2>&1 || st=$?
  if [ "$st" = 1 ] && grep -Eq -- "$re" "$T/planted.txt"; then
    ok "planted: $desc"
  else
    not_ok "planted: $desc (exit $st)"; diag "$T/planted.txt"
  fi
}

fresh && "$PY" "$L" "$C" includes calls cycles placed >"$T/copy.txt" 2>&1 ||
  { not_ok "the copy passes before anything is planted"; diag "$T/copy.txt"; }

fresh && echo '#include "pipeline.h"' >>"$C/src/base/fp.c"
caught "the floor including the frame loop" includes 'src/base/fp.c:[0-9]+: includes lib/pipeline.h'
fresh && echo '#include "../../filters/scatter.h"' >>"$C/src/scene/camera.h"
caught "a relative include of a stage from below" includes 'src/scene/camera.h:[0-9]+: includes filters/scatter.h'
fresh && echo '#include "exrio.h"' >>"$C/cli/main.c"
caught "the program including more than the public header" includes 'cli/main.c:[0-9]+: the program includes src/exr/exrio.h'
fresh && printf 'void fp_planted(void);\nvoid fp_planted(void) { fp_light_append(0, 0, 0); }\n' >>"$C/src/cl/clrt.c"
caught "the runtime calling a stage" calls 'src/cl/clrt.c:[0-9]+: uses fp_light_append of filters/scatter.c'
fresh && printf 'const void *fp_planted_table = fp_option_groups;\n' >>"$C/src/scene/rig.c"
caught "the floor using the option groups" calls 'src/scene/rig.c:[0-9]+: uses fp_option_groups of lib/options.c'
fresh && printf 'void fp_planted(void);\nvoid fp_planted(void) { fp_animate_close(0); }\n' >>"$C/filters/fogmap_image.c"
caught "a circle within a layer" cycles 'circle: .*filters/animate.*filters/fogmap_image'
fresh && : >"$C/src/loose.c"
caught "a file loose in src/" placed 'src/loose.c: not in a layer'
fresh && awk 'BEGIN { for (i = 0; i < 1001; i++) print "/* */" }' >"$C/filters/long.c"
caught "a file of 1001 lines" lines 'filters/long.c: 1001 lines'
awk 'BEGIN { for (i = 0; i < 1000; i++) print "/* */" }' >"$C/filters/long.c"
"$PY" "$L" "$C" lines >"$T/planted.txt" 2>&1
if ! grep -q 'filters/long.c' "$T/planted.txt"; then ok "a file of 1000 lines passes"
else not_ok "a file of 1000 lines passes"; diag "$T/planted.txt"; fi

finish
