# fogpipe for Blender: every rendered frame carries what fogpipe needs to fog
# it with the scene's own light (README "From Blender" tells the whole path).
#
# Blender can put only strings into an EXR header: the fields of its render
# stamp, written into every EXR whether or not the stamp is burnt in.  Before
# each frame renders (frame_change_post, called with the render's evaluated
# depsgraph for -a, -f N, F12 and Ctrl-F12) the add-on fills the stamp's Note:
#   fogpipe-camera 1 worldToCamera <16 numbers> worldToNDC <16 numbers>
#   [fogpipe-look 1 density=... height=... fog-color=... phase=... albedo=...]
#   fogpipe-rig 1 up z clip START [shadow PATH] lights N LIGHT...
# The camera is Blender's own projection (Object.calc_matrix_camera) as
# OpenEXR defines its matrices (row vectors, row by row); the rig (schema in
# README "From other hosts") is every visible sun, point, spot and area light
# in Cycles' units.  Blender keeps 511 bytes of the Note: what does not fit
# (the look, lights) is added after Blender writes the frame (render_write)
# as the string attributes fogpipeLook and fogpipeRig (the complete rig), by
# rewriting the header; the pixels' bytes are not touched.  Text you put in
# the Note yourself is kept in front when there is room.
#
# Output Properties > fogpipe: the fog look (saved in the .blend), sun shadow
# maps (depth along the sun, fitted to the fog the camera sees), Preview Fog
# (the Render Result through fogpipe's Python module), and the check that the
# output is OpenEXR MultiLayer with the Z pass (also printed at render start).
#
# The add-on is this package (exr_header.py: the header rewrite).  Set it
# up once: Edit > Preferences > Add-ons > Install... fogpipe_blender.zip
# (installed beside this folder), enable "Render: fogpipe"; or, on a farm,
# run this file before rendering (-P before -a):
#   blender -b shot.blend -P /usr/local/share/fogpipe/blender/fogpipe_blender/__init__.py -a
# Sun shadow maps for frames A-B, then the frames (naming their maps):
#   blender -b shot.blend -P fogpipe_blender/__init__.py -a -- --fogpipe-shadow-maps --frames A-B

bl_info = {
    "name": "fogpipe",
    "author": "fogpipe",
    "version": (2, 0, 0),
    "blender": (3, 4, 0),
    "location": "Output Properties > fogpipe",
    "description": "Write the camera, the lights, the sun's shadow map and the fog look into "
                   "every rendered EXR for fogpipe; render sun shadow maps; preview the fog",
    "category": "Render",
}

import math
import os
import struct
import sys
import tempfile

import bpy
from bpy.app.handlers import persistent
from mathutils import Matrix, Vector

try:
    from .exr_header import ExrError, exr_header, exr_set_strings  # noqa: F401 (tests use exr_header)
except ImportError:
    # Run as a script (blender -P .../fogpipe_blender/__init__.py): no
    # package around this file, so its folder's modules are imported by name.
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from exr_header import ExrError, exr_header, exr_set_strings  # noqa: F401

MARK = "fogpipe-camera"
RIG_MARK = "fogpipe-rig"
LOOK_MARK = "fogpipe-look"
RIG_ATTR = "fogpipeRig"
LOOK_ATTR = "fogpipeLook"
# The Note field takes 767 bytes, but Blender's stamp (StampData.note) keeps
# 511 of them in the file: what is longer is cut mid-number.
NOTE_MAX = 511
SEPARATOR = " | "
SHADOW_SCENE = "fogpipe_shadow_scene"   # ID property of the map's temporary scene
OLD_HANDLERS = ("fogpipe_camera_frame",)     # fogpipe_camera.py, this file's old name
MAX_TEXELS = 8192   # per side of a sun shadow map

# What did not fit into the Note, for render_write: (scene name, frame) ->
# {attribute name: text}.
_pending = {}


def log(msg):
    print("fogpipe: " + msg, flush=True)


def num(x):
    """The shortest decimal that reads back as x in single precision
    (Blender's matrices and settings are single precision): exact, and
    about 100 bytes less per camera than 9 digits always."""
    f = struct.unpack("<f", struct.pack("<f", x))[0] if math.isfinite(x) else x
    for digits in range(6, 10):
        t = "%.*g" % (digits, f)
        if struct.unpack("<f", struct.pack("<f", float(t)))[0] == f or not math.isfinite(f):
            return t
    return "%.9g" % f


def nums(v):
    return " ".join(num(c) for c in v)


# ---------------------------------------------------------------- camera

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
        return " ".join(num(m[c][r]) for r in range(4) for c in range(4))

    return "%s 1 worldToCamera %s worldToNDC %s" % (MARK, numbers(w2c), numbers(w2n))


# ---------------------------------------------------------------- rig

