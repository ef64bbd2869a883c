"""The Python module (python/fogpipe) against the command line: run by
tests/api.sh as  python3 tests/test_python.py FRAME.bin CLI.exr-made-by-the-test OUTDIR.
Prints TAP lines; exit 1 when one fails."""
import sys

import numpy as np

import fogpipe

frame_bin, outdir = sys.argv[1], sys.argv[2]
n = 0
failed = 0


def check(desc, fn):
    global n, failed
    n += 1
    try:
        fn()
        print("ok %d - %s" % (n, desc))
    except Exception as e:  # noqa: BLE001 - every failure is a TAP line
        failed += 1
        print("not ok %d - %s" % (n, desc))
        for line in ("%s: %s" % (type(e).__name__, e)).splitlines():
            print("# " + line)


def load(path):
    raw = open(path, "rb").read()
    w, h = np.frombuffer(raw, dtype=np.int32, count=2)
    m = np.frombuffer(raw, dtype=np.float64, count=32, offset=8)
    px = np.frombuffer(raw, dtype=np.float32, offset=8 + 256)
    rgba = px[: w * h * 4].reshape(h, w, 4)
    depth = px[w * h * 4: w * h * 5].reshape(h, w)
    return rgba, depth, m[:16].reshape(4, 4), m[16:].reshape(4, 4)


rgba, depth, w2c, w2n = load(frame_bin)
opts = dict(density=0.05, height=(0, 4), fog_color=(0.7, 0.72, 0.75))


def save(path, img):
    h, w = img.shape[:2]
    with open(path, "wb") as f:
        f.write(np.array([w, h], dtype=np.int32).tobytes())
        f.write(np.concatenate([w2c.ravel(), w2n.ravel()]).astype(np.float64).tobytes())
        f.write(np.ascontiguousarray(img, dtype=np.float32).tobytes())


def composite():
    out = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n, **opts)
    assert out.shape == rgba.shape and out.dtype == np.float32, (out.shape, out.dtype)
    assert not np.allclose(out, rgba), "no fog was added"
    save(outdir + "/py.bin", out)


check("fogpipe.apply: an HxWx4 float32 composite (compared with the CLI by api.sh)", composite)


def layers():
    out, fog, tau = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n,
                                  aov=True, **opts)
    assert fog.shape == rgba.shape and tau.shape == rgba.shape[:2] + (3,)
    over = fog[..., :3] + rgba[..., :3] * (1 - fog[..., 3:4])
    d = float(np.abs(over - out[..., :3]).max())
    print("# fog over plate vs composite: max |d| %.3g" % d)
    assert d <= 1e-5, d
    assert np.allclose(fog[..., 3], 1 - tau[..., 0], atol=1e-6)


check("aov=True: fog over the plate is the composite, fog.A = 1 - transmittance", layers)


def preset_wins():
    a = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n,
                      preset="night-street-lamps", density=0.01)
    b = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n,
                      preset="night-street-lamps")
    assert not np.array_equal(a, b), "density after the preset changed nothing"


check("preset= first, the other options win over it", preset_wins)


def raises(fn, text):
    try:
        fn()
    except fogpipe.Error as e:
        assert text in str(e), "message %r lacks %r" % (str(e), text)
        return
    raise AssertionError("no fogpipe.Error")


def apply_with(**kw):
    args = dict(rgba=rgba, depth=depth, world_to_camera=w2c, world_to_ndc=w2n)
    args.update(kw)
    return lambda: fogpipe.apply(**args)


check("wrong rgba shape raises", lambda: raises(apply_with(rgba=rgba[..., :3]), "rgba has shape"))
check("depth of another size raises", lambda: raises(apply_with(depth=depth[1:]), "depth has shape"))
check("a string array raises", lambda: raises(apply_with(depth=np.full(depth.shape, "x")), "dtype"))
check("a 3x3 matrix raises", lambda: raises(apply_with(world_to_ndc=np.eye(3)), "expected 4x4"))
check("an empty image raises", lambda: raises(
    apply_with(rgba=np.zeros((0, 4, 4), np.float32), depth=np.zeros((0, 4), np.float32)), "empty"))
check("an unknown option raises with the library's message",
      lambda: raises(apply_with(densty=0.1), "unknown option --densty"))
check("a value out of range raises with the library's message",
      lambda: raises(apply_with(density=-1), "--density: -1 is out of range"))
check("no camera raises (not a crash)", lambda: raises(
    lambda: fogpipe.apply(rgba, depth), "camera"))
check("float64 and non-contiguous arrays are accepted", lambda: fogpipe.apply(
    rgba.astype(np.float64)[:, ::-1], depth[:, ::-1], world_to_camera=w2c, world_to_ndc=w2n))


# Integer, bool and other non-float arrays are refused (an 8-bit image is not
# radiance 0-255): the message says what is expected.
for dt in (np.uint8, np.uint16, np.int32, np.bool_, np.complex64):
    check("rgba of dtype %s raises (expected linear float)" % np.dtype(dt).name,
          lambda dt=dt: raises(apply_with(rgba=(rgba * 255).astype(dt)), "expected linear float"))
check("integer depth raises", lambda: raises(apply_with(depth=np.zeros(depth.shape, np.int32)),
                                             "depth has dtype int32 (expected linear float"))
