# The set-up the Cycles scene scripts share (light_scene.py, ms_scene.py):
# a black world, a camera keyed per frame, Cycles on the CPU with nothing
# that adapts or clamps, and one render call.  Import after the script has
# put its own folder on sys.path (blender -P does not).
import os

import bpy
from mathutils import Vector


def black_world(scene):
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs['Strength'].default_value = 0.0
    scene.world = world


def keyed_camera(scene, keys, clip):
    """A camera at each frame f = 1, 2, ... of keys [(location, target, lens)]."""
    cd = bpy.data.cameras.new("cam")
    cd.sensor_fit = 'AUTO'
    cd.clip_start = clip
    cd.clip_end = 1000.0
    cam = bpy.data.objects.new("cam", cd)
    scene.collection.objects.link(cam)
    scene.camera = cam
    for f, (loc, target, lens) in enumerate(keys, start=1):
        cam.location = loc
        cam.rotation_euler = (Vector(target) - Vector(loc)).to_track_quat('-Z', 'Y').to_euler()
        cd.lens = lens
        cam.keyframe_insert("location", frame=f)
        cam.keyframe_insert("rotation_euler", frame=f)
        cd.keyframe_insert("lens", frame=f)
    return cam


def cycles_cpu(scene, width, height, threads=2):
    """Cycles on the CPU, deterministic and unbiased: no denoising, no
    adaptive sampling, no clamping, no light threshold, a fixed seed, a
    point-like pixel filter; the Z pass on.  Bounces are the caller's."""
    r = scene.render
    r.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.filter_width = 0.01
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.use_animated_seed = False
    c.volume_max_steps = 1024
    r.threads_mode = 'FIXED'
    r.threads = threads
    r.use_persistent_data = True
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    scene.view_layers[0].use_pass_z = True
    return c


def render(scene, outdir, name, first, last, fmt):
    """Frames first..last to OUTDIR/name.####.exr, 32-bit float."""
    r = scene.render
    scene.frame_start, scene.frame_end = first, last
    r.image_settings.file_format = fmt
    r.image_settings.color_depth = '32'
    r.filepath = os.path.join(outdir, name + ".####")
    bpy.ops.render.render(animation=True)
