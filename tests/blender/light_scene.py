# tests/blender_light.sh: Cycles renders lit fog (single scattering) for
# fogpipe to match.
#   blender -b --factory-startup -noaudio -P fogpipe_blender/__init__.py -P tests/blender/light_truth.py \
#     -P tests/blender/light_scene.py -- OUTDIR SAMPLES PROFILE [map=768] [clip=1e-4] \
#     [lights=sun,point,spot] [last=3] [shadow=PATH] [lamps=behind] [addonmap=1]
# lamps=behind (tests/blender_lamps.sh): the point light behind the
# thickest pillar and the spot behind the wall, shining through its slit
# at x = 1 toward the camera: the shadow volumes of the pillar and the
# wall in view.
# addonmap=1: the sun's maps are the add-on's own (its Render Sun Shadow
# Maps operator, shadow_maps_for as `-- --fogpipe-shadow-maps`: fitted to
# the fog the camera sees, per frame, OUTDIR/fogpipe/sun.####.exr),
# recorded in every frame's rig; the script's sunmap.0001.exr is rendered
# as well (its known texels).
# shadow=PATH: the plate's rig names PATH (from OUTDIR; e.g. the script's
# own map, sunmap.0001.exr) as the sun's shadow map of every frame (the
# add-on's static map setting), so fogpipe finds it with no flag.
# The scene (Z up, meters): a ground (z = 0), a wall 4 m high along x at
# y = 5 with four vertical slits 0.5 m wide, three thin pillars (0.25 and
# 0.35 m square, 3.5 m high) in the slits' shafts, a low sun behind the
# wall (16 degrees up, shining at the camera through the slits: hard,
# angle 0), a point light between the camera and the pillars, a spot
# (20 degrees, blend 0.15) lighting the ground beside them, and a camera
# that moves, turns and zooms over frames 1-3 (128 x 72 px, clip start
# CLIP).  The fog is a box of volume, x and y in [-9, 9], z in [-0.05, 5]:
# extinction SIGMA (per meter), albedo ALBEDO (Volume Scatter of density
# ALBEDO SIGMA, white, anisotropy G, plus Volume Absorption of density
# (1 - ALBEDO) SIGMA, black), with PROFILE "height" times fogpipe's
# --height Y0,H profile (1 below Y0, exp(-(z - Y0)/H) above it) of the
# shading point's z ("homog": homogeneous).  Every surface is purely
# emissive (known colors: the plate is exact and noiseless); the world is
# black.  Cycles renders, with the add-on (-P fogpipe_blender/__init__.py: the
# camera and the rig, the lights, up axis and clip start, in every frame's
# header):
#   OUTDIR/plate.####.exr   frames 1-3, no fog, 1 sample: the plate
#                           (MultiLayer, Z pass);
#   OUTDIR/trans.####.exr   the plate through the fog: absorption SIGMA
#                           alone, no lights, 1 sample (exact, as
#                           tests/blender/absorb.py);
#   OUTDIR/fogA.####.exr    the fog's in-scattered light: the surfaces
#                           black (still casting shadows), SAMPLES
#                           samples, seed 1;
#   OUTDIR/fogB.####.exr    the same with seed 2: the two give the noise;
#   OUTDIR/sunmap.0001.exr  the sun's depth map: an orthographic camera
#                           along the sun over the whole box, MAPSIZE
#                           texels square, single-layer with Z, its
#                           camera in the Note;
#   OUTDIR/scene.txt        the medium: "sigma S albedo A g G height Y0 H
#                           box X0 Y0 Z0 X1 Y1 Z1" (fogpipe's options).
# Cycles' own fog of the plate is trans + fogA (or fogB): light adds up.
# tests/blender/light_truth.py, loaded before, writes the lights and the
# known points of every frame as Blender has them.
# The pixel filter is 0.01 px wide: every sample goes through the pixel's
# center, as the depth pass and fogpipe's ray.  What it takes for Cycles
# to render fogpipe's model (each measured):
#   - transparent bounces: shadow rays cross the box's faces as
#     transparent bounces; with none allowed the box blocks the sun;
#   - the box's floor below the ground's plane: coincident faces hide the
#     ground from some rays (black pixels of the plate through the fog);
#   - the surfaces black while the fog is lit: emitting, they light the
#     fog (a quarter of its light here), even with volume bounces 0, no
#     sample-as-light and no volume-scatter visibility; emitting toward
#     camera rays only (Light Path) leaves the plate through the fog 20%
#     short;
#   - the local lights cast shadows: with Cast Shadow off Cycles also
#     skips the fog between the light and the point (31% more light from
#     the point than fogpipe's); fogpipe shadows its local lights by the
#     geometry the depth buffer shows (--lamp-shadows screen), so by
#     default the point stands where what the pillars shadow from it is
#     mostly hidden from the camera and no geometry is in the spot's cone,
#     and lamps=behind puts both behind casters the camera sees.
import math
import os
import sys

