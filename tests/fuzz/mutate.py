"""fogpipe fuzz harness: the mutations.  Each takes a random.Random, the
input's bytes and a pool of other fixtures' bytes (for splicing), and
returns the new bytes and a short description for the report.  Standard
library only."""
import re
import struct
import zlib

from exrfile import Layout, replace_attr

INT32 = [0, 1, -1, 2, 7, 8, 15, 16, 31, 32, 33, 255, 256, 0x7fff, 0xffff, 0x10000, 46341,
         99999, 100000, 1000000, 12000000, 0x3fffffff, 0x7ffffffe, 0x7fffffff, -0x80000000,
         -0x7fffffff, -2, -16]
BYTES = [0x00, 0x01, 0x7f, 0x80, 0xfe, 0xff, 0x0a, 0x20]
# header attributes a reader depends on, most of them
KEY_ATTRS = ["dataWindow", "displayWindow", "channels", "compression", "chunkCount", "lineOrder",
             "tiles", "type", "name", "worldToCamera", "worldToNDC", "dwaCompressionLevel",
             "pixelAspectRatio", "screenWindowWidth", "version"]
TYPES = ["int", "float", "double", "string", "box2i", "box2f", "compression", "chlist",
         "m44f", "m44d", "v2i", "lineOrder", "tiledesc", "unknowntype"]


def pack32(v):
    return struct.pack("<i", v if v < 0x80000000 else v - 0x100000000)


def _pos(rng, data, lay):
    """A byte to hit: half of the time in the headers and offset tables."""
    if lay is not None and rng.random() < 0.5:
        end = lay.tables[-1][0] + 8 * lay.tables[-1][1] if lay.tables else lay.header_end
        return rng.randrange(8, max(9, min(end, len(data))))
    return rng.randrange(len(data))


def bitflip(rng, data, lay, pool):
    d = bytearray(data)
    n = rng.choice([1, 1, 2, 4, 8])
    for _ in range(n):
        d[_pos(rng, d, lay)] ^= 1 << rng.randrange(8)
    return bytes(d), "flip %d bits" % n


def byteset(rng, data, lay, pool):
    d = bytearray(data)
    n = rng.choice([1, 2, 4])
    for _ in range(n):
        d[_pos(rng, d, lay)] = rng.choice(BYTES + [rng.randrange(256)])
    return bytes(d), "set %d bytes" % n


def truncate(rng, data, lay, pool):
    if lay is not None and lay.chunks and rng.random() < 0.5:
        c = rng.choice(lay.chunks)
        at = c[1] + rng.choice([0, 1, c[2] - 1, c[2], c[2] + max(0, c[3]) // 2,
                                c[2] + max(0, c[3]) - 1])
    else:
        at = rng.randrange(1, len(data))
    at = max(1, min(at, len(data) - 1))
    return data[:at], "cut at %d of %d" % (at, len(data))


def duplicate(rng, data, lay, pool):
    if lay is not None and lay.chunks and rng.random() < 0.6:
        c = rng.choice(lay.chunks)
        a, b = c[1], min(len(data), c[1] + c[2] + max(0, c[3]))
    else:
        a = rng.randrange(len(data))
        b = min(len(data), a + rng.choice([1, 4, 16, 256, 4096]))
    return data[:b] + data[a:b] + data[b:], "duplicate bytes %d-%d" % (a, b)


def splice(rng, data, lay, pool):
    other = rng.choice(pool)
    if lay is not None and lay.chunks and rng.random() < 0.6:
        c = rng.choice(lay.chunks)
        try:
            ol = Layout(other)
        except (ValueError, IndexError, KeyError, struct.error):
            ol = None
        if ol is not None and ol.chunks:
            o = rng.choice(ol.chunks)
            chunk = other[o[1]:o[1] + o[2] + max(0, o[3])]
            end = c[1] + c[2] + max(0, c[3])
            return data[:c[1]] + chunk + data[end:], "chunk at %d replaced" % c[1]
    a = rng.randrange(len(data))
    b = rng.randrange(len(other))
    return data[:a] + other[b:], "spliced at %d with another file from %d" % (a, b)