def rig_lights(depsgraph):
    """The render's visible lights as rig text entries (suns first), in
    world space and Cycles 3.x units (rig schema, README 'From other
    hosts')."""
    suns, others = [], []
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != 'LIGHT' or ob.hide_render:
            continue
        li = ob.data
        # A portal guides sampling and emits nothing.
        if getattr(getattr(li, "cycles", None), "is_portal", False):
            continue
        power = [c * li.energy for c in li.color]
        if max(power) <= 0.0:
            continue
        m = inst.matrix_world.copy()
        rot = m.to_3x3()
        pos = m.translation
        down = (rot @ Vector((0.0, 0.0, -1.0))).normalized()   # the lamp's -Z
        if li.type == 'SUN':
            suns.append("sun %s %s %s" % (nums(-down), nums(power), num(math.degrees(li.angle))))
        elif li.type == 'POINT':
            others.append("point %s %s %s" % (nums(pos), nums(p / (4 * math.pi) for p in power),
                                              num(li.shadow_soft_size)))
        elif li.type == 'SPOT':
            others.append("spot %s %s %s %s %s %s" % (
                nums(pos), nums(p / (4 * math.pi) for p in power), num(li.shadow_soft_size),
                nums(down), num(math.degrees(li.spot_size)), num(li.spot_blend)))
        elif li.type == 'AREA':
            # Cycles takes the extents from the object's scaled X and Y axes.
            ux, vy = rot @ Vector((1.0, 0.0, 0.0)), rot @ Vector((0.0, 1.0, 0.0))
            su = li.size * ux.length
            sv = (li.size_y if li.shape in ('RECTANGLE', 'ELLIPSE') else li.size) * vy.length
            others.append("area %s %s %s %s %s %s %d" % (
                nums(pos), nums(p / 4 for p in power), nums(down), nums(ux.normalized()),
                num(su), num(sv), 1 if li.shape in ('DISK', 'ELLIPSE') else 0))
    return suns + others


def expand_hashes(path, frame):
    """The last run of '#' replaced by the frame number (Blender's rule)."""
    end = path.rfind("#")
    if end < 0:
        return path
    start = end
    while start > 0 and path[start - 1] == "#":
        start -= 1
    width = end - start + 1
    return path[:start] + "%0*d" % (width, frame) + path[end + 1:]


def frame_file(scene, frame):
    return bpy.path.abspath(scene.render.frame_path(frame=frame))


def shadow_map_file(scene, frame):
    """Absolute path of the sun's shadow map for `frame` (the static map's
    for every frame when the scene's map is static).  A path without '//'
    and not absolute is taken from the frames' directory."""
    s = scene.fogpipe
    f = scene.frame_start if s.shadow_static else frame
    p = s.shadow_path
    if p.startswith("//") or os.path.isabs(p):
        p = bpy.path.abspath(p)
    else:
        p = os.path.join(os.path.dirname(frame_file(scene, frame)), p)
    return os.path.normpath(expand_hashes(p, f))


def rig_head(scene, depsgraph, nlights):
    cam = scene.camera.evaluated_get(depsgraph)
    head = "%s 1 up z clip %s" % (RIG_MARK, num(cam.data.clip_start))
    if scene.fogpipe.shadow_maps:
        frame = scene.frame_current
        rel = os.path.relpath(shadow_map_file(scene, frame),
                              os.path.dirname(frame_file(scene, frame)))
        if any(c.isspace() or c == ";" for c in rel):
            log("frame %d: the shadow map path '%s' has a space or ';', which the rig's text "
                "cannot carry: not recorded (fogpipe --shadow-map names it)" % (frame, rel))
        else:
            head += " shadow " + rel
    return head + " lights %d" % nlights


def look_text(s):
    """The fog look as fogpipe's long options (rig schema: fogpipe-look)."""
    h = [s.height_base, math.inf if s.homogeneous else s.height_scale,
         s.height_top if s.use_top else math.inf]
    phase = s.phase
    if phase in ('hg', 'cs'):
        phase += ":" + num(s.phase_g)
    elif phase in ('mix', 'mixhg'):
        phase += ":%s,%s" % (num(s.phase_w), num(s.phase_g))
    parts = ["density=" + num(s.density),
             "height=" + ",".join(num(x) for x in h),
             "fog-color=" + ("auto" if s.fog_color_auto else ",".join(num(c) for c in s.fog_color)),
             "phase=" + phase,
             "albedo=" + num(s.albedo)]
    if s.use_box:
        parts.append("fog-box=" + ",".join(num(c) for c in tuple(s.box_min) + tuple(s.box_max)))
    return "%s 1 %s" % (LOOK_MARK, " ".join(parts))


def user_note(text):
    """The user's own part of a Note, before anything of ours."""
    cut = [text.index(m) for m in (MARK, LOOK_MARK, RIG_MARK) if m in text]
    if cut:
        text = text[:min(cut)]
    text = text.rstrip()
    if text.endswith(SEPARATOR.strip()):
        text = text[:-len(SEPARATOR.strip())].rstrip()
    return text