import bpy
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
from common import black_world, cycles_cpu, keyed_camera  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:]
outdir, samples, profile = argv[0], int(argv[1]), argv[2]
opt = dict(a.split("=", 1) for a in argv[3:])
mapsize = int(opt.get("map", 768))
# Exploring: only these lights (comma-separated names), the last frame.
only = opt["lights"].split(",") if "lights" in opt else None
last_frame = int(opt.get("last", 3))
# The camera's clip start: Cycles' fog begins there.
CLIP = float(opt.get("clip", 1e-4))
os.makedirs(outdir, exist_ok=True)

SIGMA, ALBEDO, G = 0.12, 0.9, 0.3
Y0, H = (0.5, 2.5) if profile == "height" else (0.0, math.inf)
# Its floor a little below the ground's: a volume face on the ground's
# plane hides it from some rays (black pixels).
BOX = (-9.0, -9.0, -0.05, 9.0, 9.0, 5.0)
WIDTH, HEIGHT = 128, 72

for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)
scene = bpy.context.scene


def emissive(name, color):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    em = nt.nodes.new('ShaderNodeEmission')
    em.inputs['Color'].default_value = color + (1.0,)
    em.inputs['Strength'].default_value = 1.0
    out = nt.nodes.new('ShaderNodeOutputMaterial')
    nt.links.new(em.outputs['Emission'], out.inputs['Surface'])
    m.cycles.sample_as_light = False
    return m


