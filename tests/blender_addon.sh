#!/bin/sh
# The Blender add-on (samples/blender/fogpipe_blender/__init__.py) with the real
# Blender (Cycles on the CPU, 48x32, 1 sample): tests/blender/addon_scene.py
# builds the scenes and writes where it put each light (tests/blender/
# rig_check.py reads the frames back through oiiotool):
#   - lights (a sun, a moving point light, a spot, a scaled rectangle and an
#     ellipse area light, a lamp hidden from the render, a portal), frames
#     1-2, with `-- --fogpipe-shadow-maps` then `-a`: every frame's rig is
#     the scene's lights in Cycles' units (position, direction, color x
#     power / (4 pi) or / 4, size, blend, extents), the hidden lamp and the
#     portal left out; the look set in the scene's settings is the
#     fogpipe-look text; the Note, cut at Blender's 511 bytes, says `lights
#     5` and the complete rig is the fogpipeRig attribute;
#   - the sun's shadow maps: an orthographic camera along the sun in their
#     Note, the frames' rig naming them, and their depth equal to Blender's
#     own ray casts within 1e-3 m (tests/blender/map_check.py);
#   - many (40 lamps): the Note carries a few, fogpipeRig all 40; the file
#     Blender wrote (kept by tests/blender/keep_written.py before the
#     add-on's handler changes it) and the rewritten one have the same pixels
#     (idiff, and fogpipe's fog of both) and OpenEXR reads the rewritten one;
#     a tiled file and a file with a wrong offset table are refused and left
#     as they were;
#   - noz (PNG, no Z pass): the render names both settings, and the
#     add-on's operator sets them;
#   - Preview Fog: the Render Result fogged through the Python module is
#     fogpipe's fog of it with the scene's look; without the module, a clear
#     message.
# Skips when blender is not installed.
. "${FP_SRCDIR:-.}/tests/lib.sh"
BLENDER=${BLENDER:-blender}
PY=${PYTHON3:-python3}
if ! command -v "$BLENDER" >/dev/null 2>&1; then
  skip "blender is not installed (Debian package blender; ./bootstrap check installs it)"
  finish
  exit $?
fi
ADDON="$FP_SRCDIR/samples/blender/fogpipe_blender/__init__.py"
TB="$FP_SRCDIR/tests/blender"
CHECK="$TB/rig_check.py"
B() { nice "$BLENDER" -b --factory-startup -noaudio "$@"; }

check "Blender builds the scenes with the add-on's settings" sh -c '
  "$1" -b --factory-startup -noaudio -P "$2" -P "$3/addon_scene.py" -- "$4/scene.blend" "$4" \
  > "$4/scene.log" 2>&1 && test -f "$4/scene.blend" || { tail -n 20 "$4/scene.log"; exit 1; }' \
  sh "$BLENDER" "$ADDON" "$TB" "$T"

# lights: the sun's maps (frames 1-2), then the frames, one Blender run.
L="$T/lights"
check "lights: shadow maps and frames 1-2 render with the add-on" sh -c '
  nice "$1" -b --factory-startup "$3/scene.blend" -S lights -noaudio -P "$2" -a -- \
  --fogpipe-shadow-maps --frames 1-2 > "$3/lights.log" 2>&1 &&
  test -f "$3/lights/render.0002.exr" && test -f "$3/lights/fogpipe/sun.0002.exr" ||
  { grep -i -E "error|traceback|fogpipe" "$3/lights.log" | head -n 20; exit 1; }' \
  sh "$BLENDER" "$ADDON" "$T"
for f in 1 2; do
  "$OIIOTOOL" --info -v "$L/render.000$f.exr" > "$L/info.$f.txt" 2>&1
  check "lights: frame $f: the rig is the scene's 5 lights as placed (Note cut, fogpipeRig whole)" \
    "$PY" "$CHECK" lights "$T/truth-lights.txt" $f "$L/info.$f.txt" cut
  diag "$T/out.txt"
  check "lights: frame $f: the rig says up z, clip 0.25 and its shadow map" \
    "$PY" "$CHECK" field "$L/info.$f.txt" up z clip 0.25 shadow fogpipe/sun.000$f.exr
