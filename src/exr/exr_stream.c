/* fogpipe: stream framing (fp_exr_stream_next): one EXR file at a time
 * from a concatenated stream such as stdin.  It does not use the library:
 * a pipe cannot seek and holds several files back to back, so the bytes
 * (header, offset tables, last chunk) are walked here to know where one
 * ends, reading nothing ahead. */
#include "exr_internal.h"
#include "fp.h"
#include "fp_limits.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ stream framing */

/* Bytes of one frame read so far from a stream that cannot seek.  We only
 * ever read what the format says is next, never ahead, so the next frame's
 * first byte stays in the FILE. */
typedef struct sreader_t {
    FILE *in;
    uint8_t *buf;
    size_t len, cap;
    const char *where;
    long index;
    const char *section;   /* for messages: where we were reading */
} sreader_t;

/* Make the buffer hold `upto` bytes.  FP_OK, or FP_ERR with a message.
 * The buffer grows with the bytes that actually arrive, so a corrupt
 * offset table costs a message, not a huge allocation. */
static int sr_need(sreader_t *r, uint64_t upto)
{
    if (upto <= r->len)
        return FP_OK;
    if (upto > FP_EXR_MAX_FILE)
        return fp_error("%s: frame %ld: corrupt EXR stream (%s claims %llu bytes)",
                        r->where, r->index, r->section, (unsigned long long) upto);
    while (r->len < upto) {
        if (r->len == r->cap) {
            size_t cap = r->cap ? r->cap * 2 : 65536;
            if (cap > upto)
                cap = (size_t) upto;
            uint8_t *nb = realloc(r->buf, cap);
            if (!nb)
                return fp_error("%s: frame %ld: out of memory (%zu bytes)", r->where,
                                r->index, cap);
            r->buf = nb;
            r->cap = cap;
        }
        size_t want = (size_t) (upto < r->cap ? upto : r->cap) - r->len;
        size_t n = fread(r->buf + r->len, 1, want, r->in);
        r->len += n;
        if (n < want) {
            if (ferror(r->in))
                return fp_error("%s: frame %ld: read error (%s)", r->where,
                                r->index, strerror(errno));
            return fp_error("%s: frame %ld: truncated EXR stream (expected %llu "
                            "more bytes in the %s)", r->where, r->index,
                            (unsigned long long) (upto - r->len), r->section);
        }
    }
    return FP_OK;
}

/* Read a NUL-terminated name at *pos: at most FP_EXR_LONG_NAME characters,
 * whether or not the version field has the long-names flag (the library
 * holds the file to its flag when it parses the frame). */
static int sr_name(sreader_t *r, size_t *pos, const char **name, size_t *len)
{
    size_t start = *pos;
    for (;;) {
        if (sr_need(r, *pos + 1) != FP_OK)
            return FP_ERR;
        if (r->buf[*pos] == 0)
            break;
        if (*pos - start >= FP_EXR_LONG_NAME)
            return fp_error("%s: frame %ld: corrupt EXR header (name longer than "
                            "%d characters)", r->where, r->index, FP_EXR_LONG_NAME);
        (*pos)++;
    }
    (*pos)++;
    *len = *pos - start - 1;
    *name = (const char *) r->buf + start; /* valid until the next sr_need */
    return FP_OK;
}

/* Read one header (attributes up to the terminating NUL) at *pos.
 * *empty is set when the header has no attributes (end of a multipart
 * header list). */
static int sr_header(sreader_t *r, size_t *pos, fp_exr_hpart_t *sp, int *empty)
{
    int nattr = 0;
    *empty = 1;
    memset(sp, 0, sizeof *sp);
    sp->compression = -1;
    for (;;) {
        const char *nm, *ty;
        size_t nl, tl;
        char name[FP_EXR_LONG_NAME + 1], type[FP_EXR_LONG_NAME + 1];
        r->section = "header";
        if (sr_name(r, pos, &nm, &nl) != FP_OK)
            return FP_ERR;
        if (nl == 0)
            return FP_OK;
        memcpy(name, nm, nl + 1);
        *empty = 0;
        if (++nattr > FP_EXR_MAX_ATTRS)
            return fp_error("%s: frame %ld: corrupt EXR header (too many "
                            "attributes)", r->where, r->index);
        if (sr_name(r, pos, &ty, &tl) != FP_OK)
            return FP_ERR;
        memcpy(type, ty, tl + 1);
        if (sr_need(r, *pos + 4) != FP_OK)
            return FP_ERR;
        int32_t size = fp_exr_rd_i32(r->buf + *pos);
        *pos += 4;
        if (size < 0 || size > FP_EXR_MAX_ATTR_SIZE)
            return fp_error("%s: frame %ld: corrupt EXR header (attribute %s has "
                            "size %d)", r->where, r->index, name, (int) size);
        if (sr_need(r, *pos + (size_t) size) != FP_OK)
            return FP_ERR;
        const uint8_t *v = r->buf + *pos;
        if (strcmp(name, "compression") == 0 && size == 1 &&
            v[0] >= EXR_COMPRESSION_LAST_TYPE)
            return fp_error("%s: frame %ld: corrupt EXR header (compression "
                            "%d; expected 0-%d)", r->where, r->index, v[0],
                            EXR_COMPRESSION_LAST_TYPE - 1);
        fp_exr_hpart_take(sp, name, type, v, (uint32_t) size);
        sp->chans = NULL; /* the buffer moves as it grows */
        *pos += (size_t) size;
    }
}

