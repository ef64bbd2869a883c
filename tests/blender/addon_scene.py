# Builds the scenes of tests/blender_addon.sh (run with the add-on):
#   blender -b --factory-startup -noaudio -P fogpipe_blender/__init__.py -P addon_scene.py -- OUT.blend OUTDIR
# and writes OUTDIR/truth-<scene>.txt: the rig each frame must carry,
# computed here from how the lights were placed (not from their matrices):
#   F sun DX DY DZ R G B ANGLE | F point X Y Z R G B RADIUS | F spot ... | F area ...
# Scenes (ground 40 x 40 at z = 0, a 2 m box, a wall with a slit; Cycles, 1
# sample, 48x32, multilayer float EXR with Z; the add-on's look set):
#   lights  frames 1-2: a sun, a point light moving, a spot, a scaled
#           rectangle area light, an ellipse area light, a lamp hidden from
#           the render (not in the rig) and a portal (not in the rig)
#   many    frame 1: 40 point lamps (more than the Note holds)
#   noz     frame 1: PNG output, no Z pass (the check names both settings)
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
bpy.ops.mesh.primitive_cube_add(size=1, location=(-4, 3, 2))
wall = bpy.context.active_object
wall.scale = (4, 0.2, 2)
for o in (ground, box, wall):
    for c in list(o.users_collection):
        c.objects.unlink(o)
    geo.objects.link(o)

FOUR_PI = 4 * math.pi
truth = {}


def g(x):
    return "%.9g" % x


def aim(ob, direction, axis):
    """Turn `ob` so that its local `axis` ('Z' or '-Z') points along direction."""
    ob.rotation_euler = Vector(direction).to_track_quat(axis, 'Y').to_euler()


def lamp(sc, name, kind, color, energy, loc=(0, 0, 0), hide=False):
    d = bpy.data.lights.new(name, kind)
    d.color, d.energy = color, energy
    ob = bpy.data.objects.new(name, d)
    ob.location = loc
    ob.hide_render = hide
    sc.collection.objects.link(ob)
    return ob


def note(sc, frame, *fields):
    truth.setdefault(sc.name, []).append(
        "%d %s" % (frame, " ".join(f if isinstance(f, str) else g(f) for f in fields)))


def make_scene(sc, name, fmt='OPEN_EXR_MULTILAYER', zpass=True, frames=(1, 1)):
    sc.name = name
    sc.collection.children.link(geo)
    world = bpy.data.worlds.new("world_" + name)
    world.color = (0.05, 0.07, 0.1)
    sc.world = world
    cd = bpy.data.cameras.new("cam_" + name)
    cd.clip_start = 0.25
    cam = bpy.data.objects.new("cam_" + name, cd)
    cam.location = (9, -9, 5)
    aim(cam, Vector((0, 0, 0.5)) - cam.location, '-Z')
    sc.collection.objects.link(cam)
    sc.camera = cam
    r = sc.render
    r.engine = 'CYCLES'
    sc.cycles.device = 'CPU'
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False
    sc.cycles.filter_width = 0.01
    r.threads_mode = 'FIXED'
    r.threads = 2
    r.resolution_x, r.resolution_y, r.resolution_percentage = 48, 32, 100
    sc.frame_start, sc.frame_end = frames
    r.image_settings.file_format = fmt
    if fmt.startswith('OPEN_EXR'):
        r.image_settings.color_depth = '32'
    sc.view_layers[0].use_pass_z = zpass
    r.filepath = "%s/%s/render.####" % (outdir, name)
    s = sc.fogpipe
    s.use_look = True
    s.density = 0.05
    s.height_base, s.height_scale, s.use_top, s.height_top = 0.0, 4.0, True, 12.0
    s.fog_color_auto = False
    s.fog_color = (0.6, 0.65, 0.7)
    s.phase, s.phase_g = 'hg', 0.5
    s.albedo = 0.8
    s.use_box, s.box_min, s.box_max = True, (-20, -20, -1), (20, 20, 12)
    s.thinnest_caster = 2.0   # texel 0.25 m: a small map for the test
    s.shadow_distance = 30.0
    return sc


