# tests/blender_light.sh: Blender's own lights, camera and geometry at every
# frame of the renders of tests/blender/light_scene.py (load it before):
#   blender -b ... -P fogpipe_blender/__init__.py -P tests/blender/light_truth.py -P light_scene.py -- OUTDIR ...
# For every frame rendered through the camera "cam", OUTDIR/truth.FRAME.txt:
#   flags FRAME OPTIONS...
#     fogpipe's light options for the frame, world axes (--up z), from the
#     evaluated light objects: every sun as --sun (the direction toward it:
#     the lamp's +Z), --sun-color (its color) and --sun-intensity (its
#     Strength: irradiance in W/m^2, as Cycles); every point and spot light
#     as --light with the radiant intensity Cycles 3.x gives it, color x
#     power / (4 pi) W/sr (eval_fac 1/(4 pi)); a spot's cone as fogpipe's
#     inner/outer half-angles: outer = spot_size/2, inner where Cycles'
#     smoothstep ends, cos(inner) = cos(outer) + (1 - cos(outer)) blend.
#     fogpipe's spot has no factor cos(angle to the axis) that Cycles 3.x
#     multiplies in (kernel spot_attenuation): the spot's light is up to
#     1 - cos(outer) too strong (1.5% for the scene's 20 degree cone).
#   light FRAME NAME X Y
#     the pixel (from the top-left) where Blender projects a local light.
# For the render through "suncam" (the sun's map), OUTDIR/sunmap.txt:
#   texel NAME I J DEPTH TOL
#     the texel (from the top-left) where Blender projects a known point of
#     the geometry that the sun sees, its depth along the sun camera's axis
#     (the Z pass's depth of an orthographic camera), and how far the
#     depth of its surface may be from it within its texel.
import math
import os
import sys

import bpy
from bpy.app.handlers import persistent
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

outdir = sys.argv[sys.argv.index("--") + 1]


def vec(v):
    return ",".join("%.9g" % x for x in v)


def light_flags(scene, depsgraph):
    flags = []
    for o in scene.objects:
        if o.type != 'LIGHT' or o.hide_render:
            continue
        o = o.evaluated_get(depsgraph)
        li = o.data
        mw = o.matrix_world.normalized()
        color = Vector(li.color)
        if li.type == 'SUN':
            if any(f.startswith("--sun") for f in flags):
                raise SystemExit("light_truth.py: fogpipe's flags hold one sun")
            flags += ["--sun", vec(mw.to_3x3() @ Vector((0, 0, 1))),
                      "--sun-color", vec(color), "--sun-intensity", "%.9g" % li.energy]
        elif li.type in ('POINT', 'SPOT'):
            i = color * (li.energy / (4 * math.pi))
            spec = "%s:%s:%s:1" % (li.type.lower(), vec(mw.translation), vec(i))
            if li.type == 'SPOT':
                outer = li.spot_size / 2
                co = math.cos(outer)
                inner = math.acos(min(co + (1 - co) * li.spot_blend, 1.0))
                spec += ":%s:%.9g,%.9g" % (vec(mw.to_3x3() @ Vector((0, 0, -1))),
                                           math.degrees(inner), math.degrees(outer))
            flags += ["--light", spec]
        else:
            raise SystemExit("light_truth.py: %s light %s: fogpipe's flags have no such light"
                             % (li.type, o.name))
    return flags


def pixel(scene, cam, p):
    r = scene.render
    W = r.resolution_x * r.resolution_percentage // 100
    H = r.resolution_y * r.resolution_percentage // 100
    u, v, z = world_to_camera_view(scene, cam, Vector(p))
    if z <= 0 or not (0 <= u < 1 and 0 <= v < 1):
        return None
    return int(u * W), int((1 - v) * H), z


# Points of the casters that the sun sees, with their surface's normal:
# the pillars' top centers and the middles of the wall's sunny side.
def known_points(scene):
    pts = []
    for o in scene.objects:
        if o.type == 'MESH' and (o.name.startswith("pillar") or o.name.startswith("wall")):
            a = o.matrix_world @ Vector(o.bound_box[0])
            b = o.matrix_world @ Vector(o.bound_box[6])
            lo = Vector(map(min, a, b))
            hi = Vector(map(max, a, b))
            if o.name.startswith("wall"):
                pts.append((o.name + "-back", ((lo.x + hi.x) / 2, hi.y, (lo.z + hi.z) / 2),
                            Vector((0, 1, 0))))
            else:
                pts.append((o.name + "-top", ((lo.x + hi.x) / 2, (lo.y + hi.y) / 2, hi.z),
                            Vector((0, 0, 1))))
    return pts


@persistent
def light_truth_frame(scene, depsgraph=None):
    if depsgraph is None or scene.camera is None:
        return
    cam = scene.camera.evaluated_get(depsgraph)
    frame = scene.frame_current
    if scene.camera.name == "cam":
        lines = ["flags %d %s" % (frame, " ".join(light_flags(scene, depsgraph)))]
        for o in scene.objects:
            if o.type == 'LIGHT' and o.data.type in ('POINT', 'SPOT'):
                px = pixel(scene, cam, o.evaluated_get(depsgraph).matrix_world.translation)
                if px:
                    lines.append("light %d %s %d %d" % (frame, o.name, px[0], px[1]))
        with open(os.path.join(outdir, "truth.%04d.txt" % frame), "w") as f:
            f.write("\n".join(lines) + "\n")
    elif scene.camera.name == "suncam":
        # One texel, and how much the depth of a surface changes across it.
        r = scene.render
        texel = cam.data.ortho_scale / max(r.resolution_x, r.resolution_y)
        view = (cam.matrix_world.to_3x3() @ Vector((0, 0, -1))).normalized()
        lines = []
        for name, p, n in known_points(scene):
            px = pixel(scene, cam, p)
            c = abs(n.dot(view))
            if px and c > 0.1:
                tol = texel * math.sqrt(2) * math.sqrt(1 - c * c) / c + 1e-3
                lines.append("texel %s %d %d %.9g %.3g" % (name, px[0], px[1], px[2], tol))
        with open(os.path.join(outdir, "sunmap.txt"), "w") as f:
            f.write("\n".join(lines) + "\n")


os.makedirs(outdir, exist_ok=True)
bpy.app.handlers.frame_change_post.append(light_truth_frame)