def fits(text):
    return len(text.encode("utf-8")) <= NOTE_MAX


def compose_note(user, camera, look, head, lights):
    """(note, look carried, lights carried, head carried): the user's text
    (when the camera and the rig's head fit with it), the camera, the look
    when it fits, the rig's head and as many lights as fit."""
    ours = camera + " " + head
    if look and fits(camera + " " + look + " " + head):
        ours = camera + " " + look + " " + head
    note = user + SEPARATOR + ours if user and fits(user + SEPARATOR + ours) else ours
    if not fits(note):
        return camera, False, 0, False
    for i, li in enumerate(lights):
        if not fits(note + " " + li):
            return note, bool(look) and look in note, i, True
        note += " " + li
    return note, bool(look) and look in note, len(lights), True


@persistent
def fogpipe_frame(scene, depsgraph=None):
    s = getattr(scene, "fogpipe", None)
    if s is None or not s.enabled or scene.camera is None:
        return
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    r = scene.render
    cam = camera_text(scene, depsgraph)
    if scene.get(SHADOW_SCENE):
        note = cam   # a sun shadow map: its camera only
    else:
        lights = rig_lights(depsgraph)
        head = rig_head(scene, depsgraph, len(lights))
        look = look_text(s) if s.use_look else ""
        note, has_look, carried, has_head = compose_note(user_note(r.stamp_note_text), cam,
                                                         look, head, lights)
        if not fits(cam):
            log("frame %d: the camera's text is %d bytes, more than the %d the stamp keeps: "
                "fogpipe cannot read it" % (scene.frame_current, len(cam), NOTE_MAX))
        key = (scene.name, scene.frame_current)
        extra = {}
        if not has_head or carried < len(lights):
            extra[RIG_ATTR] = " ".join([head] + lights)
        if look and not has_look:
            extra[LOOK_ATTR] = look
        if extra and _pending.get(key) != extra:
            log("frame %d: the Note holds %d of the %d lights%s%s; %s go%s into the EXR when "
                "Blender writes the frame" % (
                    scene.frame_current, carried, len(lights),
                    "" if has_head else ", not the rig's head",
                    "" if has_look or not look else ", not the look",
                    " and ".join(sorted(extra)), "" if len(extra) > 1 else "es"))
        if extra:
            _pending[key] = extra
        else:
            _pending.pop(key, None)
    r.use_stamp_note = True
    if r.stamp_note_text != note:
        r.stamp_note_text = note


