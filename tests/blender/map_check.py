# tests/blender_addon.sh: the sun's shadow map against Blender's geometry.
#   blender -b scene.blend -S lights -P map_check.py -- FRAME INFO ZDUMP
# INFO: `oiiotool --info -v` of the map (its Note: the orthographic camera),
# ZDUMP: `oiiotool --dumpdata` of its depth.  For every 5th texel in x and y
# a ray from the texel's center on the camera's plane, along the camera's
# axis, is cast into the scene at FRAME: the map's depth is that ray's hit
# distance within 1e-3 m, or the map says no hit (>= 1e9) where it misses.
# A texel whose ray passes within 0.05 texel of an edge may differ (Cycles'
# sample lies within 0.005 texel of the center): at most 1% are allowed.
import re
import sys

import bpy
from mathutils import Matrix, Vector

frame, info, zdump = sys.argv[sys.argv.index("--") + 1:][:3]
note = ""
for line in open(info):
    m = re.match(r'^\s+Note: "(.*)"\s*$', line)
    if m:
        note = m.group(1)
toks = note.split()
i = toks.index("worldToCamera")
w2c = [float(x) for x in toks[i + 1:i + 17]]
i = toks.index("worldToNDC")
w2n = [float(x) for x in toks[i + 1:i + 17]]
# Row-vector matrices as column-vector mathutils ones.
W2C = Matrix([w2c[r * 4:r * 4 + 4] for r in range(4)]).transposed()
W2N = Matrix([w2n[r * 4:r * 4 + 4] for r in range(4)]).transposed()
assert abs(W2N[3][0]) + abs(W2N[3][1]) + abs(W2N[3][2]) < 1e-9, "not orthographic"
C2W = W2C.inverted()
K = W2N @ C2W                       # camera space -> NDC
axis = (C2W.to_3x3() @ Vector((0, 0, 1))).normalized()
z = {}
w = h = 0
for line in open(zdump):
    m = re.match(r"^\s*Pixel \((\d+), (\d+)\): *([^ ]+)", line)
    if m:
        x, y = int(m.group(1)), int(m.group(2))
        z[x, y] = float(m.group(3))
        w, h = max(w, x + 1), max(h, y + 1)
scene = bpy.context.scene
scene.frame_set(int(frame))
dg = bpy.context.evaluated_depsgraph_get()
n = bad = hits = 0
worst = 0.0
A = Matrix(((K[0][0], K[0][1]), (K[1][0], K[1][1]))).inverted()
for y in range(0, h, 5):
    for x in range(0, w, 5):
        u, v = (x + 0.5) / w, (y + 0.5) / h
        cx, cy = A @ Vector((u - K[0][3], v - K[1][3]))
        origin = C2W @ Vector((cx, cy, 0.0))
        hit, loc, _, _, _, _ = scene.ray_cast(dg, origin, axis)
        n += 1
        if hit:
            hits += 1
            d = (loc - origin).length
            err = abs(z[x, y] - d)
            worst = max(worst, err if err < 1 else 0)
            bad += err > 1e-3
        else:
            bad += z[x, y] < 1e9
print("MAPCHECK %d texels, %d hits, %d differ (worst agreeing %.2g m)" % (n, hits, bad, worst))
sys.exit(0 if n > 100 and hits > n // 4 and bad <= n // 100 else 1)
