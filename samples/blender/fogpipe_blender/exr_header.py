# fogpipe for Blender: string attributes added to a rendered EXR's header
# (the add-on's render_write handler: the complete rig and look, which the
# stamp's Note cannot hold).  Pure Python, no bpy: the tests call it too.
# Only single-part scanline files are rewritten; the chunks are copied byte
# for byte and the offset table moved by the header's change in length.

import os
import struct


class ExrError(Exception):
    pass


# Scanlines per chunk of each OpenEXR compression (openexr_attr.h order).
LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}


def exr_header(data):
    """(attributes [(name, type, value, raw bytes)], end of header) of a
    single-part scanline OpenEXR file; ExrError for anything else."""
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ExrError("not an OpenEXR file")
    if len(data) < 8:
        raise ExrError("truncated header")
    version = struct.unpack_from("<I", data, 4)[0]
    if version & 0xFF != 2:
        raise ExrError("OpenEXR version %d (expected 2)" % (version & 0xFF))
    if version & 0x1000:
        raise ExrError("a multi-part file (only single-part scanline files are patched)")
    if version & 0x800:
        raise ExrError("deep data (only single-part scanline files are patched)")
    if version & 0x200:
        raise ExrError("a tiled file (only single-part scanline files are patched)")
    pos, attrs = 8, []
    try:
        while data[pos] != 0:
            n_end = data.index(b"\0", pos, pos + 256)
            t_end = data.index(b"\0", n_end + 1, n_end + 257)
            size = struct.unpack_from("<i", data, t_end + 1)[0]
            start = t_end + 5
            if size < 0 or start + size > len(data):
                raise ExrError("attribute '%s' runs past the end of the file"
                               % data[pos:n_end].decode("latin-1"))
            attrs.append((data[pos:n_end].decode("latin-1"),
                          data[n_end + 1:t_end].decode("latin-1"),
                          data[start:start + size], data[pos:start + size]))
            pos = start + size
    except (IndexError, ValueError, struct.error):
        raise ExrError("truncated or malformed header") from None
    return attrs, pos + 1


def exr_set_strings(path, values):
    """Add (or replace) the string attributes {name: text} in the header of the
    single-part scanline EXR `path`, in place and atomically (a temporary
    file renamed over it).  The chunks are copied byte for byte; every
    offset-table entry moves by the header's change in length, and each is
    checked to point at its chunk first."""
    with open(path, "rb") as f:
        data = f.read()
    attrs, end = exr_header(data)
    types = {a[0]: (a[1], a[2]) for a in attrs}
    for need, typ in (("dataWindow", "box2i"), ("compression", "compression")):
        if types.get(need, ("",))[0] != typ:
            raise ExrError("no %s attribute of type %s" % (need, typ))
    if "type" in types and types["type"][1].rstrip(b"\0") != b"scanlineimage":
        raise ExrError("part type '%s' (only scanline images are patched)"
                       % types["type"][1].decode("latin-1"))
    _, ymin, _, ymax = struct.unpack_from("<4i", types["dataWindow"][1])
    comp = types["compression"][1][0]
    if comp not in LINES_PER_CHUNK:
        raise ExrError("unknown compression %d" % comp)
    lines = LINES_PER_CHUNK[comp]
    count = (ymax - ymin + lines) // lines
    table_end = end + 8 * count
    if count < 1 or table_end > len(data):
        raise ExrError("truncated offset table")
    offsets = struct.unpack_from("<%dQ" % count, data, end)
    for i, o in enumerate(offsets):
        if o < table_end or o + 8 > len(data):
            raise ExrError("offset table entry %d (%d) is outside the file's chunks" % (i, o))
        y, size = struct.unpack_from("<ii", data, o)
        if y != ymin + i * lines or size < 0 or o + 8 + size > len(data):
            raise ExrError("offset table entry %d points at a chunk of y %d, %d bytes "
                           "(expected y %d within the file)" % (i, y, size, ymin + i * lines))
    ours = b""
    for name in sorted(values):
        raw = values[name].encode("utf-8")
        ours += name.encode("latin-1") + b"\0string\0" + struct.pack("<i", len(raw)) + raw
    header = data[:8] + b"".join(a[3] for a in attrs if a[0] not in values) + ours + b"\0"
    delta = len(header) - end
    table = struct.pack("<%dQ" % count, *(o + delta for o in offsets))
    tmp = "%s.fogpipe-tmp.%d" % (path, os.getpid())
    try:
        with open(tmp, "wb") as f:
            f.write(header)
            f.write(table)
            f.write(memoryview(data)[table_end:])
        os.chmod(tmp, os.stat(path).st_mode & 0o7777)
        os.replace(tmp, path)
    except OSError:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
