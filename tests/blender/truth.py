# Blender's own camera and geometry at every frame of the same render, for
# tests/blender.sh to compare with what fogpipe understood:
#   blender -b scene.blend -S NAME -P fogpipe_blender/__init__.py -P tests/blender/truth.py -a -- OUTDIR
# writes OUTDIR/NAME/truth.FRAME.txt, lines:
#   camera FRAME px py pz  fx fy fz  ux uy uz  rx ry rz  vfov hfov
#     (position; forward = the direction through the image center; up and
#     right = the camera's +Y and +X; the angles between the directions
#     through the middles of the top and bottom, left and right edges, in
#     degrees; for an orthographic camera forward is the view direction and
#     the angles are 0) -- what `fogpipe --print-camera` prints;
#   pixel FRAME X Y DEPTH HC HQ L LABEL
#     (pixel X, Y counted from the top-left; the ray through its center
#     cast by Blender against the scene: DEPTH the hit's camera-space depth,
#     HC and HQ the heights (z) of the ray's start and of the hit, L the
#     distance between them).
# Everything here comes from Blender's API (Camera.view_frame,
# Scene.ray_cast); nothing from the add-on's matrices.
import math
import os
import sys

import bpy
from bpy.app.handlers import persistent
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

outdir = sys.argv[sys.argv.index("--") + 1]

# World points whose pixels are checked: the box's top corner nearest the
# cameras, a ground point in front of the box, the box's far bottom corner
# on the ground; plus the image's center and corners.
POINTS = [("box-corner", (1.0, -1.0, 2.0)), ("ground", (2.5, -3.0, 0.0)),
          ("box-bottom", (1.0, 1.0, 0.0))]


@persistent
def truth_frame(scene, depsgraph=None):
    if depsgraph is None or scene.camera is None:
        return
    frame = scene.frame_current
    cam = scene.camera.evaluated_get(depsgraph)
    r = scene.render
    W = r.resolution_x * r.resolution_percentage // 100
    H = r.resolution_y * r.resolution_percentage // 100
    mw = cam.matrix_world.normalized()
    rot = mw.to_3x3()
    pos = mw.translation
    ortho = cam.data.type == 'ORTHO'
    # Frame corners in camera space: top-right, bottom-right, bottom-left, top-left.
    tr, br, bl, tl = cam.data.view_frame(scene=scene)

    def local_at(u, v):
        """Camera-space point of the frame at u (0 left .. 1 right), v (0 bottom .. 1 top)."""
        return bl + (br - bl) * u + (tl - bl) * v

    def ray(u, v):
        p = local_at(u, v)
        if ortho:
            return mw @ Vector((p.x, p.y, 0.0)), (rot @ Vector((0.0, 0.0, -1.0))).normalized()
        return pos.copy(), (rot @ p).normalized()

    lines = []
    fwd = ray(0.5, 0.5)[1]
    if ortho:
        vfov = hfov = 0.0
    else:
        vfov = math.degrees(ray(0.5, 1.0)[1].angle(ray(0.5, 0.0)[1]))
        hfov = math.degrees(ray(0.0, 0.5)[1].angle(ray(1.0, 0.5)[1]))
    up = (rot @ Vector((0, 1, 0))).normalized()
    right = (rot @ Vector((1, 0, 0))).normalized()
    lines.append("camera %d %.9g %.9g %.9g  %.9f %.9f %.9f  %.9f %.9f %.9f  %.9f %.9f %.9f  %.6f %.6f"
                 % ((frame,) + tuple(pos) + tuple(fwd) + tuple(up) + tuple(right) + (vfov, hfov)))
    pixels = []
    for label, p in POINTS:
        u, v, z = world_to_camera_view(scene, cam, Vector(p))
        if z > 0 and 0 <= u < 1 and 0 <= v < 1:
            pixels.append((int(u * W), int((1 - v) * H), label))
    pixels += [(W // 2, H // 2, "center"), (0, 0, "top-left"), (W - 1, 0, "top-right"),
               (0, H - 1, "bottom-left"), (W - 1, H - 1, "bottom-right")]
    view = mw.inverted()
    for x, y, label in pixels:
        o, d = ray((x + 0.5) / W, 1 - (y + 0.5) / H)
        hit, q = scene.ray_cast(depsgraph, o, d)[:2]
        if not hit:
            continue
        depth = -(view @ q).z
        lines.append("pixel %d %d %d %.9g %.9g %.9g %.9g %s"
                     % (frame, x, y, depth, o.z, q.z, (q - o).length, label))
    d = os.path.join(outdir, scene.name)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "truth.%04d.txt" % frame), "w") as f:
        f.write("\n".join(lines) + "\n")


bpy.app.handlers.frame_change_post.append(truth_frame)
