"""fogpipe: physically based fog for rendered images, from Python.

A thin ctypes layer over libfogpipe (fogpipe.h): the same options, values
and messages as the fogpipe command line.

    import numpy as np, fogpipe
    out = fogpipe.apply(rgba, depth, world_to_camera=w2c, world_to_ndc=w2n,
                        density=0.05, height=(0, 4), fog_color=(0.7, 0.72, 0.75))
    out, fog, tau = fogpipe.apply(rgba, depth, ..., aov=True)
    fogpipe.apply_file("shot.####.exr", "fogged.####.exr", frames="1-10",
                       preset="low-sun-shafts")

Options are the command line's long options with "-" written "_"; a value
is a number, a string, a bool (a flag) or a sequence (joined by commas).
`preset` is applied first, the other options after it (they win).  Bad
arrays or options raise fogpipe.Error with the library's message.
"""

import ctypes
import ctypes.util
import os
import threading

import numpy as np

__all__ = ["apply", "apply_file", "version", "Error", "Context"]


class Error(RuntimeError):
    """A fogpipe call failed; the message is the library's."""


def _load():
    tried = []
    env = os.environ.get("FOGPIPE_LIBRARY")
    if env:
        tried.append(env)
    try:
        from . import _config  # written by make install
        tried.append(_config.LIBRARY)
    except ImportError:
        pass
    found = ctypes.util.find_library("fogpipe")
    if found:
        tried.append(found)
    tried.append("libfogpipe.so.0")
    errors = []
    for name in tried:
        try:
            return ctypes.CDLL(name)
        except OSError as e:
            errors.append(str(e))
    raise ImportError("fogpipe: cannot load libfogpipe (tried %s): %s"
                      % (", ".join(tried), "; ".join(errors)))


_lib = _load()
_c_float_p = ctypes.POINTER(ctypes.c_float)
_c_double_p = ctypes.POINTER(ctypes.c_double)


def _is_float(dtype):
    """float16, float32 or float64, in either byte order."""
    return dtype.kind == "f" and dtype.itemsize in (2, 4, 8)


class _Frame(ctypes.Structure):
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int),
                ("rgba", _c_float_p), ("depth", _c_float_p),
                ("world_to_camera", _c_double_p), ("world_to_ndc", _c_double_p),
                ("frame", ctypes.c_long), ("name", ctypes.c_char_p)]


_lib.fogpipe_new.argtypes = [ctypes.POINTER(ctypes.c_void_p)]
_lib.fogpipe_new.restype = ctypes.c_int
_lib.fogpipe_free.argtypes = [ctypes.c_void_p]
_lib.fogpipe_free.restype = None
_lib.fogpipe_error.argtypes = [ctypes.c_void_p]
_lib.fogpipe_error.restype = ctypes.c_char_p
_lib.fogpipe_version.argtypes = []
_lib.fogpipe_version.restype = ctypes.c_char_p
_lib.fogpipe_set.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_char_p,
                             ctypes.c_char_p]
_lib.fogpipe_set.restype = ctypes.c_int
_lib.fogpipe_apply.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Frame), _c_float_p,
                               _c_float_p, _c_float_p]
_lib.fogpipe_apply.restype = ctypes.c_int


class _Deep(ctypes.Structure):
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int),
                ("counts", ctypes.POINTER(ctypes.c_uint)),
                ("offsets", ctypes.POINTER(ctypes.c_ulonglong)),
                ("total", ctypes.c_ulonglong), ("rgba", _c_float_p),
                ("z", _c_float_p), ("zback", _c_float_p)]


_lib.fogpipe_apply_deep.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Frame),
                                    ctypes.POINTER(ctypes.POINTER(_Deep))]
_lib.fogpipe_apply_deep.restype = ctypes.c_int
_lib.fogpipe_deep_free.argtypes = [ctypes.POINTER(_Deep)]
_lib.fogpipe_deep_free.restype = None
_lib.fogpipe_run.argtypes = [ctypes.c_void_p, ctypes.c_int]
_lib.fogpipe_run.restype = ctypes.c_int