done
LOOK="fogpipe-look 1 density=0.05 height=0,4,12 fog-color=0.6,0.65,0.7 phase=hg:0.5 albedo=0.8 fog-box=-20,-20,-1,20,20,12"
check "lights: the scene's fog settings are the frame's fogpipe-look" \
  "$PY" "$CHECK" look "$L/info.1.txt" "$LOOK"
check "lights: the camera still reads (--print-camera)" \
  "$FOGPIPE" --print-camera -i "$L/render.0001.exr" --up z
check "lights: the map's console line: extent, texels, texel size, caster held" \
  grep -q "frame 2: .*sun.0002.exr: sun map covers .* x .* m (the camera's view to 30 m, the fog box, the fog top), [0-9]* x [0-9]* texels of 0.25 m: casters down to 2 m held" "$T/lights.log"
# The map's camera: orthographic, looking along -sun (0.3,-0.5,0.8 normalized).
check "lights: the map carries an orthographic camera along the sun" sh -c '
  "$1" --print-camera -i "$2/fogpipe/sun.0001.exr" --up z > "$2/mapcam.txt" &&
  grep -q "orthographic view" "$2/mapcam.txt" &&
  awk "/forward/ { d = sqrt(0.98); e = (\$2 + 0.3/d)^2 + (\$3 - 0.5/d)^2 + (\$4 + 0.8/d)^2;
    print \"forward\", \$2, \$3, \$4, \"error\", e; exit !(e < 1e-10) }" "$2/mapcam.txt"' \
  sh "$FOGPIPE" "$L"
for f in 1 2; do
  "$OIIOTOOL" "$L/fogpipe/sun.000$f.exr" --ch ViewLayer.Depth.Z -o "$L/mapz.$f.exr" &&
    "$OIIOTOOL" --dumpdata "$L/mapz.$f.exr" > "$L/mapz.$f.txt" &&
    "$OIIOTOOL" --info -v "$L/fogpipe/sun.000$f.exr" > "$L/mapinfo.$f.txt"
  check "lights: frame $f: the map's depth is Blender's geometry along the sun" sh -c '
    nice "$1" -b --factory-startup "$2/scene.blend" -S lights -noaudio -P "$3/map_check.py" -- \
    $4 "$2/lights/mapinfo.$4.txt" "$2/lights/mapz.$4.txt" > "$2/map$4.log" 2>&1; st=$?;
    grep -E "MAPCHECK|Error" "$2/map$4.log"; exit $st' sh "$BLENDER" "$T" "$TB" $f
  diag "$T/out.txt"
done

# many: 40 lamps; keep_written.py copies each frame as Blender wrote it.
M="$T/many"
check "many: 40 lamps render with the add-on" sh -c '
  nice "$1" -b --factory-startup "$3/scene.blend" -S many -noaudio -P "$2" \
  -P "$4/keep_written.py" -f 1 -- "$3/many/orig" > "$3/many.log" 2>&1 &&
  test -f "$3/many/render.0001.exr" && test -f "$3/many/orig/render.0001.exr" ||
  { grep -i -E "error|traceback|fogpipe" "$3/many.log" | head -n 20; exit 1; }' \
  sh "$BLENDER" "$ADDON" "$T" "$TB"
"$OIIOTOOL" --info -v "$M/render.0001.exr" > "$M/info.txt" 2>&1
check "many: the Note says lights 40 and carries a few, fogpipeRig all 40 as placed" \
  "$PY" "$CHECK" lights "$T/truth-many.txt" 1 "$M/info.txt" cut
