# tests/blender.sh: Blender's own .chan exporter (io_anim_nuke_chan, its
# defaults: 'Make Y up', rotation order XYZ, angle_y) on the "auto" scene's
# camera with its lens shift removed (a .chan has no shift), and Blender's
# camera at frames 1-3 through tests/blender/truth.py:
#   blender -b scene.blend -S auto -P tests/blender/truth.py -P tests/blender/chan.py -- OUTDIR
# writes OUTDIR/auto.chan and OUTDIR/auto/truth.FRAME.txt.
import os
import sys

import bpy

outdir = sys.argv[sys.argv.index("--") + 1]
scene = bpy.context.scene
cam = scene.camera
action = cam.data.animation_data.action
for fc in [fc for fc in action.fcurves if fc.data_path.startswith("shift")]:
    action.fcurves.remove(fc)
cam.data.shift_x = cam.data.shift_y = 0.0
bpy.ops.preferences.addon_enable(module="io_anim_nuke_chan")
bpy.context.view_layer.objects.active = cam
os.makedirs(outdir, exist_ok=True)
bpy.ops.export.export_chan(filepath=os.path.join(outdir, scene.name + ".chan"))
for f in range(scene.frame_start, scene.frame_end + 1):
    scene.frame_set(f)