def block(name, x0, y0, z0, x1, y1, z1, mat):
    bpy.ops.mesh.primitive_cube_add(size=1, location=((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    o = bpy.context.active_object
    o.name = name
    o.scale = (x1 - x0, y1 - y0, z1 - z0)
    o.data.materials.append(mat)
    return o


bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 0, 0))
ground = bpy.context.active_object
ground.name = "ground"
ground_mat = emissive("ground", (0.10, 0.08, 0.06))
ground.data.materials.append(ground_mat)
wall_mat = emissive("wall", (0.15, 0.12, 0.10))
# The wall: x from -8 to 8 with slits 0.5 m wide centered at these x.
SLITS = (-4.0, -1.5, 1.0, 3.5)
x = -8.0
for i, s in enumerate(SLITS + (8.25,)):
    block("wall%d" % i, x, 4.8, 0.0, s - 0.25, 5.2, 4.0, wall_mat)
    x = s + 0.25
pillar_mat = emissive("pillar", (0.20, 0.20, 0.25))
# In the shafts of three slits (a shaft from the slit at x = S is at
# x = S - (5 - y)/4 at y), a little off their middles.
PILLARS = ((-2.15, 2.0, 0.35), (0.05, 1.5, 0.25), (2.8, 2.6, 0.35))
for i, (px, py, w) in enumerate(PILLARS):
    block("pillar%d" % i, px - w / 2, py - w / 2, 0.0, px + w / 2, py + w / 2, 3.5, pillar_mat)

# The sun: toward it (0.25, 1, 0.3), so its light runs to -y through the
# slits, 16 degrees up; a hard sun (angle 0).
TOWARD_SUN = Vector((0.25, 1.0, 0.3)).normalized()
sun_data = bpy.data.lights.new("sun", 'SUN')
sun_data.energy = 4.0
sun_data.color = (1.0, 0.9, 0.75)
sun_data.angle = 0.0
sun = bpy.data.objects.new("sun", sun_data)
sun.rotation_euler = (-TOWARD_SUN).to_track_quat('-Z', 'Y').to_euler()
point_data = bpy.data.lights.new("point", 'POINT')
point_data.energy = 40.0
point_data.color = (1.0, 0.7, 0.4)
point_data.shadow_soft_size = 0.0
point = bpy.data.objects.new("point", point_data)
point.location = (-1.5, -3.5, 1.0)
spot_data = bpy.data.lights.new("spot", 'SPOT')
spot_data.energy = 150.0
spot_data.color = (0.5, 0.7, 1.0)
spot_data.shadow_soft_size = 0.0
spot_data.spot_size = math.radians(20.0)
spot_data.spot_blend = 0.15
spot = bpy.data.objects.new("spot", spot_data)
spot.location = (2.0, -0.5, 3.6)
spot.rotation_euler = (Vector((2.4, 1.2, 0.0)) - spot.location).to_track_quat('-Z', 'Y').to_euler()
if opt.get("lamps") == "behind":
    point.location = (-2.1, 3.4, 1.8)
    spot.location = (1.0, 7.0, 2.2)
    spot_data.spot_size = math.radians(50.0)
    spot.rotation_euler = (Vector((1.0, -7.0, 1.2)) - spot.location).to_track_quat(
        '-Z', 'Y').to_euler()
for o in (sun, point, spot):
    scene.collection.objects.link(o)
    o.hide_render = only is not None and o.name not in only
    o.data.cycles.max_bounces = 1024

# The fog box.
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
scatter.inputs['Anisotropy'].default_value = G
absorb = nt.nodes.new('ShaderNodeVolumeAbsorption')
absorb.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
add = nt.nodes.new('ShaderNodeAddShader')
nt.links.new(scatter.outputs[0], add.inputs[0])
nt.links.new(absorb.outputs[0], add.inputs[1])
nt.links.new(add.outputs[0], out.inputs['Volume'])
if profile == "height":
    # h(z) = exp(-max(z - Y0, 0) / H), fogpipe's --height Y0,H.
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
    nt.links.new(math_node('MULTIPLY', h, ALBEDO * SIGMA), scatter.inputs['Density'])
    nt.links.new(math_node('MULTIPLY', h, (1 - ALBEDO) * SIGMA), absorb.inputs['Density'])
    fm.cycles.homogeneous_volume = False
    # Ray marching: steps of 0.1 x the box's mean size x the rate = 41 cm
    # (rate 0.05, 6.8 cm steps, renders 6 times slower for the same
    # figures): each step's optical depth is at most 0.05, and the
    # density changes by 15% across it, so Cycles' estimate of a step's
    # transmittance from one point in it is off by 1e-5 on average.
    fm.cycles.volume_step_rate = 0.3
else:
    scatter.inputs['Density'].default_value = ALBEDO * SIGMA
    absorb.inputs['Density'].default_value = (1 - ALBEDO) * SIGMA
    fm.cycles.homogeneous_volume = True
fog.data.materials.append(fm)

black_world(scene)
KEYS = [((0.0, -7.0, 1.7), (0.0, 3.0, 1.8), 24.0),
        ((1.5, -6.5, 1.4), (0.5, 3.0, 2.1), 28.0),
        ((-1.4, -7.6, 2.1), (-0.5, 3.0, 1.4), 22.0)]
cam = keyed_camera(scene, KEYS, CLIP)

r = scene.render
c = cycles_cpu(scene, WIDTH, HEIGHT)
c.max_bounces = 0
c.volume_bounces = 0
c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 0
# Shadow rays cross the fog box's faces as transparent bounces: with none
# allowed, the box would block the sun.
c.transparent_max_bounces = 8
scene.frame_start, scene.frame_end = 1, 3

with open(os.path.join(outdir, "scene.txt"), "w") as f:
    f.write("sigma %.9g albedo %.9g g %.9g height %.9g %s box %s\n"
            % (SIGMA, ALBEDO, G, Y0, "inf" if math.isinf(H) else "%.9g" % H,
               " ".join("%.9g" % v for v in BOX)))


def render(name, first=1, last=last_frame, fmt='OPEN_EXR'):
    common.render(scene, outdir, name, first, last, fmt)


def surfaces(strength):
    for m in (ground_mat, wall_mat, pillar_mat):
        m.node_tree.nodes["Emission"].inputs['Strength'].default_value = strength


# The plate: no fog, one sample (emission only: exact).
fog.hide_render = True
c.samples = 1
if "shadow" in opt:
    fs = scene.fogpipe
    fs.shadow_maps, fs.shadow_static, fs.shadow_path = True, True, opt["shadow"]
if opt.get("addonmap") == "1":
    # The add-on's maps over the fog the camera sees (to 22 m: the box's
    # far corner), texel = its default thinnest caster / 8.
    r.filepath = os.path.join(outdir, "plate.####")
    fs = scene.fogpipe
    fs.shadow_static, fs.shadow_path, fs.shadow_distance = False, "fogpipe/sun.####.exr", 22.0
    if bpy.ops.fogpipe.shadow_maps(frames="1-%d" % last_frame) != {'FINISHED'}:
        sys.exit("fogpipe: the add-on rendered no shadow map")
render("plate", fmt='OPEN_EXR_MULTILAYER')
if "shadow" in opt or opt.get("addonmap") == "1":
    scene.fogpipe.shadow_maps = False
# Cycles' fog in two parts that add up to it (light is additive): the
# plate seen through the fog, and the fog's in-scattered light.
# The plate through the fog: absorption only (SIGMA, black), no light,
# one sample: exact (tests/blender/absorb.py).
fog.hide_render = False
lights_on = [o for o in (sun, point, spot) if not o.hide_render]
for o in lights_on:
    o.hide_render = True
nt.links.remove(add.outputs[0].links[0])
plain = nt.nodes.new('ShaderNodeVolumeAbsorption')
plain.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
plain.inputs['Density'].default_value = SIGMA
if profile == "height":
    nt.links.new(math_node('MULTIPLY', h, SIGMA), plain.inputs['Density'])
nt.links.new(plain.outputs[0], out.inputs['Volume'])
render("trans")
# The in-scattered light, twice (seeds 1, 2): the surfaces black (they
# still cast shadows; emitting, they would light the fog, which fogpipe's
# do not, and Cycles lights the fog with them even with volume bounces 0,
# no sample-as-light and no volume-scatter visibility; emitting toward
# camera rays only, through Light Path, their light through the fog comes
# out 20% short).
nt.links.new(add.outputs[0], out.inputs['Volume'])
for o in lights_on:
    o.hide_render = False
surfaces(0.0)
c.samples = samples
for name, seed in (("fogA", 1), ("fogB", 2)):
    c.seed = seed
    render(name)
surfaces(1.0)

# The sun's depth map: an orthographic camera looking along the sunlight,
# square, over the box's eight corners.
fog.hide_render = True
sd = bpy.data.cameras.new("suncam")
sd.type = 'ORTHO'
sd.clip_start = 0.01
sd.clip_end = 200.0
suncam = bpy.data.objects.new("suncam", sd)
scene.collection.objects.link(suncam)
center = Vector(((BOX[0] + BOX[3]) / 2, (BOX[1] + BOX[4]) / 2, (BOX[2] + BOX[5]) / 2))
rot = (-TOWARD_SUN).to_track_quat('-Z', 'Y')
suncam.matrix_world = Matrix.Translation(center + TOWARD_SUN * 60.0) @ rot.to_matrix().to_4x4()
inv = rot.to_matrix().inverted()
ext = 0.0
for i in range(8):
    p = Vector((BOX[3 if i & 1 else 0], BOX[4 if i & 2 else 1], BOX[5 if i & 4 else 2])) - center
    q = inv @ p
    ext = max(ext, abs(q.x), abs(q.y))
sd.ortho_scale = 2 * ext
scene.camera = suncam
r.resolution_x = r.resolution_y = mapsize
c.samples = 1
r.image_settings.file_format = 'OPEN_EXR'
r.image_settings.use_zbuffer = True
render("sunmap", 1, 1)
