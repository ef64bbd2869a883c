#!/usr/bin/env python3
"""Issue 28: fogpipe's reference against Cycles' single and multiple
scattering (doc/notes/multiple-scattering.md).

  ms_compare.py CYC_A.exr CYC_B.exr FP1_A.exr FP1_B.exr FPN_A.exr FPN_B.exr [MAXBIAS]

CYC_*: tests/blender/ms_scene.py's renders (two seeds), MultiLayer with
ViewLayer.VolumeDir (single scattering), ViewLayer.VolumeInd (the rest)
and ViewLayer.Depth.Z; FP1_*: fogpipe --integrator reference --bounces 0
of the black plate (two seeds), FPN_*: the same with --bounces N.  The
fogpipe images' first channel is the fog's light (the plate is black).
Prints, over all pixels, over the geometry (Cycles' depth finite) and the
sky: the means of single (S1) and multiple (SM = total - single) for
both, fogpipe/Cycles - 1, and the noise of that ratio (two seeds each).
Red channel only (the scene is white).  With MAXBIAS: exits 1 (a MISS
line) when, over all pixels, single or multiple differ by more than
max(MAXBIAS, 3 x the noise) (relative)."""
import math
import os
import subprocess
import sys
import tempfile


def channels(path, names):
    """The named channels of PATH as lists, row-major (oiiotool --dumpdata)."""
    with tempfile.TemporaryDirectory() as tmp:
        cut = os.path.join(tmp, "ch.exr")
        subprocess.run(["oiiotool", path, "--ch", ",".join(names), "-o", cut], check=True)
        out = subprocess.run(["oiiotool", "--dumpdata", cut], check=True, capture_output=True,
                             text=True).stdout
    cols = [[] for _ in names]
    for line in out.splitlines():
        line = line.strip()
        if not line.startswith("Pixel ("):
            continue
        vals = line.split(":", 1)[1].split()
        for i, v in enumerate(vals[:len(names)]):
            cols[i].append(float(v))
    return cols


def first(path):
    out = subprocess.run(["oiiotool", "--info", "-v", path], check=True, capture_output=True,
                         text=True).stdout
    for line in out.splitlines():
        if "channel list:" in line:
            return line.split(":", 1)[1].split(",")[0].strip()
    raise SystemExit("%s: no channel list" % path)


def main():
    if len(sys.argv) not in (7, 8):
        raise SystemExit(__doc__)
    ca, cb, f1a, f1b, fna, fnb = sys.argv[1:7]
    maxbias = float(sys.argv[7]) if len(sys.argv) == 8 else None
    bad = 0
    names = ["ViewLayer.VolumeDir.R", "ViewLayer.VolumeInd.R", "ViewLayer.Depth.Z"]
    # One channel at a time: OpenEXR stores channels sorted by name.
    dA, iA, z = (channels(ca, [c])[0] for c in names)
    dB, iB = (channels(cb, [c])[0] for c in names[:2])
    fp = [channels(p, [first(p)])[0] for p in (f1a, f1b, fna, fnb)]
    n = len(z)
    if any(len(c) != n for c in (dA, iA, dB, iB) + tuple(fp)):
        raise SystemExit("images differ in size")
    geo = [i for i in range(n) if z[i] < 1e9]
    sky = [i for i in range(n) if z[i] >= 1e9]

    def est(a, b, idx):
        """Mean of (a + b) / 2 over idx and its standard error."""
        if not idx:
            return float("nan"), float("nan")
        m = sum(a[i] + b[i] for i in idx) / (2 * len(idx))
        dd = [(a[i] - b[i]) / 2 for i in idx]
        md = sum(dd) / len(dd)
        var = sum((d - md) ** 2 for d in dd) / max(1, len(dd) - 1)
        return m, math.sqrt(var / len(dd))

    sm_a = [fp[2][i] - fp[0][i] for i in range(n)]
    sm_b = [fp[3][i] - fp[1][i] for i in range(n)]
    for label, idx in (("all", list(range(n))), ("geometry", geo), ("sky", sky)):
        for part, cyc, ref in (("single", (dA, dB), (fp[0], fp[1])),
                               ("multiple", (iA, iB), (sm_a, sm_b))):
            mc, sc = est(cyc[0], cyc[1], idx)
            mf, sf = est(ref[0], ref[1], idx)
            if not (mc > 0):
                print("%-8s %-8s pixels %5d  cycles %.6g  fogpipe %.6g" % (label, part, len(idx),
                                                                          mc, mf))
                continue
            rel = mf / mc - 1
            noise = math.hypot(sc / mc, sf / mc) if mf > 0 else float("nan")
            print("%-8s %-8s pixels %5d  cycles %.6g  fogpipe %.6g  fogpipe/cycles-1 %+.4f "
                  "(noise %.4f)" % (label, part, len(idx), mc, mf, rel, noise))
            if maxbias is not None and label == "all" and not abs(rel) <= max(maxbias, 3 * noise):
                print("MISS %s scattering: fogpipe/cycles-1 %+.4f, allowed %.4f" %
                      (part, rel, max(maxbias, 3 * noise)))
                bad = 1
    sys.exit(bad)


if __name__ == "__main__":
    main()
