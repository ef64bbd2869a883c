# tests/blender.sh: Cycles renders the fog itself, for fogpipe to match.
#   blender -b scene.blend -S auto|ortho -noaudio -P fogpipe_blender/__init__.py -P tests/blender/absorb.py -- OUTDIR SIGMA
# On the scene (auto or ortho: 64x48, frame 1 only) the ground and the box are made
# purely emissive (known colors, no lighting, so no noise) and the world
# black; Cycles renders frame 1 twice, with the add-on:
#   OUTDIR/plate.0001.exr  no world volume: the plate;
#   OUTDIR/cycles.0001.exr the world with a homogeneous Volume Absorption
#                          of density SIGMA (1/m): Cycles' own fog, the
#                          plate times exp(-SIGMA * distance along the ray);
#                          black where rays leave the scene.
# Absorption alone needs no volume bounce: Cycles attenuates the camera
# ray through a homogeneous volume by exp(-sigma t) in closed form, with
# volume, diffuse and transparent bounces all 0 (set so that nothing but
# that attenuation reaches the image), so one sample is exact.  One sample
# and the 0.01 px pixel filter of scene.py also make the color and the
# depth pass come from the same ray through the pixel's center: with 4
# samples, a few pixels (8 of 3072, edges of the box among them) mix rays
# the depth pass does not show, up to 1e-3 off on the ground and 0.06 on
# the box's edges.
import os
import sys

import bpy

argv = sys.argv[sys.argv.index("--") + 1:]
outdir, sigma = argv[0], float(argv[1])
scene = bpy.context.scene
os.makedirs(outdir, exist_ok=True)


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
    return m


COLORS = {"Plane": (0.8, 0.6, 0.4), "Cube": (0.3, 0.5, 0.9)}
for o in scene.objects:
    if o.type == 'MESH':
        o.data.materials.clear()
        o.data.materials.append(emissive("emit_" + o.name, COLORS[o.name.split(".")[0]]))
    elif o.type == 'LIGHT':
        o.hide_render = True

world = bpy.data.worlds.new("absorbing")
world.use_nodes = True
nt = world.node_tree
nt.nodes.clear()
bg = nt.nodes.new('ShaderNodeBackground')
bg.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
bg.inputs['Strength'].default_value = 0.0
wout = nt.nodes.new('ShaderNodeOutputWorld')
nt.links.new(bg.outputs['Background'], wout.inputs['Surface'])
world.cycles.homogeneous_volume = True
scene.world = world

c = scene.cycles
c.samples = 1
c.use_denoising = False
c.filter_width = 0.01
c.volume_bounces = 0
c.max_bounces = 0
c.transparent_max_bounces = 0
scene.frame_start = scene.frame_end = 1
# Cycles starts camera rays on the near clip plane, and the world volume
# with them: with Blender's default clip_start of 0.1 m its fog is that of
# a ray 0.1/cos(angle off the axis) shorter (1% more transmittance here at
# SIGMA 0.1).  fogpipe's fog starts at the camera, as the offline
# renderer's does with the clip plane at the camera: 1e-4 m.
scene.camera.data.clip_start = 1e-4

scene.render.filepath = os.path.join(outdir, "plate.####")
bpy.ops.render.render(animation=True)

absorb = nt.nodes.new('ShaderNodeVolumeAbsorption')
# Cycles absorbs (1 - Color) * Density per meter: black absorbs SIGMA in
# every channel.
absorb.inputs['Color'].default_value = (0.0, 0.0, 0.0, 1.0)
absorb.inputs['Density'].default_value = sigma
nt.links.new(absorb.outputs['Volume'], wout.inputs['Volume'])
scene.render.filepath = os.path.join(outdir, "cycles.####")
bpy.ops.render.render(animation=True)