def frame_strings(scene):
    """The current frame's whole rig and look as fogpipeRig / fogpipeLook."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    lights = rig_lights(depsgraph)
    out = {RIG_ATTR: " ".join([rig_head(scene, depsgraph, len(lights))] + lights)}
    s = scene.fogpipe
    if s.use_look:
        out[LOOK_ATTR] = look_text(s)
    return out


def written_files(scene, frame):
    r = scene.render
    if r.use_multiview and r.views_format == 'INDIVIDUAL':
        return [bpy.path.abspath(r.frame_path(frame=frame, view=v.name)) for v in r.views if v.use]
    return [frame_file(scene, frame)]


@persistent
def fogpipe_written(scene, *args):
    """After Blender writes a frame: the complete rig (and the look) into the
    EXR when the Note could not hold them."""
    frame = scene.frame_current
    extra = _pending.pop((scene.name, frame), None)
    if extra is None:
        return
    fmt = scene.render.image_settings.file_format
    if fmt not in ('OPEN_EXR', 'OPEN_EXR_MULTILAYER'):
        log("frame %d: the output is %s, not OpenEXR: %s not in the frame"
            % (frame, fmt, " and ".join(sorted(extra))))
        return
    for path in written_files(scene, frame):
        try:
            exr_set_strings(path, extra)
        except (ExrError, OSError) as e:
            log("%s: frame %d: cannot add %s: %s; the frame carries only what its Note holds"
                % (path, frame, " and ".join(sorted(extra)), e))


# ---------------------------------------------------------------- output check

def output_problems(scene):
    """What keeps fogpipe from reading the frames, naming the setting."""
    r, im = scene.render, scene.render.image_settings
    out = []
    if im.file_format == 'OPEN_EXR':
        if not im.use_zbuffer:
            out.append("Output Properties > Output > Z Buffer is off (OpenEXR single-layer "
                       "writes no depth; use OpenEXR MultiLayer: image_settings.file_format = "
                       "'OPEN_EXR_MULTILAYER')")
    elif im.file_format != 'OPEN_EXR_MULTILAYER':
        out.append("Output Properties > Output > File Format is %s, not OpenEXR MultiLayer "
                   "(image_settings.file_format = 'OPEN_EXR_MULTILAYER')" % im.file_format)
    for vl in scene.view_layers:
        if vl.use and not vl.use_pass_z and not (r.use_single_layer and vl != scene.view_layers[0]):
            out.append("View Layer Properties > Passes > Data > Z is off for view layer '%s' "
                       "(view_layer.use_pass_z): the frames have no depth" % vl.name)
    return out


def output_warnings(scene):
    im = scene.render.image_settings
    if im.file_format in ('OPEN_EXR', 'OPEN_EXR_MULTILAYER') and im.color_depth == '16':
        return ["Output Properties > Output > Color Depth is Float (Half): depth is kept to "
                "1/2048 of its value (Float (Full), image_settings.color_depth = '32', keeps "
                "it exactly)"]
    return []


@persistent
def fogpipe_render_init(scene, *args):
    s = getattr(scene, "fogpipe", None)
    if s is None or not s.enabled or scene.get(SHADOW_SCENE):
        return
    for p in output_problems(scene):
        log("scene '%s': %s" % (scene.name, p))
    for w in output_warnings(scene):
        log("scene '%s': warning: %s" % (scene.name, w))


class FOGPIPE_OT_setup_output(bpy.types.Operator):
    """Set OpenEXR MultiLayer, 32-bit float, and the Z pass on every view layer"""
    bl_idname = "fogpipe.setup_output"
    bl_label = "Set OpenEXR MultiLayer + Z"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        scene = context.scene
        scene.render.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
        scene.render.image_settings.color_depth = '32'
        for vl in scene.view_layers:
            vl.use_pass_z = True
        self.report({'INFO'}, "fogpipe: output set to OpenEXR MultiLayer, float, with the Z pass")
        return {'FINISHED'}


# ---------------------------------------------------------------- sun shadow maps

def strongest_sun(depsgraph):
    """(direction toward the sun, irradiance) of the brightest visible sun."""
    best = None
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != 'LIGHT' or ob.data.type != 'SUN' or ob.hide_render:
            continue
        e = max(ob.data.color) * ob.data.energy
        d = (inst.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()
        if e > 0 and (best is None or e > best[1]):
            best = (d, e)
    return best


def frustum_faces(scene, depsgraph, near, far):
    """The camera's view between planar depths near and far, as 6 quads."""
    cam = scene.camera.evaluated_get(depsgraph)
    m = cam.matrix_world.normalized()
    frame = cam.data.view_frame(scene=scene)
    ortho = cam.data.type == 'ORTHO'
    pts = []
    for z in (near, far):
        for p in frame:
            q = Vector((p.x, p.y, -z)) if ortho else p * (z / -p.z)
            pts.append(m @ q)
    quads = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return [[pts[i] for i in q] for q in quads]


def clip_faces(faces, n, d):
    """A convex polyhedron (its faces) cut to n . p <= d."""
    out, cap = [], []
    for poly in faces:
        res = []
        for i, a in enumerate(poly):
            b = poly[(i + 1) % len(poly)]
            da, db = n.dot(a) - d, n.dot(b) - d
            if da <= 0:
                res.append(a)
            if (da < 0 < db) or (db < 0 < da):
                p = a + (b - a) * (da / (da - db))
                res.append(p)
                cap.append(p)
        if len(res) >= 3:
            out.append(res)
    if len(cap) >= 3:
        c = sum(cap, Vector()) / len(cap)
        e1 = n.orthogonal().normalized()
        e2 = n.normalized().cross(e1)
        cap.sort(key=lambda p: math.atan2((p - c).dot(e2), (p - c).dot(e1)))
        out.append(cap)
    return out


def seen_fog(scene, depsgraph):
    """Points spanning the fog the camera sees: its view from the clip
    start to the max distance, cut to the fog's box and top.  (points,
    what cut it)."""
    s = scene.fogpipe
    cam = scene.camera.evaluated_get(depsgraph).data
    far = min(cam.clip_end, s.shadow_distance)
    faces = frustum_faces(scene, depsgraph, cam.clip_start, far)
    cuts = ["the camera's view to %.4g m" % far]
    planes = []
    if s.use_look and s.use_box:
        for axis in range(3):
            e = Vector((0.0, 0.0, 0.0))
            e[axis] = 1.0
            planes += [(e, s.box_max[axis]), (-e, -s.box_min[axis])]
        cuts.append("the fog box")
    if s.use_look and s.use_top:
        planes.append((Vector((0.0, 0.0, 1.0)), s.height_top))
        cuts.append("the fog top")
    clipped = faces
    for n, d in planes:
        clipped = clip_faces(clipped, n, d)
    pts = [p for f in clipped for p in f]
    if not pts:
        log("frame %d: the camera sees none of the fog's box; the map covers the camera's view"
            % scene.frame_current)
        pts = [p for f in faces for p in f]
    return pts, ", ".join(cuts)


def sun_frame(d):
    """Orthonormal X, Y of a camera looking along -d (d toward the sun)."""
    ref = Vector((0.0, 0.0, 1.0)) if abs(d.z) < 0.99 else Vector((0.0, 1.0, 0.0))
    y = (ref - d * ref.dot(d)).normalized()
    return y.cross(d), y


