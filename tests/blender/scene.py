# Builds the scenes of tests/blender.sh and saves them as a .blend:
#   blender -b --factory-startup -noaudio -P tests/blender/scene.py -- OUT.blend OUTDIR
# One scene per camera kind, each with a ground plane (z = 0, 40 x 40) and a
# box (2 x 2 x 2 on the ground at the origin, corners at x, y = +-1, z = 0, 2)
# seen by a camera that moves, turns, rolls, zooms and shifts over frames 1-3:
#   auto        64x48, sensor fit AUTO (36 x 24 mm), multilayer EXR
#   vertical    64x48, sensor fit VERTICAL (sensor height 20 mm), multilayer
#   horizontal  48x64 (portrait), sensor fit HORIZONTAL (width 30 mm), single-layer EXR with Z
#   ortho       64x48, orthographic, multilayer
# Cycles on the CPU, 1 sample, pixel filter 0.01 px wide (so that the depth
# pass is the depth at each pixel's center), 32-bit float EXR.
import math
import sys

import bpy
from mathutils import Matrix, Vector

argv = sys.argv[sys.argv.index("--") + 1:]
blend_path, outdir = argv[0], argv[1]

for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)

geo = bpy.data.collections.new("geometry")
bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 0, 0))
ground = bpy.context.active_object
bpy.ops.mesh.primitive_cube_add(size=2, location=(0, 0, 1))
box = bpy.context.active_object
sun_data = bpy.data.lights.new("sun", 'SUN')
sun_data.energy = 3
sun = bpy.data.objects.new("sun", sun_data)
sun.rotation_euler = (0.6, 0.2, 0.8)
for o in (ground, box):
    for c in list(o.users_collection):
        c.objects.unlink(o)
for o in (ground, box, sun):
    geo.objects.link(o)

VARIANTS = [
    # name, width, height, sensor fit, sensor (w, h), type, file format
    ("auto", 64, 48, 'AUTO', (36.0, 24.0), 'PERSP', 'OPEN_EXR_MULTILAYER'),
    ("vertical", 64, 48, 'VERTICAL', (36.0, 20.0), 'PERSP', 'OPEN_EXR_MULTILAYER'),
    ("horizontal", 48, 64, 'HORIZONTAL', (30.0, 24.0), 'PERSP', 'OPEN_EXR'),
    ("ortho", 64, 48, 'AUTO', (36.0, 24.0), 'ORTHO', 'OPEN_EXR_MULTILAYER'),
]
# Per frame: camera position, point looked at, roll (deg), lens (mm),
# orthographic scale, shift x, shift y.
KEYS = [
    ((5.0, -6.0, 4.0), (0.0, 0.0, 0.5), 0.0, 30.0, 12.0, 0.0, 0.05),
    ((6.0, -4.0, 3.5), (0.5, 0.5, 0.8), 8.0, 35.0, 10.0, 0.1, 0.0),
    ((3.5, -5.5, 5.0), (-0.5, 0.0, 0.0), -12.0, 24.0, 14.0, -0.15, -0.1),
]

first = bpy.context.scene
for i, (name, w, h, fit, sensor, kind, fmt) in enumerate(VARIANTS):
    sc = first if i == 0 else bpy.data.scenes.new(name)
    sc.name = name
    sc.collection.children.link(geo)
    world = bpy.data.worlds.new("world_" + name)
    world.color = (0.05, 0.07, 0.1)
    sc.world = world
    cd = bpy.data.cameras.new("cam_" + name)
    cd.type = kind
    cd.sensor_fit = fit
    cd.sensor_width, cd.sensor_height = sensor
    cam = bpy.data.objects.new("cam_" + name, cd)
    sc.collection.objects.link(cam)
    sc.camera = cam
    for f, (loc, target, roll, lens, oscale, sx, sy) in enumerate(KEYS, start=1):
        cam.location = loc
        look = (Vector(target) - Vector(loc)).to_track_quat('-Z', 'Y').to_matrix()
        cam.rotation_euler = (look @ Matrix.Rotation(math.radians(roll), 3, 'Z')).to_euler('XYZ')
        cd.lens, cd.ortho_scale, cd.shift_x, cd.shift_y = lens, oscale, sx, sy
        cam.keyframe_insert("location", frame=f)
        cam.keyframe_insert("rotation_euler", frame=f)
        for prop in ("lens", "ortho_scale", "shift_x", "shift_y"):
            cd.keyframe_insert(prop, frame=f)
    r = sc.render
    r.engine = 'CYCLES'
    sc.cycles.device = 'CPU'
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False
    sc.cycles.filter_width = 0.01
    r.threads_mode = 'FIXED'
    r.threads = 2
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    sc.frame_start, sc.frame_end = 1, 3
    r.image_settings.file_format = fmt
    r.image_settings.color_depth = '32'
    if fmt == 'OPEN_EXR':
        r.image_settings.use_zbuffer = True
    sc.view_layers[0].use_pass_z = True
    r.filepath = "%s/%s/render.####" % (outdir, name)
    # The user's own note: kept in front of the camera by the add-on.
    r.stamp_note_text = "shot %s" % name

bpy.ops.wm.save_as_mainfile(filepath=blend_path)
