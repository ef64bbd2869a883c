#!/bin/sh
# Local lights shadowed by the scene's geometry (issue 23; --lamp-shadows
# screen, on by default) against Cycles: tests/blender_light.sh's check
# (flag-free: the medium's options only; the add-on's own sun maps) on
# light_scene.py's lamps=behind, the point light behind the thickest
# pillar and the spot behind the wall shining through a slit toward the
# camera, so that the shadow volumes of the pillar and the wall are in
# view; homogeneous fog only.  Per frame |bias| <= 1% and 8x8-block rms
# <= 2.5 x Cycles' noise; the comparison must catch --lamp-shadows none
# (the lamps unshadowed) as it catches twice the density and --lights none.
FP_TMP="$FP_TMP/lamps" FP_LIGHT_PROFILES=homog FP_LIGHT_SCENE=lamps=behind \
  FP_LIGHT_WRONG="--lamp-shadows none" \
  exec sh "${FP_SRCDIR:-.}/tests/blender_light.sh" "$@"
