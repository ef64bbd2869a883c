# tests/blender_addon.sh: copies every frame Blender writes into DIR before
# the add-on's render_write handler rewrites its header (so that the file
# as Blender wrote it can be compared with the rewritten one).
#   blender -b scene.blend -P fogpipe_blender/__init__.py -P keep_written.py -f 1 -- DIR
import os
import shutil
import sys

import bpy
from bpy.app.handlers import persistent

outdir = sys.argv[sys.argv.index("--") + 1]
os.makedirs(outdir, exist_ok=True)


@persistent
def keep_written(scene, *args):
    path = bpy.path.abspath(scene.render.frame_path(frame=scene.frame_current))
    shutil.copyfile(path, os.path.join(outdir, os.path.basename(path)))


bpy.app.handlers.render_write.insert(0, keep_written)
