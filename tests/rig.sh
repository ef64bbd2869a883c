#!/bin/sh
# The rig a frame carries (issue 23): text in a string attribute (Blender's
# Note), typed fogpipe* attributes, --rig JSON.  --print-camera shows it;
# its sun, lights, up axis, clip start, shadow map and look change the
# output exactly as the equivalent flags do; flags override it, --lights
# none ignores it; animated lights follow the frames through the pipelined
# loop; a single file's frame number comes from its name (--frame N); a
# shadow map's camera may come from its Note; bad rigs are one-line errors.
. "${FP_SRCDIR:-.}/tests/lib.sh"
S=$T/s
"$FP_SCENE" -o "$S" --width 64 --height 36 --frames 1-2 --shadow-size 128 >/dev/null 2>&1 ||
  { not_ok "fogpipe-scene"; finish; exit 1; }
P=$S/scene.0001.exr
# note OUT IN TEXT: IN with TEXT in its Note (as Blender's stamp writes it).
note() { "$OIIOTOOL" --nosoftwareattrib "$2" --attrib Note "$3" -o "$1"; }
FOG="--cpu --density 0.06 --height 0,6,25 --fog-color 0.2,0.2,0.25 -q"
SUN="fogpipe-rig 1 sun 0.3 1 0.2 2 2 1.5 0.5"
PT="point 0 2 5 10 8 6 0.1"
SPOT="spot 1 3 2 5 5 5 0.2 0 -1 0 60 0.2"
# same A B: identical pixels.
same() { "$IDIFF" -q -fail 0 -warn 0 "$1" "$2" >/dev/null 2>&1; }
differ() { ! same "$1" "$2"; }

# The text form, with the camera's Note text before it.
note "$T/n.0001.exr" "$P" "fogpipe-camera-less; $SUN $PT $SPOT"
note "$T/rig.0001.exr" "$P" "fogpipe-rig 1 up y clip 0.5 shadow shadow.0001.exr lights 3 sun 0.3 1 0.2 2 2 1.5 0.5 $PT $SPOT"
check "--print-camera shows the rig" sh -c '
  "$1" --print-camera -i "$2" > "$3" &&
  grep -q "rig       up y (rig), clip start 0.5 (rig), lights from the frame" "$3" &&
  grep -q "sun       toward 0.282216 0.940721 0.188144, irradiance 2 2 1.5" "$3" &&
  grep -q "light 1   point at 0 2 5, intensity 10 8 6 W/sr, radius 0.1" "$3" &&
  grep -q "light 2   spot at 1 3 2, intensity 5 5 5 W/sr, radius 0.2, pointing 0.000000 -1.000000 0.000000, size 60 deg, blend 0.2" "$3" &&
  grep -q "shadow map .*/shadow.0001.exr (rig)" "$3" &&
  grep -q "^  position  " "$3"' sh "$FOGPIPE" "$T/rig.0001.exr" "$T/pc.txt"
check "... without a rig, --print-camera says what it said" sh -c '
  "$1" --print-camera -i "$2" > "$3" && [ "$(wc -l < "$3")" = 6 ]' sh "$FOGPIPE" "$P" "$T/pc0.txt"

# The rig's sun and lights are the flags' sun and lights.
LIGHTS="--light point:0,2,5:10,8,6:1:0.1 --light spot:1,3,2:5,5,5:1:0,-1,0:cycles:60,0.2:0.2"
check "a frame with the rig" "$FOGPIPE" -i "$T/n.0001.exr" -o "$T/n.exr" $FOG
check "a plate with the same as flags" "$FOGPIPE" -i "$P" -o "$T/f.exr" $FOG --sun 0.3,1,0.2 \
  --sun-color 1,1,0.75 --sun-intensity 2 $LIGHTS
check "... the same frame" same "$T/n.exr" "$T/f.exr"
check "the plate alone" "$FOGPIPE" -i "$P" -o "$T/p.exr" $FOG
check "... differs from the lit frame" differ "$T/n.exr" "$T/p.exr"
check "--lights none ignores the rig" "$FOGPIPE" -i "$T/n.0001.exr" -o "$T/none.exr" $FOG --lights none
check "... the plate's fog" same "$T/none.exr" "$T/p.exr"
check "flags override the rig's sun and lights" "$FOGPIPE" -i "$T/n.0001.exr" -o "$T/o.exr" $FOG \
  --sun 0,1,0 --light point:3,1,0:1,1,1:4