def attr_int(rng, data, lay, pool):
    names = [a for a in lay.attrs if a.name in KEY_ATTRS and a.size > 0] or lay.attrs
    a = rng.choice(names)
    d = bytearray(data)
    if a.size < 4:
        d[a.value_at] = rng.choice(BYTES + [rng.randrange(16)])
        return bytes(d), "attribute %s = byte %d" % (a.name, d[a.value_at])
    at = a.value_at + 4 * rng.randrange(a.size // 4)
    if a.name == "channels" and rng.random() < 0.7:
        # a channel's pixel type or sampling, just after its name
        names_end = [m.end() for m in re.finditer(rb"\0", data[a.value_at:a.end])]
        if len(names_end) > 1:
            at = a.value_at + rng.choice(names_end[:-1]) + rng.choice([0, 8, 12])
            at = min(at, a.end - 4)
    v = rng.choice(INT32)
    d[at:at + 4] = pack32(v)
    return bytes(d), "attribute %s +%d = %d" % (a.name, at - a.value_at, v)


def attr_float(rng, data, lay, pool):
    """A matrix or float attribute scaled (a projective camera scaled is the
    same camera) or set to an extreme."""
    ms = [a for a in lay.attrs if a.type in ("m44f", "m44d", "float", "double", "v2f", "box2f")]
    if not ms:
        return bitflip(rng, data, lay, pool)
    a = rng.choice(ms)
    fmt = "<d" if a.type in ("m44d", "double") else "<f"
    w = struct.calcsize(fmt)
    d = bytearray(data)
    k = rng.choice([1e30, 1e-30, 1e-38, 1e38, 0.0, -1.0, float("nan"), float("inf")])
    whole = rng.random() < 0.5
    idx = range(a.size // w) if whole else [rng.randrange(a.size // w)]
    for i in idx:
        v = struct.unpack_from(fmt, d, a.value_at + w * i)[0]
        nv = v * k if whole else k
        try:
            struct.pack_into(fmt, d, a.value_at + w * i, nv)
        except OverflowError:
            struct.pack_into(fmt, d, a.value_at + w * i, float("inf"))
    return bytes(d), "attribute %s %s %g" % (a.name, "scaled by" if whole else "one value", k)


def attr_type(rng, data, lay, pool):
    names = [a for a in lay.attrs if a.name in KEY_ATTRS] or lay.attrs
    a = rng.choice(names)
    if rng.random() < 0.5:
        t = rng.choice(TYPES)
        return replace_attr(data, a, type_=t), "attribute %s typed %s" % (a.name, t)
    v = data[a.value_at:a.end]
    nv = rng.choice([b"", v[:len(v) // 2], v + v, v[:-1], v + b"\0" * 4])
    return replace_attr(data, a, nv), "attribute %s value %d bytes" % (a.name, len(nv))


def offset(rng, data, lay, pool):
    at, n = rng.choice(lay.tables)
    if n <= 0:
        return bitflip(rng, data, lay, pool)
    k = rng.randrange(n)
    q = at + 8 * k
    if q + 8 > len(data):
        return truncate(rng, data, lay, pool)
    cur = struct.unpack_from("<Q", data, q)[0]
    others = [c[1] for c in lay.chunks] or [cur]
    v = rng.choice([0, 1, 8, len(data), len(data) - 1, len(data) + 8, 1 << 63, (1 << 64) - 1,
                    0x7fffffff, cur - 1, cur + 1, cur + 8, rng.choice(others), lay.header_end])
    d = bytearray(data)
    struct.pack_into("<Q", d, q, v % (1 << 64))
    return bytes(d), "offset %d of part table at %d = %d" % (k, at, v)


def chunk_header(rng, data, lay, pool):
    if not lay.chunks:
        return bitflip(rng, data, lay, pool)
    part, start, hl, size = rng.choice(lay.chunks)
    d = bytearray(data)
    field = rng.randrange(hl // 4)
    at = start + 4 * field
    last = field == hl // 4 - 1
    if last and rng.random() < 0.6:  # the data size: a little short or long
        v = rng.choice([size - 1, size // 2, size + 1, size + 4096, 0, 1, -1, 0x7fffffff])
    else:
        v = rng.choice(INT32)
    d[at:at + 4] = pack32(v & 0xffffffff)
    return bytes(d), "chunk at %d field %d = %d" % (start, field, v)


def chunk_swap(rng, data, lay, pool):
    if len(lay.chunks) < 2:
        return duplicate(rng, data, lay, pool)
    a, b = rng.sample(lay.chunks, 2)
    d = bytearray(data)
    # swap their offset table entries: the chunks are then out of place
    for at, n in lay.tables:
        for k in range(n):
            q = at + 8 * k
            if q + 8 > len(d):
                continue
            v = struct.unpack_from("<Q", d, q)[0]
            if v == a[1]:
                struct.pack_into("<Q", d, q, b[1])
            elif v == b[1]:
                struct.pack_into("<Q", d, q, a[1])
    return bytes(d), "chunks at %d and %d swapped in the table" % (a[1], b[1])


EXR_MUTATIONS = [(bitflip, 3), (byteset, 2), (truncate, 2), (duplicate, 1), (splice, 1),
                 (attr_int, 4), (attr_float, 1), (attr_type, 2), (offset, 2),
                 (chunk_header, 3), (chunk_swap, 1)]
BLIND_MUTATIONS = [(bitflip, 3), (byteset, 2), (truncate, 2), (duplicate, 1), (splice, 1)]


def pick(rng, table):
    total = sum(w for _, w in table)
    r = rng.uniform(0, total)
    for f, w in table:
        r -= w
        if r <= 0:
            return f
    return table[-1][0]


# the mutations that keep a file's length: a stream member mutated by one of
# these still ends where it did, so OpenEXR's check of it alone is the
# judge of the frame fogpipe reads from it
SAME_LENGTH = [(f, w) for f, w in EXR_MUTATIONS if f not in (truncate, duplicate, splice,
                                                            attr_type)]


def mutate_exr(rng, data, pool, same_length=False):
    desc = []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        try:
            lay = Layout(data)
            f = pick(rng, SAME_LENGTH if same_length else EXR_MUTATIONS)
        except (ValueError, IndexError, KeyError, struct.error):
            lay, f = None, pick(rng, BLIND_MUTATIONS[:2] if same_length else BLIND_MUTATIONS)
        if len(data) < 2:
            break
        data, what = f(rng, data, lay, pool)
        desc.append(what)
    return data, desc


# ---------------------------------------------------------------- images
def png_dims(data, w, h):
    """A PNG whose IHDR claims w x h (its CRC made right, so that the
    reader gets past it)."""
    i = data.find(b"IHDR")
    if i < 4:
        return data
    d = bytearray(data)
    struct.pack_into(">II", d, i + 4, w, h)
    struct.pack_into(">I", d, i + 17, zlib.crc32(bytes(d[i:i + 17])) & 0xffffffff)
    return bytes(d)


def tiff_dims(data, w, h):
    """A TIFF whose first IFD's ImageWidth and ImageLength are w and h."""
    le = data[:2] == b"II"
    e = "<" if le else ">"
    ifd = struct.unpack_from(e + "I", data, 4)[0]
    n = struct.unpack_from(e + "H", data, ifd)[0]
    d = bytearray(data)
    for k in range(n):
        at = ifd + 2 + 12 * k
        tag, typ = struct.unpack_from(e + "HH", d, at)
        if tag in (256, 257):
            v = w if tag == 256 else h
            if typ == 3:
                struct.pack_into(e + "HHIH", d, at, tag, 3, 1, min(v, 0xffff))
            else:
                struct.pack_into(e + "HHII", d, at, tag, 4, 1, v)
    return bytes(d)


def jpeg_dims(data, w, h):
    """A JPEG whose SOF claims w x h (16-bit fields)."""
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xff:
            break
        m = data[i + 1]
        ln = struct.unpack_from(">H", data, i + 2)[0]
        if m in (0xc0, 0xc1, 0xc2):
            d = bytearray(data)
            struct.pack_into(">HH", d, i + 5, min(h, 0xffff), min(w, 0xffff))
            return bytes(d)
        i += 2 + ln
    return data


def image_dims(kind, data, w, h):
    return {"png": png_dims, "tif": tiff_dims, "jpg": jpeg_dims}[kind](data, w, h)


def mutate_image(rng, kind, data, pool):
    desc = []
    if rng.random() < 0.2:
        w, h = rng.choice([(30000, 30000), (100000, 100000), (65535, 65535), (1, 1 << 30),
                           (1 << 30, 1), (0, 64), (64, 0), (128, 128), (65, 63)])
        data = image_dims(kind, data, w, h)
        desc.append("claims %dx%d" % (w, h))
    for _ in range(rng.choice([1, 1, 2])):
        data, what = pick(rng, BLIND_MUTATIONS)(rng, data, None, pool)
        desc.append(what)
    return data, desc


# ---------------------------------------------------------------- text
TOKENS = ["nan", "inf", "-inf", "1e300", "-1e300", "1e-300", "1e309", "-0", "0", "0x10",
          "99999999999999999999999", "1,2", "", "1e5x", "4e", "+", "--", "\"\"", "1 2",
          "179.5", "0.001", "360001"]


def mutate_text(rng, data, pool):
    lines = data.split(b"\n")
    desc = []
    for _ in range(rng.choice([1, 1, 2, 3])):
        r = rng.random()
        k = rng.randrange(len(lines))
        if r < 0.35:  # one token replaced
            toks = lines[k].split(b" ")
            j = rng.randrange(len(toks))
            toks[j] = rng.choice(TOKENS).encode()
            lines[k] = b" ".join(toks)
            desc.append("line %d token %d replaced" % (k + 1, j + 1))
        elif r < 0.45:
            lines[k] += b" " + rng.choice(TOKENS + ["1", "0.5"]).encode()
            desc.append("line %d: an extra column" % (k + 1))
        elif r < 0.55:
            lines.insert(k, lines[k])
            desc.append("line %d repeated" % (k + 1))
        elif r < 0.62:
            del lines[k]
            desc.append("line %d removed" % (k + 1))
        elif r < 0.7:
            n = rng.choice([1023, 1024, 4096, 200000])
            lines[k] = lines[k] + b" " * n + b"1"
            desc.append("line %d %d bytes longer" % (k + 1, n))
        elif r < 0.76:
            lines = lines * rng.choice([100, 10000])
            desc.append("every line repeated")
        elif r < 0.82:
            lines[k] = lines[k].replace(b" ", b"\t").replace(b"=", b"\0")
            desc.append("line %d: tabs and NUL" % (k + 1))
        else:
            d, what = pick(rng, BLIND_MUTATIONS)(rng, b"\n".join(lines) or b"\n", None, pool)
            lines = d.split(b"\n")
            desc.append(what)
    out = b"\n".join(lines)
    return out[:1 << 20], desc


def scale_camera_text(rng, text):
    """fogpipe-camera text with worldToCamera or worldToNDC (or one value
    of them) scaled: the same projective camera for worldToNDC."""
    toks = text.split(" ")
    try:
        i = toks.index("worldToCamera")
        j = toks.index("worldToNDC")
    except ValueError:
        return text, "no camera text"
    which = rng.choice(["worldToCamera", "worldToNDC"])
    lo = (i if which == "worldToCamera" else j) + 1
    k = rng.choice([1e300, 1e-300, 1e200, 1e-200, 1e-30, 1e30])
    for n in range(lo, lo + 16):
        toks[n] = "%.17g" % (float(toks[n]) * k)
    return " ".join(toks), "%s scaled by %g" % (which, k)
