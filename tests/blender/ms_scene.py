# Issue 28: Cycles' multiple scattering for fogpipe's Monte Carlo reference
# to match (doc/notes/multiple-scattering.md).
#   blender -b --factory-startup -noaudio -P samples/blender/fogpipe_blender/__init__.py \
#     -P tests/blender/ms_scene.py -- OUTDIR SAMPLES [sigma=0.025] [bounces=32]
#     [occluder=0|1] [profile=height|homog] [seeds=1,2] [frames=1] [floor=-0.05]
# The scene (Z up, meters): a black ground (z = 0), optionally a black wall
# (4 m high, 0.4 m thick, along x at y = 5, four slits 0.5 m wide) with
# three black pillars in the slits' shafts (tests/blender/light_scene.py's
# geometry), a hard sun 18 degrees up of irradiance 3 (white) shining
# toward the camera through the slits, a camera at 96 x 54 px.  The fog:
# a box x, y in [-20, 20], z in [FLOOR, 8], scatter only (albedo 1,
# isotropic), extinction SIGMA times fogpipe's --height 0.5,2.5 profile
# (profile=height) or constant (homog).  Every surface is black (no BSDF,
# no emission: a path that meets one ends there).  The world is black.
# Cycles renders, with the add-on (the rig in every frame's header):
#   OUTDIR/plate.####.exr   no fog, 1 sample: black, the rig (sun, camera,
#                           up, clip start 0.1 m, the sun's map);
#   OUTDIR/ms{seed}.####.exr  the fog: volume_bounces BOUNCES, SAMPLES
#                           samples, MultiLayer with the VolumeDir pass
#                           (single scattering) and VolumeInd (the rest);
#   OUTDIR/sunmap.0001.exr  the sun's depth map (orthographic, over the box);
#   OUTDIR/scene.txt        fogpipe's medium options.
import math
import os
import sys

import bpy
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
from common import black_world, cycles_cpu, keyed_camera  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:]
outdir, samples = argv[0], int(argv[1])
opt = dict(a.split("=", 1) for a in argv[2:])
SIGMA = float(opt.get("sigma", 0.025))
BOUNCES = int(opt.get("bounces", 32))
OCCLUDER = opt.get("occluder", "0") == "1"
PROFILE = opt.get("profile", "height")
SEEDS = [int(s) for s in opt.get("seeds", "1,2").split(",")]
LAST = int(opt.get("frames", 1))
FLOOR = float(opt.get("floor", -0.05))
Y0, H = (0.5, 2.5) if PROFILE == "height" else (0.0, math.inf)
BOX = (-20.0, -20.0, FLOOR, 20.0, 20.0, 8.0)
WIDTH, HEIGHT = 96, 54
MAPSIZE = 512
os.makedirs(outdir, exist_ok=True)

for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)
scene = bpy.context.scene

black = bpy.data.materials.new("black")
black.use_nodes = True
black.node_tree.nodes.clear()
bout = black.node_tree.nodes.new('ShaderNodeOutputMaterial')
em = black.node_tree.nodes.new('ShaderNodeEmission')
em.inputs['Strength'].default_value = 0.0
black.node_tree.links.new(em.outputs[0], bout.inputs['Surface'])


