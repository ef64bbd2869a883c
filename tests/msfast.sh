#!/bin/sh
# The fast multiple-scattering path (issue 28, filters/ms.c and
# kernels/ms_core.h): the OpenCL kernel against the C path (--cpu) on the
# sample scene with the sun and its shadow map, without and with a fog box
# (the casters' and sides' grid), within idiff -fail 0.002 -failpercent 0.5
# -hardfail 0.01; the multiply scattered light it adds is well above that
# tolerance (the same comparison of on against off fails); bad values of
# the new options are refused in one line.
. "${FP_SRCDIR:-.}/tests/lib.sh"
P="$FP_SRCDIR/samples/presets"
IN="$FP_SAMPLES/scene.####.exr"
SM="$FP_SAMPLES/shadow.####.exr"
TOL="-fail 0.002 -failpercent 0.5 -hardfail 0.01"
for cfg in "open|" "box|--fog-box -60,-1,-20,60,15,160"; do
  name=${cfg%%|*} extra=${cfg#*|}
  for dev in cl cpu; do
    flag=; [ "$dev" = cpu ] && flag=--cpu
    # shellcheck disable=SC2086
    "$FOGPIPE" -q --preset "$P/low-sun-shafts.preset" --shadow-map "$SM" --fog-color auto \
      --frames 1 -i "$IN" -o "$T/$name-$dev.####.exr" $flag $extra --float > "$T/run.txt" 2>&1 ||
      { cat "$T/run.txt"; echo "fogpipe failed" > "$T/$name-$dev.failed"; }
  done
  # shellcheck disable=SC2086
  check "$name: OpenCL and C agree with the fast path on ($TOL)" \
    "$IDIFF" $TOL "$T/$name-cpu.0001.exr" "$T/$name-cl.0001.exr"
  # shellcheck disable=SC2086
  "$FOGPIPE" -q --preset "$P/low-sun-shafts.preset" --shadow-map "$SM" --fog-color 0,0,0 \
    --frames 1 -i "$IN" -o "$T/$name-off.####.exr" --cpu $extra --float
  # shellcheck disable=SC2086
  if "$IDIFF" $TOL "$T/$name-cpu.0001.exr" "$T/$name-off.0001.exr" > "$T/diff.txt" 2>&1; then
    not_ok "$name: the multiply scattered light is above the tolerance (on and off differ)"
    diag "$T/diff.txt"
  else
    ok "$name: the multiply scattered light is above the tolerance (on and off differ)"
  fi
done
fails "--fog-color with two components is refused" 2 "fog-color.*R,G,B.*auto" "$T/bad.0001.exr" \
  "$FOGPIPE" --fog-color 0.1,0.2 --frames 1 -i "$IN" -o "$T/bad.####.exr"
fails "--multiple-scattering maybe is refused" 2 "multiple-scattering" "$T/bad.0001.exr" \
  "$FOGPIPE" --multiple-scattering maybe --frames 1 -i "$IN" -o "$T/bad.####.exr"
finish