# lights
sc = make_scene(bpy.context.scene, "lights", frames=(1, 2))
sun_dir = Vector((0.3, -0.5, 0.8)).normalized()
sun = lamp(sc, "sun", 'SUN', (1.0, 0.9, 0.8), 3.0)
sun.data.angle = math.radians(0.5)
aim(sun, sun_dir, 'Z')          # +Z toward the sun: the light shines along -Z
pt = lamp(sc, "point", 'POINT', (1.0, 0.5, 0.25), 100.0)
pt.data.shadow_soft_size = 0.1
points = [(2.0, -1.0, 1.5), (2.5, -0.5, 1.75)]
for f, loc in enumerate(points, start=1):
    pt.location = loc
    pt.keyframe_insert("location", frame=f)
spot_dir = Vector((-1.0, 0.5, -1.0)).normalized()
spot = lamp(sc, "spot", 'SPOT', (0.5, 0.75, 1.0), 200.0, (3.0, -3.0, 4.0))
spot.data.spot_size, spot.data.spot_blend, spot.data.shadow_soft_size = math.radians(40), 0.15, 0.05
aim(spot, spot_dir, '-Z')
area = lamp(sc, "area", 'AREA', (1.0, 1.0, 1.0), 50.0, (-2.0, -2.0, 3.0))
area.data.shape, area.data.size, area.data.size_y = 'RECTANGLE', 1.0, 0.5
area.rotation_euler = (math.radians(30), 0.0, math.radians(45))
area.scale = (2.0, 3.0, 1.0)
disk = lamp(sc, "disk", 'AREA', (0.2, 0.4, 0.6), 20.0, (1.0, 3.0, 2.5))
disk.data.shape, disk.data.size = 'DISK', 0.8
lamp(sc, "hidden", 'POINT', (1, 1, 1), 1000.0, (0, 0, 5), hide=True)
portal = lamp(sc, "portal", 'AREA', (1, 1, 1), 10.0, (0, 5, 2))
portal.data.cycles.is_portal = True
for f in (1, 2):
    note(sc, f, "sun", *sun_dir, 3.0, 2.7, 2.4, 0.5)
    note(sc, f, "point", *points[f - 1], *(c * 100.0 / FOUR_PI for c in (1.0, 0.5, 0.25)), 0.1)
    note(sc, f, "spot", 3.0, -3.0, 4.0, *(c * 200.0 / FOUR_PI for c in (0.5, 0.75, 1.0)), 0.05,
         *spot_dir, 40.0, 0.15)
    # Rotation XYZ (30 deg about x, then 45 about z): normal = the lamp's -Z,
    # U = its X; extents = size x scale.
    rot = Matrix.Rotation(math.radians(45), 3, 'Z') @ Matrix.Rotation(math.radians(30), 3, 'X')
    note(sc, f, "area", -2.0, -2.0, 3.0, 12.5, 12.5, 12.5, *(rot @ Vector((0, 0, -1))),
         *(rot @ Vector((1, 0, 0))), 2.0, 1.5, "0")
    note(sc, f, "area", 1.0, 3.0, 2.5, 0.2 * 5, 0.4 * 5, 0.6 * 5, 0, 0, -1, 1, 0, 0, 0.8, 0.8, "1")

# many: 40 lamps on a grid at z = 3
sc = make_scene(bpy.data.scenes.new("many"), "many")
for i in range(40):
    loc = (-9.75 + (i % 8) * 2.5, -5.0 + (i // 8) * 2.5, 3.0)
    color = (1.0, 0.5 + 0.01 * i, 0.25)
    li = lamp(sc, "lamp%02d" % i, 'POINT', color, 10.0 + i, loc)
    li.data.shadow_soft_size = 0.0
    note(sc, 1, "point", *loc, *(c * (10.0 + i) / FOUR_PI for c in color), 0.0)

# noz: the output fogpipe cannot read
make_scene(bpy.data.scenes.new("noz"), "noz", fmt='PNG', zpass=False)

for name, lines in truth.items():
    with open("%s/truth-%s.txt" % (outdir, name), "w") as f:
        f.write("\n".join(lines) + "\n")
bpy.ops.wm.save_as_mainfile(filepath=blend_path)