def block(name, x0, y0, z0, x1, y1, z1):
    bpy.ops.mesh.primitive_cube_add(size=1, location=((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    o = bpy.context.active_object
    o.name = name
    o.scale = (x1 - x0, y1 - y0, z1 - z0)
    o.data.materials.append(black)
    return o


bpy.ops.mesh.primitive_plane_add(size=60, location=(0, 0, 0))
ground = bpy.context.active_object
ground.name = "ground"
ground.data.materials.append(black)
if OCCLUDER:
    SLITS = (-4.0, -1.5, 1.0, 3.5)
    x = -8.0
    for i, s in enumerate(SLITS + (8.25,)):
        block("wall%d" % i, x, 4.8, 0.0, s - 0.25, 5.2, 4.0)
        x = s + 0.25
    for i, (px, py, w) in enumerate(((-2.15, 2.0, 0.35), (0.05, 1.5, 0.25), (2.8, 2.6, 0.35))):
        block("pillar%d" % i, px - w / 2, py - w / 2, 0.0, px + w / 2, py + w / 2, 3.5)

EL = math.radians(18.0)
hz = Vector((0.25, 1.0, 0.0)).normalized()
TOWARD_SUN = Vector((hz.x * math.cos(EL), hz.y * math.cos(EL), math.sin(EL)))
sun_data = bpy.data.lights.new("sun", 'SUN')
sun_data.energy = 3.0
sun_data.angle = 0.0
sun = bpy.data.objects.new("sun", sun_data)
sun.rotation_euler = (-TOWARD_SUN).to_track_quat('-Z', 'Y').to_euler()
sun_data.cycles.max_bounces = 1024
scene.collection.objects.link(sun)

bpy.ops.mesh.primitive_cube_add(size=1, location=((BOX[0] + BOX[3]) / 2, (BOX[1] + BOX[4]) / 2,
                                                  (BOX[2] + BOX[5]) / 2))
fog = bpy.context.active_object
fog.name = "fog"
fog.scale = (BOX[3] - BOX[0], BOX[4] - BOX[1], BOX[5] - BOX[2])
fm = bpy.data.materials.new("fog")
fm.use_nodes = True
nt = fm.node_tree
nt.nodes.clear()
out = nt.nodes.new('ShaderNodeOutputMaterial')
scatter = nt.nodes.new('ShaderNodeVolumeScatter')
scatter.inputs['Color'].default_value = (1.0, 1.0, 1.0, 1.0)
scatter.inputs['Anisotropy'].default_value = 0.0
nt.links.new(scatter.outputs[0], out.inputs['Volume'])
if PROFILE == "height":
    geo = nt.nodes.new('ShaderNodeNewGeometry')
    sep = nt.nodes.new('ShaderNodeSeparateXYZ')
    nt.links.new(geo.outputs['Position'], sep.inputs[0])

    def math_node(op, a, b=None):
        n = nt.nodes.new('ShaderNodeMath')
        n.operation = op
        for i, v in enumerate((a, b)):
            if v is None:
                continue
            if isinstance(v, float):
                n.inputs[i].default_value = v
            else:
                nt.links.new(v, n.inputs[i])
        return n.outputs[0]

    up = math_node('MAXIMUM', math_node('SUBTRACT', sep.outputs['Z'], Y0), 0.0)
    h = math_node('EXPONENT', math_node('MULTIPLY', up, -1.0 / H))
    nt.links.new(math_node('MULTIPLY', h, SIGMA), scatter.inputs['Density'])
    fm.cycles.homogeneous_volume = False
    fm.cycles.volume_step_rate = float(opt.get("step", 0.3))
else:
    scatter.inputs['Density'].default_value = SIGMA
    fm.cycles.homogeneous_volume = True
fog.data.materials.append(fm)

black_world(scene)
KEYS = [((0.0, -7.0, 1.7), (0.0, 3.0, 1.8), 24.0),
        ((1.5, -12.0, 1.4), (0.5, 3.0, 2.6), 20.0),
        ((-1.4, -5.6, 2.1), (-0.5, 3.0, 0.6), 22.0)]
cam = keyed_camera(scene, KEYS, 0.1)

r = scene.render
c = cycles_cpu(scene, WIDTH, HEIGHT, int(opt.get("threads", 2)))
c.max_bounces = 1024
c.volume_bounces = BOUNCES
c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 0
c.transparent_max_bounces = 64
vl = scene.view_layers[0]
vl.cycles.use_pass_volume_direct = True
vl.cycles.use_pass_volume_indirect = True

with open(os.path.join(outdir, "scene.txt"), "w") as f:
    f.write("--density %.9g --albedo 1 --phase iso %s --fog-box %s --fog-color 0,0,0\n"
            % (SIGMA, "--height %g,%g" % (Y0, H) if PROFILE == "height" else "--height 0,inf",
               ",".join("%.9g" % v for v in BOX)))


def render(name, first=1, last=LAST, fmt='OPEN_EXR_MULTILAYER'):
    common.render(scene, outdir, name, first, last, fmt)


fog.hide_render = True
c.samples = 1
fs = scene.fogpipe
fs.shadow_maps, fs.shadow_static, fs.shadow_path = True, True, "sunmap.0001.exr"
render("plate")
fs.shadow_maps = False
fog.hide_render = False
c.samples = samples
for seed in SEEDS:
    c.seed = seed
    render("ms%d" % seed)

fog.hide_render = True
sd = bpy.data.cameras.new("suncam")
sd.type = 'ORTHO'
sd.clip_start = 0.01
sd.clip_end = 300.0
suncam = bpy.data.objects.new("suncam", sd)
scene.collection.objects.link(suncam)
center = Vector(((BOX[0] + BOX[3]) / 2, (BOX[1] + BOX[4]) / 2, (BOX[2] + BOX[5]) / 2))
rot = (-TOWARD_SUN).to_track_quat('-Z', 'Y')
suncam.matrix_world = Matrix.Translation(center + TOWARD_SUN * 100.0) @ rot.to_matrix().to_4x4()
inv = rot.to_matrix().inverted()
ext = 0.0
for i in range(8):
    p = Vector((BOX[3 if i & 1 else 0], BOX[4 if i & 2 else 1], BOX[5 if i & 4 else 2])) - center
    q = inv @ p
    ext = max(ext, abs(q.x), abs(q.y))
sd.ortho_scale = 2 * ext
scene.camera = suncam
r.resolution_x = r.resolution_y = MAPSIZE
c.samples = 1
r.image_settings.use_zbuffer = True
render("sunmap", 1, 1, fmt='OPEN_EXR')