diag "$T/out.txt"
check "many: the rewritten EXR reads (OpenEXR, oiiotool) with the same pixels as Blender's" sh -c '
  "$1" -q -fail 0 -warn 0 "$3/orig/render.0001.exr" "$3/render.0001.exr" &&
  ! "$2" --info -v "$3/orig/render.0001.exr" | grep -q fogpipeRig &&
  "$2" --info -v "$3/render.0001.exr" | grep -q "^    fogpipeRig: \"fogpipe-rig 1 up z clip 0.25 lights 40 point"' \
  sh "$IDIFF" "$OIIOTOOL" "$M"
# fogpipe reads all 40 lamps from fogpipeRig; the frame as Blender wrote it
# (the Note cut after 2 lamps, no attribute) is refused in one line that
# says so, with no output, rather than fogged with 2 of its 40 lamps.
check "many: fogpipe reads the 40 lamps of fogpipeRig and fogs the frame" sh -c '
  test "$("$1" --print-camera -i "$2/render.0001.exr" | grep -c "^ *light [0-9]")" = 40 &&
  "$1" -i "$2/render.0001.exr" -o "$2/fog-new.exr" --density 0.05 --float' sh "$FOGPIPE" "$M"
check "many: the frame without fogpipeRig is refused in one line, no output" sh -c '
  ! "$1" -i "$2/orig/render.0001.exr" -o "$2/fog-orig.exr" --density 0.05 2> "$2/orig.err" &&
  test "$(wc -l < "$2/orig.err")" = 1 && ! test -e "$2/fog-orig.exr" &&
  grep -q "frame 1: the rig says 40 lights but carries 2 and there is no fogpipeRig attribute" \
  "$2/orig.err"' sh "$FOGPIPE" "$M"
check "many: ... and fogged with --lights none, which needs none of its lamps" \
  "$FOGPIPE" -q -i "$M/orig/render.0001.exr" -o "$M/fog-none.exr" --density 0.05 --lights none

# The header writer refuses what it cannot rewrite, and leaves it as it was:
# a tiled file, and Blender's frame with its first offset moved by 8.
"$OIIOTOOL" "$M/orig/render.0001.exr" --tile 16 16 -o "$M/tiled.exr" 2>/dev/null
cp "$M/orig/render.0001.exr" "$M/badtable.exr"
cat > "$M/refuse.py" <<PYEOF
import shutil, struct, sys
sys.path.insert(0, "$FP_SRCDIR/samples/blender")
import fogpipe_blender as f
path = "$M/badtable.exr"
data = bytearray(open(path, "rb").read())
_, end = f.exr_header(bytes(data))
o = struct.unpack_from("<Q", data, end)[0]
struct.pack_into("<Q", data, end, o + 8)
open(path, "wb").write(data)
for p in ("$M/tiled.exr", path):
    before = open(p, "rb").read()
    try:
        f.exr_set_strings(p, {"fogpipeRig": "fogpipe-rig 1 lights 0"})
        print("ACCEPTED", p)
    except f.ExrError as e:
        print("REFUSED", p, e, "UNCHANGED" if open(p, "rb").read() == before else "CHANGED")
PYEOF
B --python "$M/refuse.py" > "$M/refuse.log" 2>&1
check "the header writer refuses a tiled file and leaves it unchanged" \
  grep -q "REFUSED .*tiled.exr a tiled file .*UNCHANGED" "$M/refuse.log"
check "the header writer refuses a wrong offset table and leaves the file unchanged" \
  grep -q "REFUSED .*badtable.exr offset table entry 0 points at .*UNCHANGED" "$M/refuse.log"
grep -E "REFUSED|ACCEPTED|Error" "$M/refuse.log" | diag