check "... as on the plate" sh -c '"$1" -i "$2" -o "$3" $4 --sun 0,1,0 --light point:3,1,0:1,1,1:4 &&
  "$5" -q -fail 0 "$3" "$6"' sh "$FOGPIPE" "$P" "$T/o2.exr" "$FOG" "$IDIFF" "$T/o.exr"

# Clip start: from the rig, the flag over it.
note "$T/c.0001.exr" "$P" "fogpipe-rig 1 clip 1.5"
check "clip start from the rig" "$FOGPIPE" -i "$T/c.0001.exr" -o "$T/c.exr" $FOG
check "... changes the fog" differ "$T/c.exr" "$T/p.exr"
check "... as --clip-start" sh -c '"$1" -i "$2" -o "$3" $4 --clip-start 1.5 && "$5" -q -fail 0 "$3" "$6"' \
  sh "$FOGPIPE" "$P" "$T/c2.exr" "$FOG" "$IDIFF" "$T/c.exr"
check "--clip-start 0 over the rig's" sh -c '"$1" -i "$2" -o "$3" $4 --clip-start 0 && "$5" -q -fail 0 "$3" "$6"' \
  sh "$FOGPIPE" "$T/c.0001.exr" "$T/c0.exr" "$FOG" "$IDIFF" "$T/p.exr"
check "... OpenCL agrees with C" sh -c '"$1" -i "$2" -o "$3" --density 0.06 --height 0,6,25 --fog-color 0.2,0.2,0.25 -q &&
  "$4" -q -fail 0.002 "$3" "$5"' sh "$FOGPIPE" "$T/c.0001.exr" "$T/ccl.exr" "$IDIFF" "$T/c.exr"
check "... with a lamp and a sun (the lights' lanes, the sun's march): OpenCL agrees with C" sh -c '
  for d in --cpu ""; do "$1" -i "$2" -o "$3$d.exr" $d --density 0.06 --height 0,6,25 --fog-color 0.2,0.2,0.25 -q \
    --light point:0,2,5:10,8,6:1 --sun 0.3,1,0.2 || exit 1; done &&
  "$4" -q -fail 0.003 -failpercent 0.5 "$3--cpu.exr" "$3.exr" &&
  ! "$4" -q -fail 0 "$3.exr" "$5"' sh "$FOGPIPE" "$T/c.0001.exr" "$T/cl" "$IDIFF" "$T/c.exr"
check "... at half resolution, clip and lamp" sh -c '"$1" -i "$2" -o "$3" --density 0.06 --height 0,6,25 \
  --fog-color 0.2,0.2,0.25 -q --light point:0,2,5:10,8,6:1 --sun 0.3,1,0.2 --fog-resolution 1/2 &&
  "$4" -q -fail 0.02 -failpercent 5 -warn 0.02 -warnpercent 5 "$3" "$5"' sh "$FOGPIPE" "$T/c.0001.exr" "$T/half.exr" "$IDIFF" "$T/cl.exr"

# Typed attributes over the text; the up axis from the frame.
"$OIIOTOOL" --nosoftwareattrib "$P" --attrib Note "fogpipe-rig 1 up y clip 0.5" \
  --attrib:type=string fogpipeUp z --attrib:type=float fogpipeClipStart 0.25 \
  --attrib:type=int fogpipeRigVersion 1 -o "$T/t.0001.exr"
check "typed attributes over the text" sh -c '"$1" --print-camera -i "$2" |
  grep -q "rig       up z (rig), clip start 0.25 (rig)"' sh "$FOGPIPE" "$T/t.0001.exr"
note "$T/z.0001.exr" "$P" "fogpipe-rig 1 up z"
check "up z from the frame" "$FOGPIPE" -i "$T/z.0001.exr" -o "$T/z.exr" $FOG
check "... as --up z" sh -c '"$1" -i "$2" -o "$3" $4 --up z && "$5" -q -fail 0 "$3" "$6"' \
  sh "$FOGPIPE" "$P" "$T/z2.exr" "$FOG" "$IDIFF" "$T/z.exr"
