#!/usr/bin/env python3
"""fogpipe's layers, checked (doc/design.md draws them).

    tools/layers.py SRCDIR CHECK...

CHECK is one or more of:
  includes  no file includes one from a layer above it; the program (cli/)
            includes nothing of the project but the public header
  calls     no file refers to a function or a variable defined in a layer
            above it (external definitions found by pattern in the C and
            C++ sources; statics are private and left out)
  cycles    no circle between modules (x.c, x.h and x.cpp are one module)
            through includes or calls, within a layer or across layers
  placed    every C, C++ and OpenCL file of the library sits in a layer's
            folder (none loose in src/)
  lines     no source file over 1000 lines (see count_lines: every line of
            every .c .h .cpp .cl .py .sh .awk under the folders below,
            tests, samples and tools included)

Prints what is wrong, one line each, and exits 1; exits 0 when all is well.
"""
import os
import re
import sys

# Bottom to top.  A file may include or call what is in its own folder or a
# folder listed before it.
LAYERS = ["kernels", "src/base", "src/exr", "src/bridges", "src/cl", "src/scene",
          "filters", "lib", "cli"]
PUBLIC_HEADER = "lib/fogpipe.h"
CODE_EXT = (".c", ".h", ".cpp", ".cl")
# Where the line limit applies.
COUNTED_DIRS = LAYERS + ["src", "tests", "samples", "tools", "python"]
COUNTED_EXT = CODE_EXT + (".py", ".sh", ".awk")
MAX_LINES = 1000
# Files allowed over the limit (none).
LINES_PENDING = set()
SKIP_DIRS = {"tmp", ".libs", ".deps", "__pycache__", "out"}


def walk(root, top):
    base = os.path.join(root, top)
    if not os.path.isdir(base):
        return
    for d, dirs, files in os.walk(base):
        dirs[:] = sorted(x for x in dirs if x not in SKIP_DIRS and not x.startswith("."))
        for f in sorted(files):
            yield os.path.relpath(os.path.join(d, f), root)


def layer_of(path):
    best = None
    for i, l in enumerate(LAYERS):
        if path.startswith(l + "/") and (best is None or len(l) > len(LAYERS[best])):
            best = i
    return best


def read(root, path):
    with open(os.path.join(root, path), encoding="utf-8", errors="replace") as f:
        return f.read()


def strip_comments(text):
    """C and C++ text without comments, string and character literals (kept
    as empty quotes), line structure kept."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def module_of(path):
    return os.path.splitext(path)[0]


class Tree:
    def __init__(self, root):
        self.root = root
        self.files = [p for l in LAYERS for p in walk(root, l) if p.endswith(CODE_EXT)
                      and layer_of(p) == LAYERS.index(l)]
        self.by_name = {}
        for p in self.files:
            self.by_name.setdefault(os.path.basename(p), []).append(p)
        self.text = {p: read(root, p) for p in self.files}
        self.code = {p: strip_comments(t) for p, t in self.text.items()}

    def includes(self, path):
        """(line, name, resolved path or None) of each #include "..." line."""
        for no, line in enumerate(self.text[path].splitlines(), 1):
            m = re.match(r'\s*#\s*include\s*"([^"]+)"', line)
            if not m:
                continue
            name = m.group(1)
            if "/" in name:
                p = os.path.normpath(os.path.join(os.path.dirname(path), name))
                yield no, name, p if p in self.text else None
                continue
            own = os.path.join(os.path.dirname(path), name)
            if own in self.text:
                yield no, name, own
            else:
                found = self.by_name.get(name, [])
                yield no, name, found[0] if len(found) == 1 else None

    def definitions(self):
        """Externally visible functions and variables: {name: {paths}}
        (headers' and kernels' inline definitions included, so that a name
        defined both in a kernel header and in the C runtime resolves to the
        one the user can reach)."""
        defs = {}
        fn = re.compile(r"^(?!static\b|typedef\b|return\b|else\b|if\b|extern\b)"
                        r"[A-Za-z_][\w \t\*]*?\b([A-Za-z_]\w*)\s*\([^;{}]*\)\s*"
                        r"(?:const\s*)?\{", re.M)
        var = re.compile(r"^(?!static\b|typedef\b|extern\b|return\b)(?:const\s+)?"
                         r"[A-Za-z_][\w \t\*]*?\b(fp_\w+)\s*(?:\[[^\]]*\])?\s*(?:=|;)", re.M)
        for p in self.files:
            code = self.code[p]
            for m in fn.finditer(code):
                name = m.group(1)
                # C++ helpers live in anonymous namespaces: only the fp_
                # names are the bridges' C interface.
                if name == "main" or name.startswith("__") or \
                        (p.endswith(".cpp") and not name.startswith("fp_")):
                    continue
                defs.setdefault(name, set()).add(p)
            if p.endswith((".c", ".cpp")):
                for m in var.finditer(code):
                    defs.setdefault(m.group(1), set()).add(p)
        return defs

    def used_text(self, path):
        """The lines of `path` where a use counts: the whole file for .c,
        .cpp and .cl; only function bodies in a header (its prototypes
        declare, they do not use)."""
        code = self.code[path]
        if not path.endswith(".h"):
            return code
        out, depth, body = [], 0, 0
        last = ""
        for c in code:
            if c == "{":
                if depth == 0:
                    body = last == ")"
                depth += 1
            elif c == "}":
                depth = max(depth - 1, 0)
            if not c.isspace():
                last = c
            out.append(c if c == "\n" or (depth > 0 and body) else " ")
        return "".join(out)

    def calls(self):
        """(user path, line, symbol, defining path) for each use of a symbol
        defined in another module, and nowhere in the user's layer or
        below, when it is defined there too."""
        defs = self.definitions()
        word = re.compile(r"\b[A-Za-z_]\w*\b")
        for p in self.files:
            mod = module_of(p)
            seen = set()
            for no, line in enumerate(self.used_text(p).splitlines(), 1):
                if line.lstrip().startswith("#"):
                    continue
                for w in word.findall(line):
                    where = defs.get(w)
                    if not where or w in seen:
                        continue
                    seen.add(w)
                    if any(module_of(d) == mod for d in where):
                        continue   # its own module defines one: that one
                    reach = [d for d in where if layer_of(d) <= layer_of(p)]
                    for d in sorted(reach or where)[:1]:
                        yield p, no, w, d