check("the message names the accepted dtypes", lambda: raises(
    apply_with(rgba=rgba.astype(np.uint8)), "float32, float64 or float16"))
check("float16 and big-endian float32 are accepted", lambda: (fogpipe.apply(
    rgba.astype(np.float16), depth.astype(np.float16), world_to_camera=w2c, world_to_ndc=w2n),
    fogpipe.apply(rgba.astype(">f4"), depth, world_to_camera=w2c, world_to_ndc=w2n)))


class _Spy:
    """libfogpipe's functions as the module calls them, with fogpipe_apply
    held inside for a while: whether fogpipe_free ran while it was."""

    def __init__(self, lib):
        import threading
        self.lib = lib
        self.inside = threading.Event()
        self.in_apply = 0
        self.overlap = False
        self.freed = set()

    def __getattr__(self, name):
        return getattr(self.lib, name)

    def fogpipe_apply(self, h, *args):
        import time
        self.in_apply += 1
        self.inside.set()
        time.sleep(0.3)
        try:
            if h.value in self.freed:   # the old module's use after free: not run here
                return 2
            return self.lib.fogpipe_apply(h, *args)
        finally:
            self.in_apply -= 1

    def fogpipe_free(self, h):
        if self.in_apply:
            self.overlap = True
        self.freed.add(h.value)
        return self.lib.fogpipe_free(h)


def close_during_apply():
    import threading
    spy = _Spy(fogpipe._lib)
    fogpipe._lib = spy
    try:
        ctx = fogpipe.Context(**opts)
        got = {}

        def worker():
            try:
                got["out"] = ctx.apply(rgba, depth, w2c, w2n)
            except Exception as e:  # noqa: BLE001
                got["error"] = e

        t = threading.Thread(target=worker)
        t.start()
        assert spy.inside.wait(10), "apply never started"
        ctx.close()
        t.join()
        assert not spy.overlap, "close() freed the context while apply was inside it"
        assert "out" in got, "the apply in progress failed: %r" % (got.get("error"),)
        assert np.isfinite(got["out"]).all()
    finally:
        fogpipe._lib = spy.lib


check("Context.close() while another thread is in apply waits for it", close_during_apply)


def closed_raises():
    ctx = fogpipe.Context(**opts)
    ctx.close()
    ctx.close()
    raises(lambda: ctx.apply(rgba, depth, w2c, w2n), "closed")
    raises(lambda: ctx.set(density=0.1), "closed")
    raises(lambda: ctx.run(), "closed")


check("calls after close() raise (closed), a second close() does nothing", closed_raises)


def close_race():
    import random
    import threading
    rng = random.Random(22)
    small = (rgba[:32, :48], depth[:32, :48])
    for _ in range(20):
        ctx = fogpipe.Context(**opts)
        errors = []

        def worker():
            for _ in range(50):
                try:
                    out = ctx.apply(small[0], small[1], w2c, w2n)
                    assert np.isfinite(out).all()
                except fogpipe.Error as e:
                    if "closed" not in str(e):
                        errors.append(e)
                    return

        ts = [threading.Thread(target=worker) for _ in range(3)]
        for t in ts:
            t.start()
        threading.Event().wait(rng.random() * 0.02)
        ctx.close()
        for t in ts:
            t.join()
        assert not errors, errors


check("three threads applying while a fourth closes: each apply a frame or 'closed'", close_race)


def scaled_camera():
    ref = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n, **opts)
    for a, b in ((1e300, 1), (1, 1e-300), (1e-300, 1e300)):
        out = fogpipe.apply(rgba, depth, world_to_camera=w2c * a, world_to_ndc=w2n * b, **opts)
        assert np.isfinite(out).all(), "non-finite pixels with scales %g, %g" % (a, b)
        d = float(np.abs(out - ref).max())
        assert d <= 1e-5, (a, b, d)


check("the camera matrices times 1e300 or 1e-300: the same frame, finite", scaled_camera)
check("a worldToNDC of NaN raises with its name", lambda: raises(
    apply_with(world_to_ndc=np.full((4, 4), np.nan)), "worldToNDC has a non-finite element"))



def deep():
    # the deep result composited front to back is the flat composite
    counts, offsets, srgba, z, zb = fogpipe.Context(**opts).apply_deep(
        rgba, depth, world_to_camera=w2c, world_to_ndc=w2n)
    flat = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n, **opts)
    assert counts.shape == depth.shape and offsets[-1] == len(z) == len(srgba)
    worst = 0.0
    for i in range(0, counts.size, 7):
        c = np.zeros(4)
        for k in range(offsets[i], offsets[i + 1]):
            assert zb[k] >= z[k] and (k == offsets[i] or z[k] >= zb[k - 1])
            c += (1 - c[3]) * srgba[k]
        worst = max(worst, float(np.abs(c[:3] - flat.reshape(-1, 4)[i, :3]).max()))
    print("# deep result flattened vs apply: max |d| %.3g, %.1f samples a pixel"
          % (worst, len(z) / counts.size))
    assert worst <= 1e-4, worst


check("Context.apply_deep: tidy samples that composite to apply's frame", deep)

print("1..%d" % n)
sys.exit(1 if failed else 0)