def casters_top(depsgraph, d):
    """The highest point of the scene's geometry along d."""
    top = -math.inf
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type not in ('MESH', 'CURVE', 'SURFACE', 'META', 'FONT', 'VOLUME', 'GPENCIL') \
                or ob.hide_render:
            continue
        m = inst.matrix_world
        for c in ob.bound_box:
            top = max(top, d.dot(m @ Vector(c)))
    return top


def fit_sun_camera(scene, frames):
    """Evaluates the scene at each of `frames` (the scene's frame is
    restored by the caller) and fits one orthographic camera along the sun to
    the fog the camera sees over all of them: (matrix_world, ortho scale,
    nx, ny, clip_end, texel, the console line) or None without a sun."""
    s = scene.fogpipe
    texel = want = s.thinnest_caster / 8.0
    lo, hi, d, cuts = [math.inf] * 3, [-math.inf] * 3, None, ""
    for f in frames:
        scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        sun = strongest_sun(dg)
        if sun is None:
            log("frame %d: no visible sun with some strength: no shadow map" % f)
            return None
        if d is None:
            d = sun[0]
            ax, ay = sun_frame(d)
        elif (sun[0] - d).length > 1e-6:
            log("frame %d: the sun moves: a static map cannot hold it (turn Static off)" % f)
            return None
        pts, cuts = seen_fog(scene, dg)
        for p in pts:
            for i, v in enumerate((ax.dot(p), ay.dot(p), d.dot(p))):
                lo[i], hi[i] = min(lo[i], v), max(hi[i], v)
        hi[2] = max(hi[2], casters_top(dg, d))
    w, h = hi[0] - lo[0] + 2 * texel, hi[1] - lo[1] + 2 * texel
    if max(w, h) / texel > MAX_TEXELS:
        texel = max(w, h) / MAX_TEXELS
    nx, ny = max(1, math.ceil(w / texel)), max(1, math.ceil(h / texel))
    w, h = nx * texel, ny * texel
    top = hi[2] + 1.0
    m = Matrix((ax, ay, d)).transposed().to_4x4()
    m.translation = ax * (lo[0] + hi[0]) / 2 + ay * (lo[1] + hi[1]) / 2 + d * top
    line = ("sun map covers %.4g x %.4g m (%s), %d x %d texels of %.4g m: casters down to "
            "%.4g m held (8 texels across)" % (w, h, cuts, nx, ny, texel, 8 * texel))
    if texel > want * (1 + 1e-9):
        line += "; WARNING: the thinnest caster setting (%.4g m) needs more than %d texels " \
                "a side: raise it or the max distance" % (s.thinnest_caster, MAX_TEXELS)
    return m, max(w, h), nx, ny, top - lo[2] + 1.0, texel, line


def disable_passes(vl):
    for owner in (vl, getattr(vl, "cycles", None)):
        if owner is None:
            continue
        for p in owner.bl_rna.properties:
            name = p.identifier
            if p.type == 'BOOLEAN' and name.startswith(("use_pass_", "denoising_store")) \
                    and not p.is_readonly and name not in ("use_pass_z", "use_pass_combined"):
                setattr(owner, name, False)
    vl.use_pass_z = True
    aovs = getattr(vl, "aovs", None)
    while aovs is not None and len(aovs):
        aovs.remove(aovs[0])
    vl.use_freestyle = False


def render_shadow_maps(scene, frames):
    """Renders the sun's depth for `frames` (once for a static map) with a
    temporary scene sharing the scene's objects; returns the files written.
    The scene's own settings and frame are left as they were."""
    s = scene.fogpipe
    current = scene.frame_current
    groups = [list(frames)] if s.shadow_static else [[f] for f in frames]
    written = []
    tmp = cam_ob = None
    try:
        for group in groups:
            fit = fit_sun_camera(scene, group)
            if fit is None:
                return written
            m, scale, nx, ny, clip_end, texel, line = fit
            frame = group[0]
            target = shadow_map_file(scene, frame)
            if tmp is None:
                tmp = scene.copy()
                tmp.name = "fogpipe-sun-map"
                tmp[SHADOW_SCENE] = True
                tmp.timeline_markers.clear()   # no camera switches
                cam_data = bpy.data.cameras.new("fogpipe-sun")
                cam_data.type, cam_data.clip_start = 'ORTHO', 1e-3
                cam_ob = bpy.data.objects.new("fogpipe-sun", cam_data)
                tmp.collection.objects.link(cam_ob)
                tmp.camera = cam_ob
                setup_map_scene(tmp)
            cam_ob.matrix_world, cam_ob.data.ortho_scale, cam_ob.data.clip_end = m, scale, clip_end
            tmp.render.resolution_x, tmp.render.resolution_y = nx, ny
            os.makedirs(os.path.dirname(target), exist_ok=True)
            tmp.render.filepath = os.path.join(os.path.dirname(target), ".fogpipe-sun.####")
            tmp.frame_start = tmp.frame_end = frame
            log("frame %d: %s: %s" % (frame, target, line))
            bpy.ops.render.render(animation=True, scene=tmp.name)
            made = bpy.path.abspath(tmp.render.frame_path(frame=frame))
            if not os.path.exists(made):
                raise RuntimeError("fogpipe: frame %d: Blender wrote no shadow map (%s)"
                                   % (frame, made))
            os.replace(made, target)
            written.append(target)
        s.shadow_maps = True
    finally:
        if tmp is not None:
            bpy.data.scenes.remove(tmp)
        if cam_ob is not None:
            data = cam_ob.data
            bpy.data.objects.remove(cam_ob)
            bpy.data.cameras.remove(data)
        scene.frame_set(current)
    return written