/* A frame cut short in the middle of a stream borrows the start of the
 * next frame to fill its last chunk, and uncompressed data cannot tell:
 * the frame would decode, and the next one would be blamed for a bad
 * magic number.  So the last chunk (from `last` to the end) is searched
 * for the start of a frame (magic number, version 2): when it holds one
 * and the stream then goes on with anything but the start of a frame, or
 * when it ends with the first 1-4 bytes of one and the stream goes on
 * with the rest, this frame is the one cut.  The stream is peeked (one
 * byte, put back) only in those cases, so it is not otherwise read ahead. */
static int cut_short(sreader_t *r, size_t last)
{
    static const uint8_t magic[5] = { 0x76, 0x2f, 0x31, 0x01, 0x02 };
    const size_t m = sizeof magic;
    size_t borrowed = 0;   /* bytes of the next frame in ours, if cut */
    int want = -1;         /* the next byte that confirms it; -1: any but magic[0] */

    if (r->len < last + m)
        return FP_OK;
    const uint8_t *p = r->buf + last, *end = r->buf + r->len - m;
    while (p <= end && (p = memchr(p, magic[0], (size_t) (end - p) + 1)) != NULL) {
        if (memcmp(p, magic, m) == 0) {
            borrowed = r->len - (size_t) (p - r->buf);
            break;
        }
        p++;
    }
    for (size_t k = m - 1; k >= 1 && !borrowed; --k)
        if (memcmp(r->buf + r->len - k, magic, k) == 0) {
            borrowed = k;
            want = magic[k];
        }
    if (!borrowed)
        return FP_OK;
    int c = fgetc(r->in);
    if (c == EOF) {
        if (ferror(r->in))
            return fp_error("%s: frame %ld: read error (%s)", r->where, r->index,
                            strerror(errno));
        return FP_OK;
    }
    if (ungetc(c, r->in) == EOF)
        return fp_error("%s: frame %ld: read error", r->where, r->index);
    if (want >= 0 ? c != want : c == magic[0])
        return FP_OK;
    return fp_error("%s: frame %ld: truncated EXR stream (the frame is cut short: "
                    "the next frame starts %zu bytes before the end of its last "
                    "chunk)", r->where, r->index, borrowed);
}

