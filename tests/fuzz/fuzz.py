#!/usr/bin/env python3
"""fogpipe fuzz harness: a seeded mutation campaign, the size-limit suite
and the API misuse cases (README "Testing"; make fuzz, tests/fuzz.sh).

  fuzz.py [--mode mutate,size,api] [--seed N] [--runs N] [--seconds S]
          [--only N] [--tap] [--known FILE]

The environment names the programs (make check's and make fuzz's):
FOGPIPE, FP_SCENE, FP_SRCDIR, FP_BUILDDIR, OIIOTOOL, PYTHON3, and
FUZZ_BIN, the folder of the harness's programs (exr_judge, image_judge,
api_misuse); FUZZ_DIR is the work folder (fixtures, runs, crashes/).

Every run gets its inputs from random.Random("SEED:RUN"), so a seed gives
the same runs in the same order on every machine, and --only N replays run
N alone.  A run fails, by class:

  crash      killed by a signal (other than the harness's own timeout)
  sanitizer  "ERROR: AddressSanitizer", "runtime error:" ... on stderr
  hang       still running after --timeout seconds (10)
  memory     peak RSS over --mem-mb (1024), killed by the address-space
             limit, or an out-of-memory message under it
  accepted   exit 0 (or a frame written) on an input that the outside judge
             rejects: OpenEXR's own check (exrcheck -m -t -c) for EXR,
             OpenImageIO reading every pixel for fogmaps, and for .chan the
             format itself (8 finite numbers a line, the options' ranges)
  nan        exit 0 and a non-finite output pixel where the input's was
             finite
  partial    non-zero exit and an output file or a temporary left behind
  message    non-zero exit without exactly one stderr line that starts
             "fogpipe: " and names the bad file ("<stdin>" for a stream),
             or an exit status other than 1 or 2
A file the judges accept is fine whatever fogpipe makes of it (a flipped
bit in a pixel gives a garbled pixel, not an error).  The reproducing
input and a repro.sh go to FUZZ_DIR/crashes/CLASS-SEED-RUN/."""
import argparse
import os
import random
import re
import resource
import shutil
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import exrfile  # noqa: E402
import mutate  # noqa: E402
import suites  # noqa: E402

COMPRESSIONS = ["none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"]
SANITIZER = re.compile(r"ERROR: (AddressSanitizer|LeakSanitizer|MemorySanitizer|ThreadSanitizer)"
                       r"|runtime error:|WARNING: ThreadSanitizer|SUMMARY: UndefinedBehavior")
OOM = re.compile(r"out of memory|std::bad_alloc|cannot allocate|Cannot allocate|"
                 r"RSS limit|allocation-size-too-big|requested allocation size", re.I)
CLASSES = ["crash", "sanitizer", "hang", "memory", "accepted", "nan", "partial", "message"]


class Env:
    def __init__(self, a):
        self.fogpipe = os.environ["FOGPIPE"]
        self.scene = os.environ["FP_SCENE"]
        self.srcdir = os.environ.get("FP_SRCDIR", ".")
        self.builddir = os.environ.get("FP_BUILDDIR", ".")
        self.oiiotool = os.environ.get("OIIOTOOL") or shutil.which("oiiotool")
        b = os.environ.get("FUZZ_BIN", os.path.join(self.builddir, "tests", "fuzz"))
        self.judges = {"exr": os.path.join(b, "exr_judge"), "image": os.path.join(b, "image_judge"),
                       "finite": os.path.join(b, "image_judge")}
        self.api = os.path.join(b, "api_misuse")
        self.python = os.environ.get("PYTHON3") or sys.executable
        self.dir = os.path.abspath(os.environ.get("FUZZ_DIR", "fuzz-work"))
        self.timeout = a.timeout
        self.mem = a.mem_mb << 20
        self.asan = sanitized(self.fogpipe)


def sanitized(prog):
    try:
        with open(prog, "rb") as f:
            return b"__asan_init" in f.read()
    except OSError:
        return False


class Result:
    def __init__(self, rc, sig, hung, rss, wall, cpu, out, err):
        self.rc, self.sig, self.hung, self.rss, self.wall = rc, sig, hung, rss, wall
        self.cpu = cpu
        self.out, self.err = out, err