# noz: PNG without the Z pass; the render names both settings, and
# fogpipe.setup_output sets them.
check "noz: the render names the file format and the Z pass setting" sh -c '
  nice "$1" -b --factory-startup "$3/scene.blend" -S noz -noaudio -P "$2" -f 1 > "$3/noz.log" 2>&1;
  grep "^fogpipe: scene" "$3/noz.log";
  grep -q "^fogpipe: scene .noz.: Output Properties > Output > File Format is PNG, not OpenEXR MultiLayer" "$3/noz.log" &&
  grep -q "^fogpipe: scene .noz.: View Layer Properties > Passes > Data > Z is off for view layer .ViewLayer. (view_layer.use_pass_z)" "$3/noz.log"' \
  sh "$BLENDER" "$ADDON" "$T"
check "noz: Set OpenEXR MultiLayer + Z leaves nothing to report" sh -c '
  nice "$1" -b --factory-startup "$3/scene.blend" -S noz -noaudio -P "$2" --python-expr "
import sys, bpy
sys.path.insert(0, \"$4/samples/blender\")
import fogpipe_blender as f
s = bpy.context.scene
assert f.output_problems(s), \"nothing reported before\"
bpy.ops.fogpipe.setup_output()
print(\"AFTER\", f.output_problems(s) + f.output_warnings(s))
" > "$3/setup.log" 2>&1; grep -q "^AFTER \[\]" "$3/setup.log" || { tail -n 5 "$3/setup.log"; exit 1; }' \
  sh "$BLENDER" "$ADDON" "$T" "$FP_SRCDIR"

# Preview Fog: the Render Result of frame 1 through the Python module.
P="$T/preview"
mkdir -p "$P"
if "$PY" -c "import numpy" 2>/dev/null; then
  check "Preview Fog fogs the Render Result through the Python module" sh -c '
    TMPDIR="$4" PYTHONPATH="$5/python" FOGPIPE_LIBRARY="$6/.libs/libfogpipe.so.0" \
    nice "$1" -b --factory-startup "$3/scene.blend" -S lights -noaudio --python-use-system-env \
    -P "$2" --python-expr "
import bpy
bpy.ops.render.render()
print(\"PREVIEW\", bpy.ops.fogpipe.preview(), bpy.data.images[\"fogpipe preview\"].filepath)
" > "$4/preview.log" 2>&1; grep -q "^PREVIEW {.FINISHED.}" "$4/preview.log" ||
    { grep -E "fogpipe|rror" "$4/preview.log" | tail -n 5; exit 1; }' \
    sh "$BLENDER" "$ADDON" "$T" "$P" "$FP_SRCDIR" "$FP_BUILDDIR"
  check "Preview Fog's image is fogpipe's fog of the render with the scene's look" sh -c '
    d=$(ls -d "$1"/fogpipe-preview-* | head -n 1) && "$2" -i "$d/render.exr" -o "$1/cli.exr" \
    --up z --density 0.05 --height 0,4,12 --fog-color 0.6,0.65,0.7 --phase hg:0.5 --albedo 0.8 \
    --fog-box -20,-20,-1,20,20,12 && "$3" -q -fail 1e-6 -warn 1e-6 "$d/fogged.exr" "$1/cli.exr" &&
    ! "$3" -q -fail 1e-6 -warn 1e-6 "$d/render.exr" "$1/cli.exr"' sh "$P" "$FOGPIPE" "$IDIFF"
else
  skip "Preview Fog: python3 with numpy"
  skip "Preview Fog's image: python3 with numpy"
fi
check "Preview Fog without the module says so" sh -c '
  nice "$1" -b --factory-startup "$3/scene.blend" -S lights -noaudio -P "$2" --python-expr "
import sys, bpy
sys.modules[\"fogpipe\"] = None
try:
    bpy.ops.fogpipe.preview()
except RuntimeError as e:
    print(\"REPORT\", e)
" > "$3/nomodule.log" 2>&1;
  grep -q "REPORT .*fogpipe: Preview Fog needs fogpipe.s Python module" "$3/nomodule.log" ||
  { tail -n 5 "$3/nomodule.log"; exit 1; }' sh "$BLENDER" "$ADDON" "$T"
finish
