"""fogpipe fuzz harness: the size-limit suite and the API misuse cases
(tests/fuzz/fuzz.py runs them).

Size limits: headers that claim huge images, in every compression, tiled
and multipart EXR, PNG/TIFF/JPEG fogmaps (their headers edited), endless
and huge text inputs.  Each must be refused (exit 1 or 2, one line naming
the file) within SIZE_SECONDS of CPU time (user + system: the figure
holds on a loaded machine) with a peak RSS under SIZE_MB and no
out-of-memory message: refused from the header, before anything of that
size is allocated or decoded.

API misuse: tests/fuzz/api_misuse (C, the public header) and
tests/fuzz/api_misuse.py (the Python module), one case a process; a case
passes when it exits 0 in time (a signal, a sanitizer report or a hang
fails it)."""
import os
import re

import exrfile
import mutate

SIZE_MB = 200
SIZE_SECONDS = 2.0
COMPRESSIONS = ["none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"]
SANITIZER = re.compile(r"ERROR: (Address|Leak|Thread)Sanitizer|runtime error:")
OOM = re.compile(r"out of memory|std::bad_alloc|cannot allocate|RSS limit", re.I)

API_C = ["null_args", "wrong_sizes", "freed_argv", "free_during_apply", "reentrant_handler",
         "handler_new_context", "new_free_cycles", "bad_matrices"]
API_PY = ["py_integer_arrays", "py_bad_shapes", "py_after_close", "py_close_during_apply",
          "py_scaled_camera", "py_bad_options"]


def _size_cases(env, fx):
    """(name, argv, files the message may name, file to write or None)."""
    d = fx["_dir"]
    work = os.path.join(env.dir, "size")
    os.makedirs(work, exist_ok=True)
    scene = os.path.join(d, "scene.0001.exr")
    base = [env.fogpipe, "-q", "--cpu"]
    cases = []

    def exr_case(name, src, x1, y1, part=0):
        p = os.path.join(work, name + ".exr")
        with open(p, "wb") as f:
            f.write(exrfile.set_data_window(fx[src], x1, y1, part))
        cases.append((name, base + ["-i", p, "-o", os.path.join(work, "out.exr")],
                      [os.path.basename(p)]))

    for c in COMPRESSIONS:
        exr_case("%s_100000x100000" % c, "sl_%s.1.exr" % c, 99999, 99999)
        exr_case("%s_1000000x40" % c, "sl_%s.1.exr" % c, 999999, 39)
    exr_case("b44_65536x32768", "sl_b44.1.exr", 65535, 32767)
    exr_case("b44a_65536x32768", "sl_b44a.1.exr", 65535, 32767)
    exr_case("dwaa_12000000x40", "sl_dwaa.1.exr", 11999999, 39)
    exr_case("oiio_b44_100000x100000", "oiio_b44.exr", 99999, 99999)
    for c in ("zip", "dwab", "b44a"):
        exr_case("tiled_%s_100000x100000" % c, "tl_%s.exr" % c, 99999, 99999)
    exr_case("multipart_dwaa_part2_100000x100000", "mp_dwaa.exr", 99999, 99999, part=1)
    exr_case("multipart_zip_100000x100000", "mp_zip.exr", 99999, 99999)
    for ext in ("png", "tif", "jpg"):
        for w, h in ((30000, 30000), (100000, 100000)):
            p = os.path.join(work, "fog%dx%d.%s" % (w, h, ext))
            with open(p, "wb") as f:
                f.write(mutate.image_dims(ext, fx["fogmap." + ext], w, h))
            cases.append(("fogmap_%s_%dx%d" % (ext, w, h),
                          base + ["-i", scene, "-o", os.path.join(work, "out.exr"), "--fogmap", p],
                          [os.path.basename(p)]))
    for opt in ("--camera-chan", "--preset", "--fogmap"):
        cases.append(("endless%s" % opt.replace("--", "_"),
                      base + ["-i", scene, "-o", os.path.join(work, "out.exr"), opt, "/dev/zero"],
                      ["/dev/zero"]))
    big = os.path.join(work, "long.chan")
    with open(big, "wb") as f:
        f.write(b"1 0 2 -10 0 180 0 45" + b" " * (8 << 20) + b"\n")
    cases.append(("chan_one_8MB_line", base + ["-i", scene, "-o", os.path.join(work, "out.exr"),
                                               "--camera-chan", big], ["long.chan"]))
    # 1 GB of zeros, sparse (no disk): a huge file, not an endless one
    for ext, opt in (("chan", "--camera-chan"), ("preset", "--preset")):
        p = os.path.join(work, "huge." + ext)
        with open(p, "wb") as f:
            f.truncate(1 << 30)
        cases.append(("%s_1GB" % ext, base + ["-i", scene, "-o", os.path.join(work, "out.exr"),
                                              opt, p], [os.path.basename(p)]))
    return cases, os.path.join(work, "out.exr")


