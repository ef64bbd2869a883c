#!/usr/bin/env python3
"""Issue 28: fogpipe's fast path (single scattering plus the plane-parallel
multiple scattering, no fog color) against Cycles' fog light.

  msfast_compare.py CYC_A.exr CYC_B.exr FP.exr [MAXBIAS [BLOCKS]]

CYC_*: tests/blender/ms_scene.py's renders of one frame (two seeds;
ViewLayer.VolumeDir + ViewLayer.VolumeInd is the fog's light), FP:
fogpipe's output on the black plate (its first channel is the fog's
light).  Red channel only (the scene is white).  Prints the means, the
bias (fogpipe / Cycles - 1, over all pixels), and the rms over 8x8-pixel
blocks of fogpipe - Cycles against Cycles' own noise there (the rms over
blocks of (A - B) / 2: the noise of the two seeds' mean).  With MAXBIAS:
exits 1 (a MISS line) when |bias| > MAXBIAS or the block rms > BLOCKS
(default 3) times Cycles' noise."""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ms_compare import channels, first  # noqa: E402


def blocks(vals, w, h, n=8):
    """Means of n x n blocks (whole blocks only)."""
    out = []
    for by in range(0, h - n + 1, n):
        for bx in range(0, w - n + 1, n):
            s = 0.0
            for y in range(by, by + n):
                s += sum(vals[y * w + bx:y * w + bx + n])
            out.append(s / (n * n))
    return out


def size(path):
    import subprocess
    out = subprocess.run(["oiiotool", "--info", path], check=True, capture_output=True,
                         text=True).stdout
    dims = out.split(":", 1)[1].split(",")[0].strip().split("x")
    return int(dims[0]), int(dims[1])


def main():
    if len(sys.argv) not in (4, 5, 6):
        raise SystemExit(__doc__)
    ca, cb, fpath = sys.argv[1:4]
    maxbias = float(sys.argv[4]) if len(sys.argv) >= 5 else None
    maxblk = float(sys.argv[5]) if len(sys.argv) == 6 else 3.0
    w, h = size(fpath)
    dA, iA = (channels(ca, [c])[0] for c in ["ViewLayer.VolumeDir.R", "ViewLayer.VolumeInd.R"])
    dB, iB = (channels(cb, [c])[0] for c in ["ViewLayer.VolumeDir.R", "ViewLayer.VolumeInd.R"])
    f = channels(fpath, [first(fpath)])[0]
    ta = [a + b for a, b in zip(dA, iA)]
    tb = [a + b for a, b in zip(dB, iB)]
    cyc = [(a + b) / 2 for a, b in zip(ta, tb)]
    mc, mf = sum(cyc) / len(cyc), sum(f) / len(f)
    ms = sum((a + b) / 2 for a, b in zip(iA, iB)) / len(iA)
    bias = mf / mc - 1
    bc, bf = blocks(cyc, w, h), blocks(f, w, h)
    bn = blocks([(a - b) / 2 for a, b in zip(ta, tb)], w, h)
    rms = math.sqrt(sum((x - y) ** 2 for x, y in zip(bf, bc)) / len(bc))
    noise = math.sqrt(sum(x * x for x in bn) / len(bn))
    print("cycles total %.6g (multiple %.6g)  fogpipe %.6g  bias %+.4f  "
          "block rms %.4g = %.2f x cycles' noise %.4g (%.2f%% of the fog)"
          % (mc, ms, mf, bias, rms, rms / noise if noise > 0 else math.inf, noise,
             100 * rms / mc))
    if maxbias is not None:
        bad = abs(bias) > maxbias or rms > maxblk * noise
        if bad:
            print("MISS: |bias| %.4f (at most %.4f), block rms %.2f x noise (at most %.1f)"
                  % (abs(bias), maxbias, rms / noise if noise > 0 else math.inf, maxblk))
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
