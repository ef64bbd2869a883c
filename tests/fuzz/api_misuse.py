"""fogpipe fuzz harness: the Python module misused (tests/fuzz/fuzz.py
--mode api), one case a process:

  api_misuse.py CASE    exit 0: the module coped (fogpipe.Error, TypeError
                        or ValueError with a one-line message, or the work
                        done); 1: it did not; 77: skipped (no numpy).

PYTHONPATH and FOGPIPE_LIBRARY point at the build's module and library;
FP_FIXTURES at the harness's fixtures (scene.0001.exr)."""
import os
import struct
import sys
import threading
import time

try:
    import numpy as np
except ImportError:
    print("numpy is not installed", file=sys.stderr)
    sys.exit(77)
import fogpipe

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import exrfile  # noqa: E402

failed = []
REFUSALS = (fogpipe.Error, TypeError, ValueError)
OPTS = dict(cpu=True, camera_pos="0,2,10", vfov=40)


def expect(cond, what):
    if not cond:
        failed.append(what)
        print("api_misuse.py: " + what, file=sys.stderr)


def refused(what, fn, must_say=None):
    """fn() must raise one of REFUSALS with a one-line message (mentioning
    must_say when given)."""
    try:
        fn()
    except REFUSALS as e:
        m = str(e)
        expect(m and "\n" not in m, "%s: message %r" % (what, m))
        if must_say:
            expect(must_say in m.lower(), "%s: message %r does not say %r" % (what, m, must_say))
        return
    except Exception as e:  # noqa: BLE001 - any other exception is the finding
        expect(False, "%s: raised %s: %s" % (what, type(e).__name__, e))
        return
    expect(False, "%s: accepted" % what)


def frame(h=12, w=16, dtype=np.float32):
    rgba = np.full((h, w, 4), 0.5, dtype=dtype)
    rgba[..., 3] = 1
    depth = (5 + np.arange(h * w) % 17).reshape(h, w).astype(dtype)
    return rgba, depth


def py_integer_arrays():
    """Integer arrays are not linear float values: refused, saying so."""
    with fogpipe.Context(**OPTS) as c:
        rgba, depth = frame()
        for dt in (np.uint8, np.uint16, np.int32, np.int64, np.bool_):
            refused("rgba of %s" % np.dtype(dt).name,
                    lambda: c.apply((rgba * 255).astype(dt), depth), "float")
            refused("depth of %s" % np.dtype(dt).name,
                    lambda: c.apply(rgba, depth.astype(dt)), "float")
        out = c.apply(rgba.astype(np.float64), depth.astype(np.float16))
        expect(out.dtype == np.float32 and np.isfinite(out).all(), "float64 / float16 arrays")


def py_bad_shapes():
    with fogpipe.Context(**OPTS) as c:
        rgba, depth = frame()
        refused("rgba HxWx3", lambda: c.apply(rgba[..., :3], depth))
        refused("depth of another size", lambda: c.apply(rgba, depth[:-1]))
        refused("empty", lambda: c.apply(rgba[:0], depth[:0]))
        refused("1-D rgba", lambda: c.apply(rgba.ravel(), depth))
        refused("None", lambda: c.apply(None, depth))
        refused("strings", lambda: c.apply(np.array([["a"]]), depth))
        refused("objects", lambda: c.apply(rgba.astype(object), depth))
        refused("camera 3x3", lambda: c.apply(rgba, depth, world_to_camera=np.eye(3)))
        out = c.apply(rgba[::-1, ::2].copy(order="F")[:, :8], depth[::-1, ::2][:, :8])
        expect(np.isfinite(out).all(), "a non-contiguous view")


def py_after_close():
    c = fogpipe.Context(**OPTS)
    rgba, depth = frame()
    c.apply(rgba, depth)
    c.close()
    refused("apply after close", lambda: c.apply(rgba, depth))
    refused("set after close", lambda: c.set(density=0.1))
    refused("run after close", lambda: c.run())
    c.close()