def run(env, argv, stdin=None, timeout=None, mem=None, cwd=None, extra_env=None):
    """One child under a timeout and an address-space limit (not under
    AddressSanitizer, which reserves terabytes: there its own
    hard_rss_limit_mb), its peak RSS from wait4."""
    timeout = timeout or env.timeout
    mem = mem or env.mem
    e = dict(os.environ)
    e.setdefault("FOGPIPE_PROGRESS", "off")
    e["ASAN_OPTIONS"] = ("hard_rss_limit_mb=%d:detect_leaks=1:abort_on_error=0:"
                         "allocator_may_return_null=1" % (mem >> 20))
    e["UBSAN_OPTIONS"] = "print_stacktrace=1"
    if extra_env:
        e.update(extra_env)

    def limits():
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if not env.asan:
            resource.setrlimit(resource.RLIMIT_AS, (mem + (512 << 20), mem + (512 << 20)))

    fin = open(stdin, "rb") if stdin else subprocess.DEVNULL
    fout = open(os.path.join(env.dir, "child.out"), "wb+")
    ferr = open(os.path.join(env.dir, "child.err"), "wb+")
    t0 = time.monotonic()
    p = subprocess.Popen(argv, stdin=fin, stdout=fout, stderr=ferr, preexec_fn=limits,
                         start_new_session=True, env=e, cwd=cwd)
    hung = False
    deadline = t0 + timeout
    while True:
        pid, status, ru = os.wait4(p.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            hung = True
            try:
                os.killpg(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            pid, status, ru = os.wait4(p.pid, 0)
            break
        time.sleep(0.005)
    p.returncode = 0  # reaped here, not by Popen
    wall = time.monotonic() - t0
    if stdin:
        fin.close()
    fout.seek(0)
    ferr.seek(0)
    out, err = fout.read(), ferr.read()
    fout.close()
    ferr.close()
    sig = os.WTERMSIG(status) if os.WIFSIGNALED(status) else 0
    rc = os.WEXITSTATUS(status) if os.WIFEXITED(status) else -sig
    return Result(rc, sig, hung, ru.ru_maxrss << 10, wall, ru.ru_utime + ru.ru_stime, out,
                  err.decode("utf-8", "replace"))


def lines_of(text):
    """Lines as a terminal or a log sees them: split at "\n" alone
    (str.splitlines also splits at \f, \x1d ... that a message quoting a
    binary file's bytes may hold)."""
    return text[:-1].split("\n") if text.endswith("\n") else text.split("\n") if text else []


# ---------------------------------------------------------------- fixtures
def sh(argv, **kw):
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, **kw)


def fixtures(env):
    """The inputs the mutations start from, made by the project's own scene
    generator and oiiotool (the same bytes on every run)."""
    fx = os.path.join(env.dir, "fixtures")
    stamp = os.path.join(fx, ".done")
    if os.path.exists(stamp):
        return load_fixtures(fx)
    shutil.rmtree(fx, ignore_errors=True)
    os.makedirs(fx)
    sh([env.scene, "-o", fx, "--width", "40", "--height", "24", "--frames", "1-2",
        "--shadow-size", "0"])
    t = env.oiiotool

    def oiio(args, out):
        sh([t, "--nosoftwareattrib"] + args + ["-o", out])
        with open(out, "rb") as f:
            d = exrfile.normalized(f.read())
        with open(out, "wb") as f:
            f.write(d)

    s1, s2 = os.path.join(fx, "scene.0001.exr"), os.path.join(fx, "scene.0002.exr")
    # scanline in every compression by the project's own writer (fogged
    # frames: color, Z and the camera kept), tiled and multipart by oiiotool
    for c in COMPRESSIONS:
        for fr, src in ((1, s1), (2, s2)):
            sh([env.fogpipe, "-q", "--cpu", "-i", src, "--compression", c, "-o",
                os.path.join(fx, "sl_%s.%d.exr" % (c, fr))])
    for c in ("none", "zip", "piz", "pxr24", "b44a", "dwab"):
        oiio([s1, "--tile", "16", "16", "--compression", c], os.path.join(fx, "tl_%s.exr" % c))
    for c in ("zip", "dwaa"):
        oiio([s1, s2, "--chnames", "o.R,o.G,o.B,o.A,o.Z", "--siappend", "--compression", c],
             os.path.join(fx, "mp_%s.exr" % c))
    oiio([s1, "--attrib", "openexr:lineOrder", "decreasingY", "--compression", "dwab"],
         os.path.join(fx, "dec_dwab.exr"))
    for c in ("piz", "b44"):
        oiio([s1, "--compression", c], os.path.join(fx, "oiio_%s.exr" % c))
    # the camera as fogpipe-camera text instead of the matrices
    with open(s1, "rb") as f:
        lay = exrfile.Layout(f.read())
    mats = []
    for name in ("worldToCamera", "worldToNDC"):
        a = lay.attr(name)
        fmt = "<16d" if a.type == "m44d" else "<16f"
        import struct
        mats.append(" ".join("%.9g" % v for v in struct.unpack_from(fmt, lay.data, a.value_at)))
    text = "fogpipe-camera 1 worldToCamera %s worldToNDC %s" % tuple(mats)
    oiio([s1, "--eraseattrib", "worldToCamera", "--eraseattrib", "worldToNDC",
          "--attrib", "Note", text, "--compression", "zip"], os.path.join(fx, "camtext.exr"))
    # fogmaps in the formats OpenImageIO reads for fogpipe
    fm = os.path.join(fx, "fogmap.exr")
    for ext in ("png", "tif", "jpg"):
        sh([t, "--nosoftwareattrib", fm, "--ch", "0", "--resize", "32x32", "-d", "uint8",
            "--attrib", "DateTime", "2000:01:01 00:00:00",
            "-o", os.path.join(fx, "fogmap." + ext)])
    with open(os.path.join(fx, "cam.chan"), "w") as f:
        f.write("1 0 2 -10 0 180 0 45\n2 0.1 2 -10 1 180 0 45\n3 0.2 2.1 -9.5 2 181 0.5 44\n")
    shutil.copy(os.path.join(env.srcdir, "samples/presets/morning-valley-mist.preset"),
                os.path.join(fx, "look.preset"))
    # every fixture must go through fogpipe and OpenEXR's check as it is,
    # or the campaign would blame the mutations for it
    for name in sorted(os.listdir(fx)):
        p = os.path.join(fx, name)
        if not name.endswith(".exr") or name == "fogmap.exr":
            continue
        r = run(env, [env.fogpipe, "-q", "--cpu", "-i", p, "-o", os.path.join(fx, ".check.exr")])
        rej, why = judge(env, "exr", p)
        if r.rc or rej:
            raise SystemExit("fuzz: fixture %s: fogpipe exit %d, judge: %s %s" % (
                name, r.rc, why, r.err.strip()))
    os.remove(os.path.join(fx, ".check.exr"))
    open(stamp, "w").close()
    return load_fixtures(fx)


def load_fixtures(fx):
    out = {}
    for name in sorted(os.listdir(fx)):
        if name.startswith(".") or name in ("scene.0001.exr", "scene.0002.exr", "fogmap.exr"):
            continue
        with open(os.path.join(fx, name), "rb") as f:
            out[name] = f.read()
    out["_dir"] = fx
    return out


# ---------------------------------------------------------------- the judges
def judge(env, kind, path):
    """0: the outside judge accepts the file; 1: it rejects it; its reason."""
    r = run(env, [env.judges[kind], kind, path], timeout=60, mem=2 << 30)
    if r.rc not in (0, 1):  # the judge itself crashed or ran out: the file is hostile
        return 1, "the judge failed (%s)" % (r.rc if not r.hung else "timeout")
    return r.rc, r.out.decode("utf-8", "replace").strip()


NUM = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def chan_rejected(data):
    """The .chan format as fogpipe documents it: 'frame tx ty tz rx ry rz
    vfov', finite numbers, rotations within --camera-rot's range, the FOV
    within --vfov's; '#' lines and blank lines are comments."""
    for n, line in enumerate(data.split(b"\n"), 1):
        s = line.strip(b" \t\r")
        if not s or s.startswith(b"#"):
            continue
        toks = s.split()
        if len(toks) != 8:
            return 1, "line %d has %d columns" % (n, len(toks))
        for i, t in enumerate(toks):
            if not NUM.match(t.decode("latin-1")):
                return 1, "line %d column %d is %r" % (n, i + 1, t)
            v = float(t)
            if v != v or v in (float("inf"), float("-inf")):
                return 1, "line %d column %d is not finite" % (n, i + 1)
            if 4 <= i < 7 and abs(v) > 360000 or i == 7 and not 0.01 <= v <= 179:
                return 1, "line %d column %d out of range" % (n, i + 1)
    return 0, ""


# ---------------------------------------------------------------- one run
class Case:
    """What one run feeds fogpipe: argv, stdin, the files it must name in
    a message, the outputs it may leave, and how its input is judged."""

    def __init__(self):
        self.argv, self.stdin, self.names, self.outputs = [], None, [], []
        self.judge = []  # (kind, path, output frame it gates or None)
        self.desc, self.files, self.nan_pair = [], [], None


def make_case(env, fx, seed, n, work):
    rng = random.Random("%s:%d" % (seed, n))
    exrs = sorted(k for k in fx if k.endswith(".exr"))
    pool = [fx[k] for k in exrs]
    kind = mutate.pick(rng, [("exr", 10), ("stream", 3), ("fogmap", 2), ("chan", 1),
                             ("preset", 1), ("camtext", 1)])
    c = Case()
    base = [env.fogpipe, "-q"]
    if kind != "camtext" and n % 8 != 7:
        base.append("--cpu")  # the C reference: 10x faster a run; the reader is the same
    out = os.path.join(work, "out.exr")
    scene = os.path.join(fx["_dir"], "scene.0001.exr")

    def put(name, data):
        p = os.path.join(work, name)
        with open(p, "wb") as f:
            f.write(data)
        c.files.append(p)
        return p

    if kind == "exr":
        name = rng.choice(exrs)
        data, desc = mutate.mutate_exr(rng, fx[name], pool)
        p = put("in_" + name.replace(".1.exr", ".exr"), data)
        c.argv = base + ["-i", p, "-o", out]
        c.names, c.outputs = [os.path.basename(p)], [out]
        c.judge = [("exr", p, None)]
        c.nan_pair = (p, out)
        c.desc = ["%s: %s" % (name, "; ".join(desc))]
    elif kind == "stream":
        comp = rng.choice(COMPRESSIONS)
        members = [fx["sl_%s.1.exr" % comp], fx["sl_%s.2.exr" % comp]]
        k = rng.randrange(2)
        if rng.random() < 0.2:  # the stream cut short: the last member
            k = 1
            at = rng.randrange(1, len(members[1]))
            members[1], desc = members[1][:at], ["cut at %d" % at]
        else:
            members[k], desc = mutate.mutate_exr(rng, members[k], pool, same_length=True)
        for i, m in enumerate(members):
            c.judge.append(("exr", put("member%d.exr" % (i + 1), m), i + 1))
        p = put("in.stream", b"".join(members))
        c.stdin = p
        pat = os.path.join(work, "o.####.exr")
        c.argv = base + ["-i", "-", "-o", pat]
        c.names = ["<stdin>"]
        c.outputs = [os.path.join(work, "o.%04d.exr" % i) for i in (1, 2)]
        c.desc = ["stream of sl_%s frames 1-2, member %d: %s" % (comp, k + 1, "; ".join(desc))]
    elif kind == "fogmap":
        ext = rng.choice(["png", "tif", "jpg"])
        data, desc = mutate.mutate_image(rng, ext, fx["fogmap." + ext], pool)
        p = put("fog." + ext, data)
        c.argv = base + ["-i", scene, "-o", out, "--fogmap", p]
        c.names, c.outputs = [os.path.basename(p)], [out]
        c.judge = [("image", p, None)]
        c.desc = ["fogmap.%s: %s" % (ext, "; ".join(desc))]
    elif kind == "chan":
        data, desc = mutate.mutate_text(rng, fx["cam.chan"], pool)
        p = put("cam.chan", data)
        c.argv = base + ["-i", scene, "-o", out, "--camera-chan", p]
        c.names, c.outputs = [os.path.basename(p)], [out]
        c.judge = [("chan", p, None)]
        c.desc = ["cam.chan: %s" % "; ".join(desc)]
    elif kind == "preset":
        data, desc = mutate.mutate_text(rng, fx["look.preset"], pool)
        p = put("look.preset", data)
        c.argv = base + ["-i", scene, "-o", out, "--preset", p]
        c.names, c.outputs = [os.path.basename(p)], [out]
        c.desc = ["look.preset: %s" % "; ".join(desc)]
    else:
        src = fx["camtext.exr"]
        note = exrfile.Layout(src).attr("Note")
        text = src[note.value_at:note.end].decode("latin-1")
        if rng.random() < 0.6:
            text, what = mutate.scale_camera_text(rng, text)
        else:
            d, ds = mutate.mutate_text(rng, text.replace(" ", "\n").encode(), pool)
            text, what = d.replace(b"\n", b" ").decode("latin-1")[:700], "; ".join(ds)
        p = put("camtext.exr", exrfile.set_string(src, "Note", text))
        c.argv = base + ["-i", p, "-o", out]
        c.names, c.outputs = [os.path.basename(p)], [out]
        c.judge = [("exr", p, None)]
        c.nan_pair = (p, out)
        c.desc = ["camtext.exr: %s" % what]
    return c


def check(env, c, r, work):
    """The failure classes of one run (empty: it passed)."""
    fails = []
    if SANITIZER.search(r.err):
        fails.append("sanitizer")
    if r.hung:
        fails.append("hang")
    elif r.sig and r.sig != signal.SIGKILL:
        fails.append("crash")
    if r.rss > env.mem or OOM.search(r.err) or (r.sig == signal.SIGKILL and not r.hung):
        fails.append("memory")
    if r.hung or r.sig:
        return fails, ""
    why = ""
    written = [o for o in c.outputs if os.path.exists(o)]
    for kind, path, frame in c.judge:
        gated = r.rc == 0 if frame is None else c.outputs[frame - 1] in written
        if not gated:
            continue
        if kind == "chan":
            with open(path, "rb") as f:
                rej, why = chan_rejected(f.read())
        else:
            rej, why = judge(env, kind, path)
        if rej:
            fails.append("accepted")
            break
    if r.rc == 0 and c.nan_pair and "accepted" not in fails and os.path.exists(c.nan_pair[1]):
        fin = run(env, [env.judges["finite"], "finite", c.nan_pair[0], c.nan_pair[1]], timeout=60,
                  mem=2 << 30)
        if fin.rc == 1:
            fails.append("nan")
            why = fin.out.decode("utf-8", "replace").strip()
    if r.rc != 0:
        tmp = [f for f in os.listdir(work) if ".tmp" in f]
        if (c.stdin is None and written) or tmp:
            fails.append("partial")
        lines = lines_of(r.err)
        if (r.rc not in (1, 2) or len(lines) != 1 or not lines[0].startswith("fogpipe: ") or
                not any(nm in lines[0] for nm in c.names)):
            fails.append("message")
    return fails, why


def save(env, c, seed, n, fails, r, why):
    d = os.path.join(env.dir, "crashes", "%s-%s-%d" % (fails[0], seed, n))
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    for p in c.files:
        shutil.copy(p, d)
    with open(os.path.join(d, "repro.sh"), "w") as f:
        f.write("#!/bin/sh\n# %s (run %d of seed %s): %s\n# %s\n" %
                (", ".join(fails), n, seed, "; ".join(c.desc), why))
        f.write("# exit %d, signal %d, %.1f s, peak %d MB\ncd \"$(dirname \"$0\")\"\n" %
                (r.rc, r.sig, r.wall, r.rss >> 20))
        argv = [os.path.basename(a) if a in c.files else a for a in c.argv]
        f.write(" ".join("'%s'" % a for a in argv) +
                (" < %s" % os.path.basename(c.stdin) if c.stdin else "") + "\n")
    with open(os.path.join(d, "stderr.txt"), "w") as f:
        f.write(r.err)
    return d


def campaign(env, a, report):
    fx = fixtures(env)
    work = os.path.join(env.dir, "run")
    t0 = time.monotonic()
    n = a.only if a.only is not None else 0
    runs = 0
    while True:
        if a.only is None and (runs >= a.runs or time.monotonic() - t0 > a.seconds):
            break
        shutil.rmtree(work, ignore_errors=True)
        os.makedirs(work)
        c = make_case(env, fx, a.seed, n, work)
        r = run(env, c.argv, stdin=c.stdin)
        fails, why = check(env, c, r, work)
        runs += 1
        if fails:
            d = save(env, c, a.seed, n, fails, r, why)
            report.fail("mutate", fails, "run %d: %s -> exit %d: %s %s [%s]" % (
                n, "; ".join(c.desc), r.rc, (lines_of(r.err) or [""])[0][:160], why,
                os.path.relpath(d, env.dir)))
        if a.verbose:
            print("# run %d %s: exit %d %.2fs %dMB %s" % (n, "; ".join(c.desc), r.rc, r.wall,
                                                         r.rss >> 20, fails or ""))
        if a.only is not None:
            break
        n += 1
    report.runs["mutate"] = runs


class Report:
    def __init__(self, tap, known):
        self.tap, self.known = tap, known
        self.runs, self.failures, self.n = {}, [], 0

    def fail(self, mode, classes, text):
        self.failures.append((mode, classes, text))

    def tap_line(self, ok, text, name):
        self.n += 1
        # a flaky known failure ("?" in the file: a race that fails only
        # some of the time) is TODO only when it fails
        strict = self.known.get(name)
        todo = " # TODO known failure (%s)" % name if strict or (
            strict is False and not ok) else ""
        print("%s %d - %s%s" % ("ok" if ok else "not ok", self.n, text, todo))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mode", default="mutate,size,api")
    ap.add_argument("--seed", default=os.environ.get("FUZZ_SEED", "1"))
    ap.add_argument("--runs", type=int, default=1 << 30)
    ap.add_argument("--seconds", type=float, default=float(os.environ.get("FUZZ_SECONDS", 600)))
    ap.add_argument("--only", type=int)
    ap.add_argument("--timeout", type=float, default=10)
    ap.add_argument("--mem-mb", type=int, default=1024)
    ap.add_argument("--tap", action="store_true", help="TAP for make check")
    ap.add_argument("--known", help="file of check names expected to fail (TAP TODO)")
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args()
    env = Env(a)
    os.makedirs(env.dir, exist_ok=True)
    known = {}  # name: True, or False for a flaky one ("name ?")
    if a.known and os.path.exists(a.known):
        with open(a.known) as f:
            for ln in f:
                w = ln.split("#")[0].split()
                if w:
                    known[w[0]] = w[1:] != ["?"]
    report = Report(a.tap, known)
    modes = a.mode.split(",")
    t0 = time.monotonic()
    if "mutate" in modes:
        campaign(env, a, report)
    if "size" in modes:
        suites.size_suite(env, run, report, fixtures(env))
    if "api" in modes:
        fixtures(env)
        suites.api_suite(env, run, report)
    return summary(report, modes, time.monotonic() - t0)


def summary(report, modes, wall):
    by = {}
    for mode, classes, text in report.failures:
        for k in classes:
            by.setdefault((mode, k), []).append(text)
    if "mutate" in modes:
        runs = report.runs.get("mutate", 0)
        for k in CLASSES:
            items = by.get(("mutate", k), [])
            report.tap_line(not items, "mutate: %d runs, %d %s" % (runs, len(items), k),
                            "mutate:" + k)
            for t in items[:5]:
                print("#   " + t)
            if len(items) > 5:
                print("#   ... %d more" % (len(items) - 5))
    for mode in ("size", "api"):
        if mode not in modes:
            continue
        for name, ok, text in report.runs.get(mode, []):
            report.tap_line(ok, "%s: %s" % (mode, text), "%s:%s" % (mode, name))
    print("1..%d" % report.n)
    print("# fuzz: %s in %.0f s; failures by class: %s" % (
        ", ".join("%s %s" % (v if isinstance(v, int) else len(v), k)
                  for k, v in report.runs.items()), wall,
        ", ".join(["%s/%s %d" % (m, k, len(v)) for (m, k), v in sorted(by.items())] +
                  ["%s %d of %d" % (m, sum(1 for r in report.runs[m] if not r[1]),
                                    len(report.runs[m]))
                   for m in ("size", "api") if m in report.runs and
                   any(not r[1] for r in report.runs[m])]) or "none"))
    failed = ["%s:%s" % mk for mk in by]
    for mode in ("size", "api"):
        failed += ["%s:%s" % (mode, name) for name, ok, _ in report.runs.get(mode, []) if not ok]
    if report.tap:  # the known ones are TODO
        failed = [f for f in failed if f not in report.known]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
