# fogpipe camera for Blender: every rendered frame carries its camera.
#
# Blender writes no camera into its EXR files, and it can put only strings
# into an EXR header: the fields of its render stamp (Output Properties >
# Metadata), which it writes as string attributes of every EXR, single-layer
# and multilayer alike, whether or not the stamp is burnt into the image.
# This add-on fills the stamp's Note, before each frame renders, with the
# frame's camera as OpenEXR defines it:
#
#   fogpipe-camera 1 worldToCamera <16 numbers> worldToNDC <16 numbers>
#
# (row-vector matrices, row by row), which fogpipe reads when the header has
# no worldToCamera/worldToNDC matrices.  The matrices come from Blender's
# own projection (Object.calc_matrix_camera) of the evaluated camera, so
# animated cameras, camera switches at markers, lens, sensor fit (AUTO,
# HORIZONTAL, VERTICAL), lens shift and orthographic cameras are what
# Blender renders (tests/blender.sh checks them against Cycles' renders).
# Text you put in the Note yourself is kept in front.
#
# Set it up once, either way:
#   - as an add-on: Edit > Preferences > Add-ons > Install... this file,
#     enable "Render: fogpipe camera", and let the preferences auto-save;
#     a checkbox "fogpipe camera" in Output Properties > Metadata turns it
#     off for a scene;
#   - on a farm, without preferences: run it before rendering,
#       blender -b shot.blend -P /usr/local/share/fogpipe/blender/fogpipe_camera.py -a
#     (-P must come before -a or -f).
# Then: fogpipe -i render.####.exr -o fogged.####.exr --up z ...
#
# Why the stamp and not a sidecar file: the camera then travels inside the
# frame (copies, streams on stdin, farm nodes), and Blender writes the stamp
# into the EXR header itself.  The handler runs on frame_change_post, which
# Blender calls with the render's own evaluated depsgraph before each frame
# of `-a`, `-f N` and F12/Ctrl-F12 renders; the stamp is made after the
# frame renders, from the scene's Note at that time.

bl_info = {
    "name": "fogpipe camera",
    "author": "fogpipe",
    "version": (1, 0, 0),
    "blender": (3, 4, 0),
    "location": "Output Properties > Metadata",
    "description": "Write the render camera (OpenEXR worldToCamera and worldToNDC) into "
                   "every frame's EXR header through the stamp Note, for fogpipe",
    "category": "Render",
}

import bpy
from bpy.app.handlers import persistent
from mathutils import Matrix

MARK = "fogpipe-camera"
NOTE_MAX = 767      # RenderData.stamp_udata holds 768 bytes with its NUL
SEPARATOR = " | "


def exr_matrices(scene, depsgraph):
    """worldToCamera and worldToNDC of the scene's camera, OpenEXR's
    conventions, as column-vector mathutils matrices (transpose them for
    OpenEXR's row-vector form)."""
    cam = scene.camera.evaluated_get(depsgraph)
    r = scene.render
    # The rendered size: Blender truncates resolution * percentage / 100.
    width = r.resolution_x * r.resolution_percentage // 100
    height = r.resolution_y * r.resolution_percentage // 100
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                  scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
    # Blender ignores the camera object's scale when it renders.
    view = cam.matrix_world.normalized().inverted()
    # OpenEXR camera space: x right, y up, +z the viewing direction (Blender
    # cameras look down their -Z).
    flip_z = Matrix.Diagonal((1.0, 1.0, -1.0, 1.0))
    # Clip space (x right, y up, -1..1 across the frame) to OpenEXR NDC
    # ((0,0) top-left, (1,1) bottom-right of the display window, y down),
    # in homogeneous form so that the division by w comes after.
    to_ndc = Matrix(((0.5, 0.0, 0.0, 0.5),
                     (0.0, -0.5, 0.0, 0.5),
                     (0.0, 0.0, 1.0, 0.0),
                     (0.0, 0.0, 0.0, 1.0)))
    return flip_z @ view, to_ndc @ proj @ view


def camera_text(scene, depsgraph):
    w2c, w2n = exr_matrices(scene, depsgraph)

    def numbers(m):
        # Row-vector form: row r of the OpenEXR matrix is column r here.
        # Blender's matrices are single precision: 9 digits keep them exactly.
        return " ".join("%.9g" % m[c][r] for r in range(4) for c in range(4))

    return "%s 1 worldToCamera %s worldToNDC %s" % (MARK, numbers(w2c), numbers(w2n))


@persistent
def fogpipe_camera_frame(scene, depsgraph=None):
    if not getattr(scene, "fogpipe_camera", True) or scene.camera is None:
        return
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    ours = camera_text(scene, depsgraph)
    r = scene.render
    user = r.stamp_note_text
    if MARK in user:
        user = user[:user.index(MARK)]
    user = user.rstrip()
    if user.endswith(SEPARATOR.strip()):
        user = user[:-len(SEPARATOR.strip())].rstrip()
    note = user + SEPARATOR + ours if user else ours
    if len(note.encode("utf-8")) > NOTE_MAX:
        print("fogpipe camera: the stamp Note is too long for your own text and the camera; "
              "your text is left out of the Note")
        note = ours
    r.use_stamp_note = True
    if r.stamp_note_text != note:
        r.stamp_note_text = note


def draw_metadata(self, context):
    self.layout.prop(context.scene, "fogpipe_camera")


def register():
    bpy.types.Scene.fogpipe_camera = bpy.props.BoolProperty(
        name="fogpipe camera",
        description="Write the camera into the stamp Note of every rendered frame "
                    "(worldToCamera and worldToNDC, read by fogpipe)",
        default=True)
    handlers = bpy.app.handlers.frame_change_post
    for h in [h for h in handlers if getattr(h, "__name__", "") == "fogpipe_camera_frame"]:
        handlers.remove(h)
    handlers.append(fogpipe_camera_frame)
    panel = getattr(bpy.types, "RENDER_PT_stamp", None)
    if panel is not None:
        panel.append(draw_metadata)
    # The current frame too, for a render that changes no frame.
    scene = getattr(bpy.context, "scene", None)
    if scene is not None and scene.camera is not None:
        fogpipe_camera_frame(scene)


def unregister():
    handlers = bpy.app.handlers.frame_change_post
    for h in [h for h in handlers if getattr(h, "__name__", "") == "fogpipe_camera_frame"]:
        handlers.remove(h)
    panel = getattr(bpy.types, "RENDER_PT_stamp", None)
    if panel is not None:
        panel.remove(draw_metadata)
    del bpy.types.Scene.fogpipe_camera


if __name__ == "__main__":
    register()