def py_close_during_apply():
    """Context.close() while another thread is inside apply: the close
    waits or is refused, never frees the context under the call.  Ten
    contexts, each closed at another moment of a thread's applies (a use
    after free crashes only some of the time)."""
    rgba, depth = frame(64, 64)
    errors = []
    for k in range(10):
        c = fogpipe.Context(sun="0,1,0.3", scatter_steps=32, **OPTS)

        def worker():
            for _ in range(50):
                try:
                    out = c.apply(rgba, depth)
                    if not np.isfinite(out).all():
                        errors.append("non-finite output")
                except REFUSALS:
                    return
                except Exception as e:  # noqa: BLE001
                    errors.append("%s: %s" % (type(e).__name__, e))
                    return

        t = threading.Thread(target=worker)
        t.start()
        time.sleep(0.002 * k)
        try:
            c.close()
        except REFUSALS:
            pass
        t.join()
        c.close()
    expect(not errors, "apply during close: %s" % errors)


def py_scaled_camera():
    """The fixture's camera, and the same projective camera scaled by
    1e300 and 1e-300: the same frame, or refused with the matrix's name."""
    fx = os.environ.get("FP_FIXTURES")
    if not fx:
        print("FP_FIXTURES is not set", file=sys.stderr)
        sys.exit(77)
    with open(os.path.join(fx, "scene.0001.exr"), "rb") as f:
        lay = exrfile.Layout(f.read())
    mats = []
    for name in ("worldToCamera", "worldToNDC"):
        a = lay.attr(name)
        fmt = "<16d" if a.type == "m44d" else "<16f"
        mats.append(np.array(struct.unpack_from(fmt, lay.data, a.value_at)).reshape(4, 4))
    rgba, depth = frame(24, 40)
    opts = dict(OPTS)
    del opts["camera_pos"], opts["vfov"]
    for cpu in (True, False):
        opts["cpu"] = cpu
        with fogpipe.Context(**opts) as c:
            ref = c.apply(rgba, depth, mats[0], mats[1])
            expect(np.isfinite(ref).all(), "the fixture's camera gives non-finite pixels")
            for k in (1e300, 1e-300):
                for i, name in enumerate(("world_to_camera", "world_to_ndc")):
                    m = [mats[0], mats[1]]
                    m[i] = m[i] * k
                    what = "%s scaled by %g (%s)" % (name, k, "cpu" if cpu else "OpenCL")
                    try:
                        out = c.apply(rgba, depth, m[0], m[1])
                    except REFUSALS as e:
                        expect("\n" not in str(e) and ("world" in str(e).lower()),
                               "%s: refused without naming the matrix: %s" % (what, e))
                        continue
                    bad = int((~np.isfinite(out)).sum())
                    expect(bad == 0, "%s: %d non-finite values" % (what, bad))
                    if bad == 0:
                        d = float(np.abs(out - ref).max())
                        expect(d < 1e-3, "%s: differs from the unscaled camera by %g" % (what, d))


def py_bad_options():
    refused("unknown option", lambda: fogpipe.Context(no_such_option=1))
    refused("density nan", lambda: fogpipe.Context(density="nan"))
    refused("density 1e400", lambda: fogpipe.Context(density="1e400"))
    refused("fog_color of 2", lambda: fogpipe.Context(fog_color="1,2"))
    refused("preset of a missing file", lambda: fogpipe.Context(preset="/nonexistent/x.preset"))


CASES = {f.__name__: f for f in (py_integer_arrays, py_bad_shapes, py_after_close,
                                 py_close_during_apply, py_scaled_camera, py_bad_options)}

if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] not in CASES:
        print("usage: api_misuse.py %s" % "|".join(CASES), file=sys.stderr)
        sys.exit(2)
    CASES[sys.argv[1]]()
    sys.exit(1 if failed else 0)