def version():
    """The library's version string."""
    return _lib.fogpipe_version().decode()


def _value(v):
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, (str, bytes)):
        return v if isinstance(v, str) else v.decode()
    if isinstance(v, np.ndarray):
        v = v.ravel().tolist()
    if isinstance(v, (list, tuple)):
        return ",".join(_value(x) for x in v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        return repr(float(v)) if isinstance(v, (float, np.floating)) else str(int(v))
    raise Error("fogpipe: option value %r: expected a number, a string, a bool or a "
                "sequence of them" % (v,))


class Context:
    """A libfogpipe context: options set once, frames applied many times
    (the device, programs and fogmap are kept between frames).

    Threads: calls on one context from several threads run one at a time
    (the library's lock).  close() waits for the calls in progress on other
    threads to return, then frees the context; calls made after it, or
    that start while it waits, raise fogpipe.Error ("closed")."""

    def __init__(self, **options):
        self._cv = threading.Condition()
        self._busy = 0          # calls in progress with the handle
        self._closing = False
        self._h = None
        h = ctypes.c_void_p()
        if _lib.fogpipe_new(ctypes.byref(h)) != 0:
            raise MemoryError("fogpipe: cannot make a context")
        self._h = h
        self.set(**options)

    def close(self):
        """Free the context, after the calls in progress return."""
        cv = getattr(self, "_cv", None)
        if cv is None:          # __init__ did not get that far
            return
        with cv:
            if self._h is None:
                return
            self._closing = True
            while self._busy:
                cv.wait()
            h, self._h = self._h, None
        _lib.fogpipe_free(h)

    def __del__(self):
        self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _call(self, fn, *args):
        """fn(handle, *args) with the handle held against close(); raises
        with the library's message when it fails."""
        with self._cv:
            if self._h is None or self._closing:
                raise Error("fogpipe: the Context is closed")
            self._busy += 1
            h = self._h
        try:
            rc = fn(h, *args)
            if rc != 0:
                raise Error(_lib.fogpipe_error(h).decode(errors="replace"))
        finally:
            with self._cv:
                self._busy -= 1
                if not self._busy:
                    self._cv.notify_all()

    def set(self, **options):
        """Set options by the command line's long names, "-" written "_"."""
        items = list(options.items())
        items.sort(key=lambda kv: kv[0] != "preset")  # the preset first
        for name, value in items:
            if value is None:
                continue
            opt = name.replace("_", "-")
            self._call(_lib.fogpipe_set, opt.encode(), _value(value).encode(),
                       ("fogpipe: %s=%r" % (name, value)).encode())

    def _frame(self, rgba, depth, world_to_camera, world_to_ndc, frame):
        """The arrays checked and held as a _Frame (with the arrays that
        must live as long as it)."""
        rgba = np.asarray(rgba)
        depth = np.asarray(depth)
        if rgba.ndim != 3 or rgba.shape[2] != 4:
            raise Error("fogpipe.apply: rgba has shape %s (expected height x width x 4)"
                        % (rgba.shape,))
        h, w = rgba.shape[:2]
        if depth.shape != (h, w):
            raise Error("fogpipe.apply: depth has shape %s (expected %s, the rgba's height "
                        "and width)" % (depth.shape, (h, w)))
        if h < 1 or w < 1:
            raise Error("fogpipe.apply: an empty image (%dx%d)" % (w, h))
        # Pixels are scene-linear radiance: an integer image (8-bit sRGB,
        # 16-bit) is not, and is refused rather than read as 0-255.
        for n, a in (("rgba", rgba), ("depth", depth)):
            if not _is_float(a.dtype):
                raise Error("fogpipe.apply: %s has dtype %s (expected linear float: float32, "
                            "float64 or float16; convert integer or display-referred images "
                            "to scene-linear float first)" % (n, a.dtype))
        rgba = np.ascontiguousarray(rgba, dtype=np.float32)
        depth = np.ascontiguousarray(depth, dtype=np.float32)
        mats = []
        for n, m in (("world_to_camera", world_to_camera), ("world_to_ndc", world_to_ndc)):
            if m is None:
                mats.append(None)
                continue
            m = np.ascontiguousarray(m, dtype=np.float64)
            if m.shape != (4, 4) and m.shape != (16,):
                raise Error("fogpipe.apply: %s has shape %s (expected 4x4)" % (n, m.shape))
            mats.append(m)
        fr = _Frame()
        fr.width, fr.height = w, h
        fr.rgba = rgba.ctypes.data_as(_c_float_p)
        fr.depth = depth.ctypes.data_as(_c_float_p)
        fr.world_to_camera = mats[0].ctypes.data_as(_c_double_p) if mats[0] is not None else None
        fr.world_to_ndc = mats[1].ctypes.data_as(_c_double_p) if mats[1] is not None else None
        fr.frame = int(frame)
        fr.name = b"<numpy>"
        return fr, (rgba, depth, mats), h, w

    def apply(self, rgba, depth, world_to_camera=None, world_to_ndc=None, frame=1, aov=False):
        """Fog one frame: rgba HxWx4 and depth HxW, scene-linear float
        (float32; float64 and float16 are converted, other dtypes refused),
        the camera as OpenEXR's 4x4 worldToCamera and worldToNDC (row
        vectors), or from the options.  Returns the composite (HxWx4
        float32), and with aov=True also the fog layer (HxWx4: light, and
        alpha 1 - transmittance) and the transmittance (HxWx3)."""
        fr, keep, h, w = self._frame(rgba, depth, world_to_camera, world_to_ndc, frame)
        out = np.empty((h, w, 4), dtype=np.float32)
        fog = np.empty((h, w, 4), dtype=np.float32) if aov else None
        tau = np.empty((h, w, 3), dtype=np.float32) if aov else None
        self._call(_lib.fogpipe_apply, ctypes.byref(fr), out.ctypes.data_as(_c_float_p),
                   fog.ctypes.data_as(_c_float_p) if aov else None,
                   tau.ctypes.data_as(_c_float_p) if aov else None)
        return (out, fog, tau) if aov else out

    def apply_deep(self, rgba, depth, world_to_camera=None, world_to_ndc=None, frame=1):
        """The fog of one frame as deep samples, as --deep writes them
        (README "Deep compositing"): returns (counts HxW uint32, offsets
        H*W+1 uint64: pixel i's samples are offsets[i]..offsets[i+1], rgba
        Nx4 premultiplied, z N, zback N), sorted and not overlapping per
        pixel, the surface's sample last."""
        fr, keep, h, w = self._frame(rgba, depth, world_to_camera, world_to_ndc, frame)
        d = ctypes.POINTER(_Deep)()
        self._call(_lib.fogpipe_apply_deep, ctypes.byref(fr), ctypes.byref(d))
        try:
            n, t = h * w, d.contents.total
            counts = np.ctypeslib.as_array(d.contents.counts, (n,)).reshape(h, w).copy()
            offsets = np.ctypeslib.as_array(d.contents.offsets, (n + 1,)).copy()
            rgba_s = np.ctypeslib.as_array(d.contents.rgba, (max(t, 1) * 4,))[:t * 4].reshape(t, 4).copy()
            z = np.ctypeslib.as_array(d.contents.z, (max(t, 1),))[:t].copy()
            zb = np.ctypeslib.as_array(d.contents.zback, (max(t, 1),))[:t].copy()
        finally:
            _lib.fogpipe_deep_free(d)
        return counts, offsets, rgba_s, z, zb

    def run(self):
        """Run the options' files or streams (input, output, frames...)."""
        self._call(_lib.fogpipe_run, 0)


def apply(rgba, depth, world_to_camera=None, world_to_ndc=None, frame=1, aov=False, **options):
    """Fog one frame held in NumPy arrays with the given options (see
    Context.apply); returns the composite, or (composite, fog, transmittance)
    with aov=True."""
    with Context(**options) as c:
        return c.apply(rgba, depth, world_to_camera, world_to_ndc, frame=frame, aov=aov)


def apply_file(input, output, **options):
    """Fog files or sequences ("shot.####.exr") as the command line does."""
    with Context(input=input, output=output, **options) as c:
        c.run()
