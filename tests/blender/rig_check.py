"""tests/blender_addon.sh: what the add-on wrote, read back from
`oiiotool --info -v` of a frame, against what tests/blender/addon_scene.py
placed.  Prints what it compared; exit 1 on a difference.
  rig_check.py lights TRUTH FRAME INFO [cut]  the rig (Note, or fogpipeRig when the
                                              Note says more lights than it carries)
                                              is the truth's lights of FRAME; `cut`:
                                              the Note must carry fewer than all
  rig_check.py look INFO TEXT                 the look (Note or fogpipeLook) is TEXT
  rig_check.py field INFO TOKENS...           the rig's head holds TOKENS in a row
"""
import re
import sys

KINDS = {"sun": 7, "point": 7, "spot": 12, "area": 15}


def attrs(info):
    out = {}
    for line in open(info):
        m = re.match(r'^\s+([A-Za-z][\w.]*): "(.*)"\s*$', line)
        if m:
            out[m.group(1)] = m.group(2)
    return out


def parse_rig(text):
    """(head tokens, [(kind, numbers)], lights N or None) of the rig in text."""
    toks = re.split(r"[\s;]+", text[text.index("fogpipe-rig"):].strip())
    i, head, n = 2, [], None
    while i < len(toks) and toks[i] not in KINDS:
        if toks[i] in ("up", "clip", "shadow", "lights"):
            head += toks[i:i + 2]
            if toks[i] == "lights":
                n = int(toks[i + 1])
            i += 2
        else:
            break
    lights = []
    while i < len(toks) and toks[i] in KINDS:
        k = toks[i]
        lights.append((k, [float(x) for x in toks[i + 1:i + 1 + KINDS[k]]]))
        i += 1 + KINDS[k]
    return head, lights, n


def same(a, b):
    return a[0] == b[0] and len(a[1]) == len(b[1]) and \
        all(abs(x - y) <= 1e-5 * max(1.0, abs(y)) for x, y in zip(a[1], b[1]))


def main(argv):
    mode = argv[1]
    if mode == "lights":
        truth_file, frame, info = argv[2], argv[3], argv[4]
        cut = len(argv) > 5 and argv[5] == "cut"
        want = []
        for line in open(truth_file):
            f = line.split()
            if f and f[0] == frame:
                want.append((f[1], [float(x) for x in f[2:]]))
        a = attrs(info)
        head, note_lights, n = parse_rig(a.get("Note", ""))
        print("Note: lights %s, %d carried; truth: %d" % (n, len(note_lights), len(want)))
        if n != len(want):
            print("the Note's 'lights N' is %s, the scene has %d" % (n, len(want)))
            return 1
        lights = note_lights
        if len(note_lights) < n:
            if "fogpipeRig" not in a:
                print("the Note carries %d of %d lights and there is no fogpipeRig" %
                      (len(note_lights), n))
                return 1
            _, lights, n2 = parse_rig(a["fogpipeRig"])
            print("fogpipeRig: lights %s, %d carried" % (n2, len(lights)))
            if not all(any(same(x, y) for y in lights) for x in note_lights):
                print("the Note's lights are not the fogpipeRig's")
                return 1
        elif cut:
            print("expected a Note too short for every light")
            return 1
        left = list(want)
        for li in lights:
            match = [w for w in left if same(li, w)]
            if not match:
                print("not in the scene: %s %s" % (li[0], " ".join("%g" % x for x in li[1])))
                return 1
            left.remove(match[0])
        if left:
            print("missing: %s" % "; ".join("%s %s" % (w[0], w[1]) for w in left))
            return 1
        print("all %d lights as placed" % len(want))
        return 0
    if mode == "look":
        a = attrs(argv[2])
        text = a.get("fogpipeLook") or ""
        m = re.search(r"fogpipe-look 1( [^ ]+=[^ ]+)+", a.get("Note", ""))
        if m:
            text = m.group(0)
        print("look: %s" % text)
        return 0 if text == argv[3] else 1
    if mode == "field":
        a = attrs(argv[2])
        head, _, _ = parse_rig(a.get("Note", ""))
        print("rig head: %s" % " ".join(head))
        want = argv[3:]
        return 0 if any(head[i:i + len(want)] == want for i in range(len(head))) else 1
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