check "... which changes the fog" differ "$T/z.exr" "$T/p.exr"
check "--up y against the frame's z: used, with one warning" sh -c '
  "$1" -i "$2" -o "$3" --cpu --density 0.06 --height 0,6,25 --fog-color 0.2,0.2,0.25 --up y \
    --progress off 2> "$4" && [ "$(grep -c "rig says up z; --up y is used" "$4")" = 1 ] &&
  "$5" -q -fail 0 "$3" "$6"' sh "$FOGPIPE" "$T/z.0001.exr" "$T/zy.exr" "$T/zy.txt" "$IDIFF" "$T/p.exr"
check "a stream keeps the run's up axis, and says so once" sh -c '
  cat "$2" "$2" | "$1" --cpu --density 0.06 --height 0,6,25 --progress off > "$3" 2> "$4" &&
  [ "$(grep -c "the rig says up z, the run.s up axis is y" "$4")" = 1 ]' sh "$FOGPIPE" "$T/z.0001.exr" \
  "$T/zs.exr" "$T/zs.txt"

# The look the frame carries, under the command line.
note "$T/l.0001.exr" "$P" "fogpipe-look 1 density=0.12 fog-color=0.5,0.2,0.1"
check "the look from the frame" "$FOGPIPE" -i "$T/l.0001.exr" -o "$T/l.exr" --cpu --height 0,6,25 -q
check "... as its options" sh -c '"$1" -i "$2" -o "$3" --cpu --height 0,6,25 -q --density 0.12 \
  --fog-color 0.5,0.2,0.1 && "$4" -q -fail 0 "$3" "$5"' sh "$FOGPIPE" "$P" "$T/l2.exr" "$IDIFF" "$T/l.exr"
check "... the command line over it" sh -c '"$1" -i "$2" -o "$3" $4 && "$5" -q -fail 0 "$3" "$6"' \
  sh "$FOGPIPE" "$T/l.0001.exr" "$T/l3.exr" "$FOG" "$IDIFF" "$T/p.exr"
"$OIIOTOOL" --nosoftwareattrib "$P" --attrib:type=string fogpipeLook "fogpipe-look 1 density=0.12 fog-color=0.5,0.2,0.1" -o "$T/lt.0001.exr"
check "... and as the typed attribute fogpipeLook" sh -c '"$1" -i "$2" -o "$3" --cpu --height 0,6,25 -q &&
  "$4" -q -fail 0 "$3" "$5"' sh "$FOGPIPE" "$T/lt.0001.exr" "$T/lt.exr" "$IDIFF" "$T/l.exr"

# The sun's shadow map beside the frame, and a map whose camera is a Note.
note "$S/m.0001.exr" "$P" "fogpipe-rig 1 shadow shadow.0001.exr $(echo "$SUN" | sed 's/fogpipe-rig 1 //')"
check "the shadow map the rig names" "$FOGPIPE" -i "$S/m.0001.exr" -o "$T/m.exr" $FOG
check "... as --shadow-map" sh -c '"$1" -i "$2" -o "$3" $4 --sun 0.3,1,0.2 --sun-color 1,1,0.75 \
  --sun-intensity 2 --shadow-map "$5" && "$6" -q -fail 0 "$3" "$7"' \
  sh "$FOGPIPE" "$P" "$T/m2.exr" "$FOG" "$S/shadow.####.exr" "$IDIFF" "$T/m.exr"
check "... which shadows the fog" sh -c '"$1" -i "$2" -o "$3" $4 --sun 0.3,1,0.2 --sun-color 1,1,0.75 \
  --sun-intensity 2 && ! "$5" -q -fail 0 "$3" "$6"' sh "$FOGPIPE" "$P" "$T/m3.exr" "$FOG" "$IDIFF" "$T/m.exr"
check "--shadow-map for the frame's sun" sh -c '"$1" -i "$2" -o "$3" $4 --shadow-map "$5" && "$6" -q -fail 0 "$3" "$7"' \
  sh "$FOGPIPE" "$S/m.0001.exr" "$T/m5.exr" "$FOG" "$S/shadow.####.exr" "$IDIFF" "$T/m.exr"
fails "--shadow-map for a frame whose rig has no sun" 1 "c.0001.exr: frame 1: --shadow-map: the shadows are the sun's; give --sun too \\(with the rig" \
  "$T/x.exr" "$FOGPIPE" -i "$T/c.0001.exr" -o "$T/x.exr" $FOG --shadow-map "$S/shadow.####.exr"