def setup_map_scene(tmp):
    """Depth only, cheaply: Cycles, 1 sample, no bounces, the pixel's
    center, full float multilayer EXR with the Z pass, nothing else."""
    r = tmp.render
    r.engine = 'CYCLES'
    for k, v in dict(samples=1, use_adaptive_sampling=False, use_denoising=False,
                     filter_width=0.01, max_bounces=0, use_animated_seed=False).items():
        setattr(tmp.cycles, k, v)
    for k, v in dict(film_transparent=True, resolution_percentage=100, pixel_aspect_x=1.0,
                     pixel_aspect_y=1.0, use_border=False, use_motion_blur=False,
                     use_compositing=False, use_sequencer=False, use_freestyle=False,
                     use_multiview=False, use_persistent_data=False, use_stamp=False,
                     use_file_extension=True, use_overwrite=True, use_placeholder=False,
                     use_stamp_note=True).items():
        setattr(r, k, v)
    im = r.image_settings
    im.file_format, im.color_depth, im.exr_codec = 'OPEN_EXR_MULTILAYER', '32', 'ZIP'
    used = [vl for vl in tmp.view_layers if vl.use] or list(tmp.view_layers)
    for vl in tmp.view_layers:
        vl.use = vl == used[0]
    disable_passes(used[0])


def parse_frames(text, scene):
    if not text:
        return list(range(scene.frame_start, scene.frame_end + 1, scene.frame_step))
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


class FOGPIPE_OT_shadow_maps(bpy.types.Operator):
    """Render the sun's depth maps for the scene's frames (once when Static) and record them in
    the frames' rig"""
    bl_idname = "fogpipe.shadow_maps"
    bl_label = "Render Sun Shadow Maps"

    frames: bpy.props.StringProperty(name="Frames", default="",
                                     description="A-B[,C-D]; empty: the scene's range")

    def execute(self, context):
        made, err = shadow_maps_for(context.scene, self.frames)
        if err:
            self.report({'ERROR'}, err)
            return {'CANCELLED'}
        self.report({'INFO'}, "fogpipe: %d shadow map(s), %s" % (len(made), made[0]))
        return {'FINISHED'}


def shadow_maps_for(scene, frames):
    """(files, None) or (None, the message)."""
    if scene.camera is None:
        return None, "fogpipe: scene '%s' has no camera: no shadow map" % scene.name
    try:
        made = render_shadow_maps(scene, parse_frames(frames, scene))
    except (RuntimeError, ValueError) as e:
        return None, "fogpipe: scene '%s': %s" % (scene.name, e)
    return (made, None) if made else (None, "fogpipe: no shadow map rendered (see above)")


# ---------------------------------------------------------------- preview

def look_options(s):
    opts = {"up": "z"}
    if s.use_look:
        for kv in look_text(s).split(" ")[2:]:
            k, v = kv.split("=", 1)
            opts[k.replace("-", "_")] = v
    return opts


