"""fogpipe fuzz harness: where things are in an OpenEXR file.

Enough of the layout (openexr.com, "OpenEXR File Layout") to aim mutations
at header attribute values, offset tables and chunk headers, and to edit a
header (an attribute's value or type) with the offset tables moved to
match: magic, version (flags 0x200 single-part tiled, 0x1000 multipart,
0x800 deep), one header per part (name\\0 type\\0 int32 size value ...,
ended by \\0; multipart: an empty header ends the list), one offset table
(uint64 per chunk) per part, then chunks (multipart: int32 part number
first; scanline: int32 y, int32 size, data; tiled: int32 tx, ty, lx, ly,
int32 size, data).  Standard library only."""
import struct

MAGIC = b"\x76\x2f\x31\x01"
# lines per chunk of each compression (the enum value's order)
LINES = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}


class Attr:
    def __init__(self, part, name, type_, start, value_at, size):
        self.part, self.name, self.type, self.start = part, name, type_, start
        self.value_at, self.size = value_at, size

    @property
    def end(self):
        return self.value_at + self.size


class Layout:
    """attrs: every attribute (Attr); tables: per part (offset, count) of
    its offset table; chunks: (part, start, header_len, data_size) of each
    chunk the tables point to; header_end: first byte after the headers."""

    def __init__(self, data):
        self.data = data
        if len(data) < 8 or data[:4] != MAGIC:
            raise ValueError("not an EXR file")
        flags = struct.unpack_from("<I", data, 4)[0]
        self.tiled = bool(flags & 0x200)
        self.multipart = bool(flags & 0x1000)
        self.attrs = []
        self.parts = []  # per part: {name: Attr}
        p = 8
        part = 0
        while True:
            cur = {}
            if data[p] == 0:  # an empty header: end of a multipart list
                p += 1
                break
            while data[p] != 0:
                n = data.index(b"\0", p)
                t = data.index(b"\0", n + 1)
                size = struct.unpack_from("<i", data, t + 1)[0]
                a = Attr(part, data[p:n].decode("latin-1"), data[n + 1:t].decode("latin-1"),
                         p, t + 5, size)
                if size < 0 or a.end > len(data):
                    raise ValueError("attribute %s runs past the end" % a.name)
                self.attrs.append(a)
                cur[a.name] = a
                p = a.end
            p += 1
            self.parts.append(cur)
            part += 1
            if not self.multipart:
                break
        self.header_end = p
        self.tables = []
        for i, attrs in enumerate(self.parts):
            self.tables.append((p, self._count(attrs, p if i == 0 else None)))
            p += 8 * self.tables[-1][1]
        self.chunks = []
        for i, (at, n) in enumerate(self.tables):
            for k in range(n):
                off = struct.unpack_from("<Q", data, at + 8 * k)[0]
                hl = (4 if self.multipart else 0) + (20 if self._is_tiled(i) else 8)
                if off + hl > len(data):
                    continue
                size = struct.unpack_from("<i", data, off + hl - 4)[0]
                self.chunks.append((i, off, hl, size))

    def _is_tiled(self, i):
        t = self.parts[i].get("type")
        if t is not None:
            return b"tile" in self.data[t.value_at:t.end]
        return self.tiled

    def _count(self, attrs, first_table):
        cc = attrs.get("chunkCount")
        if cc is not None:
            return struct.unpack_from("<i", self.data, cc.value_at)[0]
        # single part: the first chunk starts where the table ends
        if first_table is not None and first_table + 8 <= len(self.data):
            first = struct.unpack_from("<Q", self.data, first_table)[0]
            if first > first_table and (first - first_table) % 8 == 0:
                return min((first - first_table) // 8, (len(self.data) - first_table) // 8)
        dw = attrs["dataWindow"]
        x0, y0, x1, y1 = struct.unpack_from("<4i", self.data, dw.value_at)
        comp = self.data[attrs["compression"].value_at]
        return (y1 - y0 + LINES.get(comp, 1)) // LINES.get(comp, 1)

    def attr(self, name, part=0):
        return self.parts[part].get(name) if part < len(self.parts) else None


def replace_attr(data, attr, value=None, type_=None):
    """The file with one attribute's value (bytes) and/or type name
    replaced, every offset table moved by the change of header length."""
    lay = Layout(data)
    a = next(x for x in lay.attrs if x.start == attr.start)
    value = data[a.value_at:a.end] if value is None else value
    type_ = a.type if type_ is None else type_
    new = (a.name.encode("latin-1") + b"\0" + type_.encode("latin-1") + b"\0" +
           struct.pack("<i", len(value)) + value)
    delta = len(new) - (a.end - a.start)
    out = bytearray(data[:a.start] + new + data[a.end:])
    for at, n in lay.tables:
        for k in range(n):
            q = at + delta + 8 * k
            if q + 8 > len(out):
                break
            off = struct.unpack_from("<Q", out, q)[0]
            if off >= lay.header_end:
                struct.pack_into("<Q", out, q, off + delta)
    return bytes(out)


def set_string(data, name, text, part=0):
    a = Layout(data).attr(name, part)
    return replace_attr(data, a, text.encode("latin-1")) if a else data


def normalized(data):
    """oiiotool's writer stamps the time (capDate, Exif:ImageHistory):
    fixed values, so that fixtures and so the mutations are the same on
    every run."""
    for name in ("capDate", "Exif:ImageHistory", "DateTime"):
        while True:
            lay = Layout(data)
            a = next((x for x in lay.attrs if x.name == name and
                      data[x.value_at:x.end] != b"2000:01:01 00:00:00"), None)
            if a is None:
                break
            data = replace_attr(data, a, b"2000:01:01 00:00:00")
    return data


def set_data_window(data, x1, y1, part=0, x0=0, y0=0):
    """The file claiming a data window of (x0,y0)-(x1,y1) (its display
    window too), its offset table and chunks left as they are."""
    lay = Layout(data)
    out = bytearray(data)
    for name in ("dataWindow", "displayWindow"):
        a = lay.attr(name, part)
        if a is not None and a.size == 16:
            struct.pack_into("<4i", out, a.value_at, x0, y0, x1, y1)
    return bytes(out)