mats=$("$OIIOTOOL" --info -v "$S/shadow.0001.exr" | awk -F': ' '/worldToCamera:/ { c = $2 } /worldToNDC:/ { n = $2 }
  END { gsub(",", "", c); gsub(",", "", n); print "fogpipe-camera 1 worldToCamera " c " worldToNDC " n }')
"$OIIOTOOL" --nosoftwareattrib "$S/shadow.0001.exr" --eraseattrib "worldTo.*" --attrib Note "$mats" \
  -o "$T/noted.0001.exr"
check "a shadow map with its camera in a Note" sh -c '"$1" -i "$2" -o "$3" $4 --sun 0.3,1,0.2 \
  --sun-color 1,1,0.75 --sun-intensity 2 --shadow-map "$5" && "$6" -q -fail 0.003 -failpercent 1 "$3" "$7"' \
  sh "$FOGPIPE" "$P" "$T/m4.exr" "$FOG" "$T/noted.####.exr" "$IDIFF" "$T/m.exr"
"$OIIOTOOL" --nosoftwareattrib "$S/shadow.0001.exr" --eraseattrib "worldTo.*" -o "$T/bare.0001.exr"
fails "a shadow map without a camera" 1 "bare.0001.exr: frame 1: shadow map without a camera" \
  "$T/x.exr" "$FOGPIPE" -i "$P" -o "$T/x.exr" $FOG --sun 0,1,0 --shadow-map "$T/bare.####.exr"

# --rig FILE: the same rig, per frame, over the frame's.
cat > "$T/rig.json" <<'EOF'
{ "fogpipe_rig": 1,
  "lights": [ {"type": "sun", "direction": [0.3, 1, 0.2], "irradiance": [2, 2, 1.5], "angle": 0.5},
              {"type": "point", "position": [0, 2, 5], "intensity": [10, 8, 6], "radius": 0.1},
              {"type": "spot", "position": [1, 3, 2], "intensity": [5, 5, 5], "radius": 0.2,
               "direction": [0, -1, 0], "size": 60, "blend": 0.2} ],
  "frames": { "2": { "lights": [] } } }
EOF
check "--rig FILE" "$FOGPIPE" -i "$P" -o "$T/j.exr" $FOG --rig "$T/rig.json"
check "... as the frame's text" same "$T/j.exr" "$T/n.exr"
check "... over the frame's rig, per frame" sh -c '"$1" -i "$2" -o "$3" --frame 2 $4 --rig "$5" &&
  "$6" -q -fail 0 "$3" "$7"' sh "$FOGPIPE" "$T/n.0001.exr" "$T/j2.exr" "$FOG" "$T/rig.json" "$IDIFF" "$T/p.exr"

# Animated lights: each frame its own rig, through the pipelined loop.
mkdir -p "$T/anim"
note "$T/anim/a.0001.exr" "$S/scene.0001.exr" "fogpipe-rig 1 point 0 2 5 10 8 6 0"
note "$T/anim/a.0002.exr" "$S/scene.0002.exr" "fogpipe-rig 1 point 3 1 2 2 8 16 0"
check "a sequence with animated lights" "$FOGPIPE" -i "$T/anim/a.####.exr" -o "$T/anim/o.####.exr" \
  --density 0.06 --height 0,6,25 -q
check "... frame 2 lit by frame 2's light" sh -c '"$1" -i "$2" -o "$3" --density 0.06 --height 0,6,25 -q \
  --light point:3,1,2:2,8,16:1 && "$4" -q -fail 0 "$3" "$5"' \
  sh "$FOGPIPE" "$S/scene.0002.exr" "$T/anim/f2.exr" "$IDIFF" "$T/anim/o.0002.exr"
check "... frame 1 by frame 1's" sh -c '"$1" -i "$2" -o "$3" --density 0.06 --height 0,6,25 -q \
  --light point:0,2,5:10,8,6:1 && "$4" -q -fail 0 "$3" "$5"' \
  sh "$FOGPIPE" "$S/scene.0001.exr" "$T/anim/f1.exr" "$IDIFF" "$T/anim/o.0001.exr"

# A warning of the light stage is said once a run, not once per rig change
# (each frame commits the light again): fog without a top under the rig's sun.
note "$T/anim/w.0001.exr" "$S/scene.0001.exr" "$SUN point 0 2 5 10 8 6 0"
note "$T/anim/w.0002.exr" "$S/scene.0002.exr" "$SUN point 3 1 2 2 8 16 0"
check "a light stage warning once a run, however often the rig changes" sh -c '
  "$1" -i "$2" -o "$3" --cpu --density 0.06 --height 0,inf --progress off 2> "$4" &&
  [ "$(grep -c "has no top" "$4")" = 1 ] || { cat "$4"; exit 1; }' \
  sh "$FOGPIPE" "$T/anim/w.####.exr" "$T/anim/w.o.####.exr" "$T/anim/w.log"

# A single file's frame number: from its name, --frame over it.
cp "$P" "$T/shot.0002.exr"
check "a single file's frame number from its name" sh -c '"$1" --print-camera -i "$2" | grep -q "shot.0002.exr: frame 2: camera"' \
  sh "$FOGPIPE" "$T/shot.0002.exr"
check "... --frame over it" sh -c '"$1" --print-camera -i "$2" --frame 7 | grep -q "shot.0002.exr: frame 7: camera"' \
  sh "$FOGPIPE" "$T/shot.0002.exr"
check "... the animated fog of that frame" sh -c '
  "$1" -i "$2" -o "$3" --cpu --density 0.1 --height 0,3 --fogmap "$4" --fog-rect -20,-10,20,30 --wind 3,0 -q &&
  "$1" -i "$5" -o "$6" --cpu --density 0.1 --height 0,3 --fogmap "$4" --fog-rect -20,-10,20,30 --wind 3,0 -q --frames 2 &&
  "$7" -q -fail 0 "$3" "$8"' sh "$FOGPIPE" "$T/shot.0002.exr" "$T/s2.exr" "$FP_SAMPLES/fogmap.exr" \
  "$T/shot.####.exr" "$T/sq.####.exr" "$IDIFF" "$T/sq.0002.exr"
fails "--frame with a sequence" 2 "--frame 3: only for a single input file" "$T/x.####.exr" \
  "$FOGPIPE" -i "$S/scene.####.exr" -o "$T/x.####.exr" --frame 3

# Bad rigs: one line naming the file, the frame and the attribute.
note "$T/bad.0001.exr" "$P" "fogpipe-rig 1 spot 0 0 0 1 1 1 0 0 -1 0 400 0.2"
fails "a bad light in the Note" 1 "bad.0001.exr: frame 1: attribute 'Note': light 1 \\(spot\\): the spot's SIZE" \
  "$T/x.exr" "$FOGPIPE" -i "$T/bad.0001.exr" -o "$T/x.exr" $FOG
note "$T/cut.0001.exr" "$P" "fogpipe-rig 1 lights 12 $PT $PT point 1 2"
fails "a cut-off Note without fogpipeRig" 1 "cut.0001.exr: frame 1: the rig says 12 lights but carries 2 and there is no fogpipeRig attribute" \
  "$T/x.exr" "$FOGPIPE" -i "$T/cut.0001.exr" -o "$T/x.exr" $FOG
"$OIIOTOOL" --nosoftwareattrib "$P" --attrib:type=int fogpipeClipStart 3 -o "$T/ty.0001.exr"
fails "a typed attribute of the wrong type" 1 "ty.0001.exr: frame 1: attribute 'fogpipeClipStart' is of type int \\(expected float\\)" \
  "$T/x.exr" "$FOGPIPE" -i "$T/ty.0001.exr" -o "$T/x.exr" $FOG
echo '{"fogpipe_rig": 1, "lights": [{"type": "point", "position": [0, 0]}]}' > "$T/bad.json"
fails "a bad rig file" 2 "bad.json:1: light 1 \\(point\\): unknown key|bad.json:1: light 1 \\(point\\): \"position\"" \
  "$T/x.exr" "$FOGPIPE" -i "$P" -o "$T/x.exr" $FOG --rig "$T/bad.json"
note "$T/lk.0001.exr" "$P" "fogpipe-look 1 output=/tmp/elsewhere.exr"
fails "a look that is not a look" 2 "lk.0001.exr: frame 1: attribute 'Note': look: --output is not part of a fog look" \
  "$T/x.exr" "$FOGPIPE" -i "$T/lk.0001.exr" -o "$T/x.exr" $FOG
finish