def check_includes(t):
    bad = []
    for p in t.files:
        for no, name, q in t.includes(p):
            if q is None:
                if len(t.by_name.get(name, [])) > 1:
                    bad.append(f"{p}:{no}: '{name}' names {len(t.by_name[name])} files "
                               f"({', '.join(t.by_name[name])}): bare names must be unique")
                continue   # a system or generated header (config.h, fp_kernels.c)
            if p.startswith("cli/") and q != PUBLIC_HEADER:
                bad.append(f"{p}:{no}: the program includes {q}; it may include only "
                           f"{PUBLIC_HEADER}")
            elif layer_of(q) > layer_of(p):
                bad.append(f"{p}:{no}: includes {q}, a layer above "
                           f"({LAYERS[layer_of(p)]}/ may include only "
                           f"{', '.join(l + '/' for l in LAYERS[:layer_of(p) + 1])})")
    return bad


def check_calls(t):
    bad = []
    for p, no, sym, d in t.calls():
        if layer_of(d) > layer_of(p):
            bad.append(f"{p}:{no}: uses {sym} of {d}, a layer above")
    return bad


def check_cycles(t):
    edges = {}
    for p in t.files:
        for _, _, q in t.includes(p):
            if q is not None and module_of(q) != module_of(p):
                edges.setdefault(module_of(p), set()).add(module_of(q))
    for p, _, _, d in t.calls():
        edges.setdefault(module_of(p), set()).add(module_of(d))
    bad = []
    state = {}
    stack = []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(edges.get(m, ())):
            if state.get(n) == 1:
                cyc = stack[stack.index(n):] + [n]
                bad.append("circle: " + " -> ".join(cyc))
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    sys.setrecursionlimit(10000)
    for m in sorted(edges):
        if m not in state:
            visit(m)
    return bad


def check_placed(t):
    bad = []
    for p in walk(t.root, "src"):
        if p.endswith(CODE_EXT) and layer_of(p) is None:
            bad.append(f"{p}: not in a layer's folder ({', '.join(LAYERS)})")
    return bad


def count_lines(root, path):
    with open(os.path.join(root, path), "rb") as f:
        return f.read().count(b"\n")


def check_lines(t):
    bad = []
    seen = set()
    for top in COUNTED_DIRS:
        for p in walk(t.root, top):
            if p in seen or not p.endswith(COUNTED_EXT):
                continue
            seen.add(p)
            n = count_lines(t.root, p)
            if n > MAX_LINES and p not in LINES_PENDING:
                bad.append(f"{p}: {n} lines (at most {MAX_LINES}: split it by job)")
    return bad


CHECKS = {"includes": check_includes, "calls": check_calls, "cycles": check_cycles,
          "placed": check_placed, "lines": check_lines}


def main(argv):
    if len(argv) < 3 or any(c not in CHECKS for c in argv[2:]):
        sys.stderr.write(f"usage: layers.py SRCDIR {{{'|'.join(CHECKS)}}}...\n")
        return 2
    t = Tree(argv[1])
    if not t.files:
        sys.stderr.write(f"layers.py: {argv[1]}: no sources found in {', '.join(LAYERS)}\n")
        return 2
    bad = []
    for c in argv[2:]:
        bad += CHECKS[c](t)
    for b in bad:
        print(b)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