class FOGPIPE_OT_preview(bpy.types.Operator):
    """Fog the current Render Result (or the current frame's file) through fogpipe's Python
    module and show it in the Image Editor"""
    bl_idname = "fogpipe.preview"
    bl_label = "Preview Fog"

    def execute(self, context):
        scene = context.scene
        try:
            import fogpipe
        except Exception as e:  # ImportError, or the library's OSError
            self.report({'ERROR'}, "fogpipe: Preview Fog needs fogpipe's Python module "
                        "(make install puts it in the system Python's site-packages; or start "
                        "Blender with --python-use-system-env and PYTHONPATH=.../python): %s" % e)
            return {'CANCELLED'}
        work = os.path.join(tempfile.gettempdir(), "fogpipe-preview-%d" % os.getpid())
        os.makedirs(work, exist_ok=True)
        src = os.path.join(work, "render.exr")
        rr = bpy.data.images.get("Render Result")
        im = scene.render.image_settings
        fmt, depth = im.file_format, im.color_depth
        try:   # the Render Result with its passes and stamp, exactly
            im.file_format, im.color_depth = 'OPEN_EXR_MULTILAYER', '32'
            rr.save_render(src, scene=scene)
            # save_render runs no write handler: the whole rig and look go
            # into the file here, as after a frame Blender writes.
            exr_set_strings(src, frame_strings(scene))
        except (AttributeError, RuntimeError):   # none, or nothing rendered
            pass
        except (ExrError, OSError) as e:
            self.report({'ERROR'}, "fogpipe: %s: cannot add the rig to the Render Result: %s"
                        % (src, e))
            return {'CANCELLED'}
        finally:
            im.file_format, im.color_depth = fmt, depth
        if not os.path.exists(src):
            src = frame_file(scene, scene.frame_current)
            if not os.path.exists(src):
                self.report({'ERROR'}, "fogpipe: no Render Result and no rendered frame %d (%s): "
                            "render first" % (scene.frame_current, src))
                return {'CANCELLED'}
        out = os.path.join(work, "fogged.exr")
        opts = look_options(scene.fogpipe)
        if scene.fogpipe.shadow_maps:
            sm = shadow_map_file(scene, scene.frame_current)
            if os.path.exists(sm):
                opts["shadow_map"] = sm
        try:
            fogpipe.apply_file(src, out, **opts)
        except fogpipe.Error as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        img = bpy.data.images.get("fogpipe preview")
        if img is None:
            img = bpy.data.images.load(out, check_existing=False)
            img.name = "fogpipe preview"
        else:
            img.filepath = out
            img.reload()
        def editors():
            return [a for w in context.window_manager.windows for a in w.screen.areas
                    if a.type == 'IMAGE_EDITOR']
        if not editors() and context.window is not None:
            bpy.ops.render.view_show('INVOKE_DEFAULT')
        for area in editors()[:1]:
            area.spaces.active.image = img
        self.report({'INFO'}, "fogpipe: preview in image 'fogpipe preview' (%s)" % out)
        return {'FINISHED'}


# ---------------------------------------------------------------- settings and panel

PHASES = [('iso', "Isotropic", "iso"), ('hg', "Henyey-Greenstein", "hg:G"),
          ('cs', "Cornette-Shanks", "cs:G"), ('rayleigh', "Rayleigh", "rayleigh"),
          ('mix', "Rayleigh + Cornette-Shanks", "mix:W,G"),
          ('mixhg', "Rayleigh + Henyey-Greenstein", "mixhg:W,G")]


B, F, V = bpy.props.BoolProperty, bpy.props.FloatProperty, bpy.props.FloatVectorProperty


class FogpipeSettings(bpy.types.PropertyGroup):
    enabled: B(name="fogpipe", default=True, description="Write the camera, lights and look into "
               "every rendered frame (stamp Note, EXR attributes), read by fogpipe")
    use_look: B(name="Write the Fog Look", default=False, description="Write these settings with "
                "every frame (fogpipe-look): fogpipe uses them; its own options still win")
    density: F(name="Density", default=0.02, min=0.0, max=1e6, precision=4,
               description="--density: extinction per meter")
    height_base: F(name="Base", default=0.0, unit='LENGTH', description="--height Y0")
    height_scale: F(name="Scale Height", default=20.0, min=1e-6, unit='LENGTH',
                    description="--height H: density exp(-(z-Y0)/H) above Y0")
    homogeneous: B(name="Homogeneous", default=False, description="H = inf")
    use_top: B(name="Top", default=False, description="no fog above TOP")
    height_top: F(name="Top", default=50.0, unit='LENGTH', description="--height TOP")
    fog_color_auto: B(name="Auto", default=True,
                      description="--fog-color auto: the ambient light from the sun and the fog "
                                  "(multiple scattering); off: the typed color below")
    fog_color: V(name="Fog Color", subtype='COLOR', size=3, default=(0.7, 0.75, 0.8), min=0.0,
                 max=1e6, description="--fog-color (scene-linear)")
    phase: bpy.props.EnumProperty(name="Phase", items=PHASES, default='iso', description="--phase")
    phase_g: F(name="G", default=0.6, min=-0.99, max=0.99, description="> 0 scatters forward")
    phase_w: F(name="Rayleigh Weight", default=0.3, min=0.0, max=1.0)
    albedo: F(name="Albedo", default=1.0, min=0.0, max=1.0, description="--albedo")
    use_box: B(name="Box", default=False, description="--fog-box: no fog outside it")
    box_min: V(name="Box Min", size=3, default=(-50, -50, -10), subtype='XYZ', unit='LENGTH')
    box_max: V(name="Box Max", size=3, default=(50, 50, 30), subtype='XYZ', unit='LENGTH')
    shadow_maps: B(name="Record Sun Shadow Map", default=False, description="Name the sun's "
                   "shadow map in every frame's rig (set when maps are rendered)")
    shadow_path: bpy.props.StringProperty(
        name="Map Path", default="fogpipe/sun.####.exr", description="'#': the frame; relative "
        "to the frames' directory, or '//' to the .blend's")
    shadow_static: B(name="Static", default=False, description="Sun and scene do not move: one "
                     "map (the first frame's) for every frame")
    thinnest_caster: F(name="Thinnest Caster", default=0.25, min=1e-4, unit='LENGTH',
                       description="The thinnest caster whose shadow must show: texel = this / 8 "
                       "(with fewer than about 8 texels across, shafts are lost)")
    shadow_distance: F(name="Max Distance", default=100.0, min=0.01, unit='LENGTH',
                       description="The map covers the fog the camera sees up to this distance")