int fp_exr_stream_next(FILE *in, const char *where_file, long index,
                       void **buf, size_t *size)
{
    sreader_t r = { in, NULL, 0, 0, where_file ? where_file : "<stdin>", index,
                    "header" };
    fp_exr_hpart_t *parts = NULL;
    int nparts = 0, cap = 0;
    int rc = FP_ERR;
    size_t pos = 0;

    *buf = NULL;
    *size = 0;

    /* A clean end: not a single byte where a frame would start. */
    int ch = fgetc(in);
    if (ch == EOF) {
        if (ferror(in)) {
            fp_error("%s: frame %ld: read error (%s)", r.where, index,
                     strerror(errno));
            goto done;
        }
        rc = FP_EOF;
        goto done;
    }
    if (ungetc(ch, in) == EOF) {
        fp_error("%s: frame %ld: read error", r.where, index);
        goto done;
    }

    r.section = "magic number";
    if (sr_need(&r, 4) != FP_OK)
        goto done;
    if (fp_exr_rd_u32(r.buf) != FP_EXR_MAGIC) {
        fp_error("%s: frame %ld: not an EXR file (bad magic number)", r.where, index);
        goto done;
    }
    r.section = "version field";
    if (sr_need(&r, 8) != FP_OK)
        goto done;
    uint32_t version = fp_exr_rd_u32(r.buf + 4);
    int multipart = (version & 0x1000) != 0;
    if ((version & 0xff) != 2) {
        fp_error("%s: frame %ld: unsupported EXR version %u (expected 2)", r.where,
                 index, version & 0xff);
        goto done;
    }
    pos = 8;
    for (;;) {
        fp_exr_hpart_t sp;
        int empty;
        if (sr_header(&r, &pos, &sp, &empty) != FP_OK)
            goto done;
        if (empty && multipart)
            break; /* the extra NUL after the last header */
        if (empty || !sp.has_dw) {
            fp_error("%s: frame %ld: corrupt EXR header (part %d has no "
                     "dataWindow)", r.where, index, nparts);
            goto done;
        }
        if (!multipart && (version & 0x200)) {
            sp.tiled = 1;
        }
        if (sp.deep && sp.tiled) {
            fp_error("%s: frame %ld: part %d holds deep tiled data, which is not "
                     "supported (expected deep scanline)", r.where, index, nparts);
            goto done;
        }
        if (sp.tiled && !sp.has_tiles) {
            fp_error("%s: frame %ld: corrupt EXR header (tiled part %d without "
                     "tile description)", r.where, index, nparts);
            goto done;
        }
        if (!sp.has_cc)
            sp.chunk_count = fp_exr_count_chunks(&sp, NULL);
        if (sp.chunk_count < 1 || sp.chunk_count > FP_EXR_MAX_CHUNKS) {
            fp_error("%s: frame %ld: corrupt EXR header (part %d: %lld chunks)",
                     r.where, index, nparts, (long long) sp.chunk_count);
            goto done;
        }
        if (nparts == cap) {
            int ncap = cap ? cap * 2 : 4;
            fp_exr_hpart_t *np = realloc(parts, (size_t) ncap * sizeof *np);
            if (!np) {
                fp_error("%s: frame %ld: out of memory", r.where, index);
                goto done;
            }
            parts = np;
            cap = ncap;
        }
        parts[nparts++] = sp;
        if (!multipart)
            break;
        if (nparts > fp_image_limits()->max_parts) {
            fp_error("%s: frame %ld: more than %d parts (the image budget; "
                     "--max-image-pixels raises it)", r.where, index,
                     fp_image_limits()->max_parts);
            goto done;
        }
    }

    /* The version's deep-data flag and the parts' types must agree. */
    int any_deep = 0;
    for (int p = 0; p < nparts; ++p)
        any_deep |= parts[p].deep;
    if (!multipart && any_deep != ((version & 0x800) != 0)) {
        fp_error("%s: frame %ld: corrupt EXR header (the version field %s deep data, the "
                 "part's type %s)", r.where, index, any_deep ? "does not flag" : "flags",
                 any_deep ? "is deep" : "is not");
        goto done;
    }

    /* Offset tables: the frame ends with the chunk that starts last. */
    int64_t total = 0;
    for (int p = 0; p < nparts; ++p)
        total += parts[p].chunk_count;
    if (total > FP_EXR_MAX_CHUNKS) {
        fp_error("%s: frame %ld: corrupt EXR header (%lld chunks)", r.where, index,
                 (long long) total);
        goto done;
    }
    r.section = "offset table";
    if (sr_need(&r, pos + (uint64_t) total * 8) != FP_OK)
        goto done;
    size_t table_end = pos + (size_t) total * 8;
    uint64_t last = 0;
    for (int64_t i = 0; i < total; ++i) {
        uint64_t off = fp_exr_rd_u64(r.buf + pos + (size_t) i * 8);
        if (off != 0 && (off < table_end || off > FP_EXR_MAX_FILE)) {
            fp_error("%s: frame %ld: corrupt EXR offset table (chunk %lld at %llu)",
                     r.where, index, (long long) i, (unsigned long long) off);
            goto done;
        }
        if (off > last)
            last = off;
    }
    if (last == 0) {
        fp_error("%s: frame %ld: corrupt EXR offset table (no chunk offsets)",
                 r.where, index);
        goto done;
    }

    r.section = "chunk data";
    if (sr_need(&r, last) != FP_OK)
        goto done;
    uint64_t at = last;
    int part = 0;
    if (multipart) {
        if (sr_need(&r, at + 4) != FP_OK)
            goto done;
        part = fp_exr_rd_i32(r.buf + at);
        at += 4;
        if (part < 0 || part >= nparts) {
            fp_error("%s: frame %ld: corrupt EXR chunk (part number %d of %d)",
                     r.where, index, part, nparts);
            goto done;
        }
    }
    /* deep scanline: y, the sizes of the packed sample count table, of
     * the packed data and of the unpacked data, then table and data */
    if (parts[part].deep) {
        if (sr_need(&r, at + 28) != FP_OK)
            goto done;
        uint64_t tsize = fp_exr_rd_u64(r.buf + at + 4), psize = fp_exr_rd_u64(r.buf + at + 12);
        if (tsize > FP_EXR_MAX_FILE || psize > FP_EXR_MAX_FILE) {
            fp_error("%s: frame %ld: corrupt deep EXR chunk (sizes %llu and %llu)", r.where,
                     index, (unsigned long long) tsize, (unsigned long long) psize);
            goto done;
        }
        if (sr_need(&r, at + 28 + tsize + psize) != FP_OK || cut_short(&r, (size_t) last))
            goto done;
        *buf = r.buf;
        *size = r.len;
        r.buf = NULL;
        rc = FP_OK;
        goto done;
    }
    /* tiled: tile x, y, level x, y; scanline: y; then the data size */
    uint64_t lead = parts[part].tiled ? 16 : 4;
    if (sr_need(&r, at + lead + 4) != FP_OK)
        goto done;
    int32_t dsize = fp_exr_rd_i32(r.buf + at + lead);
    if (dsize < 0) {
        fp_error("%s: frame %ld: corrupt EXR chunk (size %d)", r.where, index,
                 (int) dsize);
        goto done;
    }
    if (sr_need(&r, at + lead + 4 + (uint64_t) dsize) != FP_OK)
        goto done;
    if (cut_short(&r, (size_t) last) != FP_OK)
        goto done;

    *buf = r.buf;
    *size = r.len;
    r.buf = NULL;
    rc = FP_OK;
done:
    free(r.buf);
    free(parts);
    return rc;
}