def fuzz_lines(text):
    return text[:-1].split("\n") if text.endswith("\n") else text.split("\n") if text else []


def size_suite(env, run, report, fx):
    cases, out = _size_cases(env, fx)
    results = []
    for name, argv, names in cases:
        if os.path.exists(out):
            os.remove(out)
        r = run(env, argv, timeout=5)
        lines = fuzz_lines(r.err)
        why = []
        if r.hung:
            why.append("hung (killed after 5 s)")
        elif r.sig:
            why.append("signal %d" % r.sig)
        elif r.rc == 0:
            why.append("exit 0 (accepted)")
        elif r.rc not in (1, 2):
            why.append("exit %d" % r.rc)
        if SANITIZER.search(r.err):
            why.append("sanitizer report")
        if r.rss > SIZE_MB << 20:
            why.append("peak %d MB" % (r.rss >> 20))
        if r.cpu > SIZE_SECONDS:
            why.append("%.1f s of CPU" % r.cpu)
        if OOM.search(r.err):
            why.append("out of memory under the harness's limit")
        if not r.hung and r.rc != 0 and (len(lines) != 1 or not lines[0].startswith("fogpipe: ")
                                         or not any(n in lines[0] for n in names)):
            why.append("message %r" % r.err[:200])
        if os.path.exists(out):
            why.append("an output was written")
        text = "%s refused (peak %d MB, %.2f s CPU)" % (name, r.rss >> 20, r.cpu)
        if why:
            text = "%s: %s" % (name, ", ".join(why))
        results.append((name, not why, text))
    report.runs["size"] = results


def api_suite(env, run, report):
    results = []
    lib = os.path.join(env.builddir, ".libs", "libfogpipe.so.0")
    here = os.path.dirname(os.path.abspath(__file__))
    for name in API_C + API_PY:
        if name.startswith("py_"):
            argv = [env.python, os.path.join(here, "api_misuse.py"), name]
        else:
            argv = [env.api, name]
        r = run(env, argv, timeout=30, cwd=env.dir, extra_env={
            "PYTHONPATH": os.path.join(env.srcdir, "python"), "FOGPIPE_LIBRARY": lib,
            "FP_FIXTURES": os.path.join(env.dir, "fixtures")})
        if r.hung:
            ok, why = False, "hung (killed after 30 s)"
        elif r.sig:
            ok, why = False, "signal %d" % r.sig
        elif SANITIZER.search(r.err):
            ok, why = False, "sanitizer report"
        elif r.rc == 77:
            ok, why = True, "skipped: " + r.err.strip()[-200:]
        elif r.rc != 0:
            ok, why = False, "exit %d: %s" % (r.rc, " | ".join(r.err.strip().splitlines()[-3:]))
        else:
            ok, why = True, "ok"
        results.append((name, ok, "%s: %s" % (name, why)))
    report.runs["api"] = results