class FOGPIPE_PT_panel(bpy.types.Panel):
    bl_label = "fogpipe"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "output"
    bl_options = {'DEFAULT_CLOSED'}

    def draw_header(self, context):
        self.layout.prop(context.scene.fogpipe, "enabled", text="")

    def draw(self, context):
        scene, layout = context.scene, self.layout
        s = scene.fogpipe
        layout.active = s.enabled
        problems = output_problems(scene) + output_warnings(scene)
        for p in problems:
            layout.label(text=p, icon='ERROR')
        if problems:
            layout.operator("fogpipe.setup_output")
        col = layout.box().column()
        col.prop(s, "use_look")
        rows = [("density",), ("height_base", "height_scale"), ("homogeneous", "use_top",
                "height_top"), ("fog_color_auto",) + (() if s.fog_color_auto else ("fog_color",)), ("phase",) + (("phase_w",) if s.phase in (
                    'mix', 'mixhg') else ()) + (("phase_g",) if s.phase not in (
                        'iso', 'rayleigh') else ()), ("albedo",), ("use_box",)]
        if s.use_box:
            rows += [("box_min",), ("box_max",)]
        rows += [(None,), ("shadow_maps", "shadow_static"), ("shadow_path",),
                 ("thinnest_caster", "shadow_distance")]
        for names in rows:
            row = col.row(align=True)
            row.active = s.use_look or names[0] in ("shadow_maps", "shadow_path",
                                                    "thinnest_caster")
            for n in names:
                if n is None:
                    row.label(text="Sun Shadow Maps")
                else:
                    row.prop(s, n)
        col.operator("fogpipe.shadow_maps")
        layout.operator("fogpipe.preview", icon='IMAGE')


def draw_metadata(self, context):
    self.layout.prop(context.scene.fogpipe, "enabled", text="fogpipe")


CLASSES = (FogpipeSettings, FOGPIPE_OT_setup_output, FOGPIPE_OT_shadow_maps, FOGPIPE_OT_preview,
           FOGPIPE_PT_panel)
HANDLERS = (("frame_change_post", fogpipe_frame), ("render_write", fogpipe_written),
            ("render_init", fogpipe_render_init))
OUR_NAMES = {h.__name__ for _, h in HANDLERS} | set(OLD_HANDLERS)


def remove_handlers():
    for kind, _ in HANDLERS:
        lst = getattr(bpy.app.handlers, kind)
        for h in [h for h in lst if getattr(h, "__name__", "") in OUR_NAMES]:
            lst.remove(h)


def register():
    # Run twice (-P and the installed add-on), or after fogpipe_camera.py:
    # one set of handlers, ours.
    remove_handlers()
    for c in CLASSES:
        if getattr(bpy.types, c.__name__, None) is not None:
            bpy.utils.unregister_class(getattr(bpy.types, c.__name__))
        bpy.utils.register_class(c)
    bpy.types.Scene.fogpipe = bpy.props.PointerProperty(type=FogpipeSettings)
    for kind, h in HANDLERS:
        getattr(bpy.app.handlers, kind).append(h)
    panel = getattr(bpy.types, "RENDER_PT_stamp", None)
    if panel is not None:
        panel.remove(draw_metadata)
        panel.append(draw_metadata)
    # The current frame too, for a render that changes no frame.
    scene = getattr(bpy.context, "scene", None)
    if scene is not None and scene.camera is not None:
        fogpipe_frame(scene)


def unregister():
    remove_handlers()
    panel = getattr(bpy.types, "RENDER_PT_stamp", None)
    if panel is not None:
        panel.remove(draw_metadata)
    del bpy.types.Scene.fogpipe
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)


def main(argv):
    """-P mode: register; with --fogpipe-shadow-maps [--frames A-B], render
    the sun's shadow maps (the rest of the command line, -a, records them)."""
    register()
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    if "--fogpipe-shadow-maps" in args:
        i = args.index("--frames") + 1 if "--frames" in args else len(args)
        made, err = shadow_maps_for(bpy.context.scene, args[i] if i < len(args) else None)
        if err:
            print(err, flush=True)
            sys.exit(1)


if __name__ == "__main__":
    main(sys.argv)
