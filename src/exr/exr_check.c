/* fogpipe: an EXR image held in memory checked from its bytes before
 * anything is allocated for its pixels or any codec runs (exr_internal.h,
 * fp_exr_check_image).  One walk for every reader: the C path and the C++
 * codec path (DWA, B44, exr_dwa.h) start from the same verdict, so a
 * header that claims a giant image costs a message, not gigabytes.
 *
 * Three questions, each answered from the header, the offset tables and
 * the chunk headers alone:
 *   - the image budget (src/base/fp_limits.h): pixels, axis, channels, line bytes,
 *     parts;
 *   - can the file hold what the header claims: the offset tables and the
 *     chunk headers must fit in it, and the decoded bytes must not exceed
 *     the compression's largest possible ratio times the file's size (so
 *     the memory a frame costs is bounded by its size);
 *   - each chunk of the part's highest resolution against the bytes its
 *     lines need: an uncompressed chunk must hold exactly them, a
 *     compressed one at least them over its codec's largest ratio;
 *   - what OpenEXR's C library reads and its C++ library refuses (so that
 *     the path a file takes does not decide whether it is refused): a
 *     channel list that does not end with the attribute, parts of a
 *     multipart file that differ in the attributes they share, chunks
 *     that share bytes.
 * Bytes this walk cannot frame (a name without its NUL, an attribute past
 * the end) are left to the library, whose message says what is wrong. */
#include "exr_internal.h"
#include "fp.h"
#include "fp_limits.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ codec ratios */

/* The most decoded bytes one packed byte can give, per compression (the
 * codec's own limit, so that no valid file is refused):
 *   NONE   1: the bytes are the pixels;
 *   RLE    64: a run of at most 127 bytes costs 2;
 *   ZIPS, ZIP  1032: deflate's limit (258 bytes from a 2-bit code);
 *   PIZ    512: Huffman codes of at least 1 bit, runs of at most 256
 *          symbols of 16 bits in one code, its run code and 8 bits
 *          (4096 bits in 10: 410);
 *   PXR24  1376: deflate over floats cut to 24 bits (1032 x 4/3);
 *   B44, B44A  11: a 4x4 block of halves (32 bytes) in 14 bytes, a flat
 *          one in 3 (B44A); float channels are stored raw;
 *   DWAA, DWAB  66048: an 8x8 block of halves (128 bytes) gives at least
 *          a DC value and an end-of-block code (4 bytes), both deflated;
 *          RLE channels are RLE'd (64), then deflated. */
static int64_t max_ratio(int compression)
{
    switch (compression) {
    case EXR_COMPRESSION_NONE: return 1;
    case EXR_COMPRESSION_RLE: return 64;
    case EXR_COMPRESSION_ZIPS:
    case EXR_COMPRESSION_ZIP: return 1032;
    case EXR_COMPRESSION_PIZ: return 512;
    case EXR_COMPRESSION_PXR24: return 1376;
    case EXR_COMPRESSION_B44:
    case EXR_COMPRESSION_B44A: return 11;
    default: return 66048; /* DWAA, DWAB */
    }
}

/* ------------------------------------------------------------ chunk counts */

static int round_log2(uint32_t x, int round_up)
{
    int y = 0, odd = 0;
    while (x > 1) {
        if (x & 1)
            odd = 1;
        y++;
        x >>= 1;
    }
    return round_up ? y + odd : y;
}

static int64_t level_size(int64_t size, int l, int round_up)
{
    int64_t b = (int64_t) 1 << l;
    int64_t s = size / b;
    if (round_up && s * b < size)
        s++;
    return s < 1 ? 1 : s;
}

int fp_exr_lines_per_chunk(int compression)
{
    static const int lines[] = { 1, 1, 1, 16, 32, 16, 32, 32, 32, 256 };
    if (compression < 0 || compression >= (int) FP_ARRAY_LEN(lines))
        return -1;
    return lines[compression];
}

int64_t fp_exr_count_chunks(const fp_exr_hpart_t *sp, int64_t *level0)
{
    int64_t w = (int64_t) sp->dw[2] - sp->dw[0] + 1;
    int64_t h = (int64_t) sp->dw[3] - sp->dw[1] + 1;
    if (w < 1 || h < 1 || w > INT32_MAX || h > INT32_MAX)
        return -1;
    if (!sp->tiled) {
        int64_t l = fp_exr_lines_per_chunk(sp->compression);
        if (l < 1)
            return -1;
        if (level0)
            *level0 = (h + l - 1) / l;
        return (h + l - 1) / l;
    }
    if (sp->tx < 1 || sp->ty < 1)
        return -1;
    if (level0)
        *level0 = ((w + sp->tx - 1) / sp->tx) * ((h + sp->ty - 1) / sp->ty);
    int up = sp->round_mode == EXR_TILE_ROUND_UP;
    int nx = 1, ny = 1;
    if (sp->level_mode == EXR_TILE_MIPMAP_LEVELS) {
        nx = ny = round_log2((uint32_t) (w > h ? w : h), up) + 1;
    } else if (sp->level_mode == EXR_TILE_RIPMAP_LEVELS) {
        nx = round_log2((uint32_t) w, up) + 1;
        ny = round_log2((uint32_t) h, up) + 1;
    } else if (sp->level_mode != EXR_TILE_ONE_LEVEL) {
        return -1;
    }
    int64_t total = 0;
    for (int ly = 0; ly < (sp->level_mode == EXR_TILE_RIPMAP_LEVELS ? ny : 1); ++ly)
        for (int lx = 0; lx < nx; ++lx) {
            int lyy = sp->level_mode == EXR_TILE_RIPMAP_LEVELS ? ly : lx;
            int64_t lw = level_size(w, lx, up), lh = level_size(h, lyy, up);
            total += ((lw + sp->tx - 1) / sp->tx) * ((lh + sp->ty - 1) / sp->ty);
            if (total > FP_EXR_MAX_CHUNKS)
                return total;
        }
    return total;
}

/* ------------------------------------------------------------ header */

/* One attribute of a header in memory, as fp_exr_hpart_t wants it. */
void fp_exr_hpart_take(fp_exr_hpart_t *sp, const char *name, const char *type,
                       const uint8_t *v, uint32_t size)
{
    if (strcmp(name, "dataWindow") == 0 && strcmp(type, "box2i") == 0 && size == 16) {
        for (int i = 0; i < 4; ++i)
            sp->dw[i] = fp_exr_rd_i32(v + 4 * i);
        sp->has_dw = 1;
    } else if (strcmp(name, "compression") == 0 && size == 1) {
        sp->compression = v[0];
    } else if (strcmp(name, "tiles") == 0 && strcmp(type, "tiledesc") == 0 && size == 9) {
        sp->tx = fp_exr_rd_u32(v);
        sp->ty = fp_exr_rd_u32(v + 4);
        sp->level_mode = v[8] & 0xf;
        sp->round_mode = (v[8] >> 4) & 0xf;
        sp->has_tiles = 1;
    } else if (strcmp(name, "chunkCount") == 0 && strcmp(type, "int") == 0 && size == 4) {
        sp->chunk_count = fp_exr_rd_i32(v);
        sp->has_cc = 1;
    } else if (strcmp(name, "type") == 0 && strcmp(type, "string") == 0) {
        if ((size == 12 && memcmp(v, "deepscanline", 12) == 0) ||
            (size == 8 && memcmp(v, "deeptile", 8) == 0))
            sp->deep = 1;
        else if (size == 10 && memcmp(v, "tiledimage", 10) == 0)
            sp->tiled = 1;
    } else if (strcmp(name, "channels") == 0 && strcmp(type, "chlist") == 0) {
        sp->chans = v;
        sp->chans_size = size;
    } else if (strcmp(name, "displayWindow") == 0 && strcmp(type, "box2i") == 0 && size == 16) {
        sp->disp = v;
    } else if (strcmp(name, "pixelAspectRatio") == 0 && strcmp(type, "float") == 0 && size == 4) {
        sp->aspect = v;
    } else if (strcmp(name, "chromaticities") == 0 && strcmp(type, "chromaticities") == 0 &&
               size == 32) {
        sp->chroma = v;
    } else if (strcmp(name, "timecode") == 0 && strcmp(type, "timecode") == 0 && size == 8) {
        sp->timecode = v;
    }
}

/* A name at *pos (NUL-terminated, at most FP_EXR_LONG_NAME characters):
 * 0, or -1 when the bytes end first. */
static int take_name(const uint8_t *b, size_t size, size_t *pos, char *out)
{
    size_t start = *pos;
    while (*pos < size && b[*pos] != 0) {
        if (*pos - start >= FP_EXR_LONG_NAME)
            return -1;
        (*pos)++;
    }
    if (*pos >= size)
        return -1;
    memcpy(out, b + start, *pos - start + 1);
    (*pos)++;
    return 0;
}

/* The channels of a part: count, and the decoded bytes of the lines
 * [ya, yb) over the columns [xa, xb) (sampled as OpenEXR samples).  -1
 * for an entry the library should name; -2 when the list does not end
 * with its NUL at its last byte: OpenEXR's C library reads such a list
 * (up to the attribute's size), the C++ library reads on into the next
 * attribute, so the file is corrupt and only one of them would say so. */
typedef struct chan_sum_t {
    int n;
    int max_bpe;
} chan_sum_t;

static int walk_channels(const fp_exr_hpart_t *sp, chan_sum_t *cs, int64_t xa, int64_t xb,
                         int64_t ya, int64_t yb, int64_t *bytes)
{
    const uint8_t *b = sp->chans;
    size_t end = sp->chans_size, q = 0;
    int64_t total = 0;
    cs->n = 0;
    cs->max_bpe = 0;
    while (q < end && b[q] != 0) {
        const void *z = memchr(b + q, 0, end - q);
        if (!z)
            return -1;
        q = (size_t) ((const uint8_t *) z - b) + 1;
        if (end - q < 16)
            return -1;
        uint32_t type = fp_exr_rd_u32(b + q);
        int32_t xs = fp_exr_rd_i32(b + q + 8), ys = fp_exr_rd_i32(b + q + 12);
        q += 16;
        if (type > EXR_PIXEL_FLOAT || xs < 1 || ys < 1)
            return -1; /* the library says what is wrong */
        int bpe = type == EXR_PIXEL_HALF ? 2 : 4;
        if (bpe > cs->max_bpe)
            cs->max_bpe = bpe;
        cs->n++;
        total += sampled_count(xa, xb, xs) * sampled_count(ya, yb, ys) * bpe;
    }
    if (q + 1 != end)
        return -2;
    *bytes = total;
    return 0;
}

/* n little-endian floats compared as values (a -0 is 0, a NaN differs
 * from everything), as OpenEXR's C++ library compares them. */
static int floats_differ(const uint8_t *a, const uint8_t *b, int n)
{
    for (int i = 0; i < n; ++i) {
        float x, y;
        uint32_t u = fp_exr_rd_u32(a + 4 * i), v = fp_exr_rd_u32(b + 4 * i);
        memcpy(&x, &u, 4);
        memcpy(&y, &v, 4);
        if (x != y)
            return 1;
    }
    return 0;
}

/* Whether a part of a multipart file disagrees with part 0 on an
 * attribute they must share (OpenEXR's MultiPartInputFile refuses such a
 * file, checkSharedAttributesValues): its name, else NULL.  displayWindow
 * and pixelAspectRatio in every part, chromaticities and timecode when the
 * part has them (as the C++ library names them). */
static const char *shared_differs(const fp_exr_hpart_t *p0, const fp_exr_hpart_t *sp)
{
    if (p0->disp && sp->disp && memcmp(p0->disp, sp->disp, 16) != 0)
        return "displayWindow";
    if (p0->aspect && sp->aspect && floats_differ(p0->aspect, sp->aspect, 1))
        return "pixelAspectRatio";
    if (sp->chroma && (!p0->chroma || floats_differ(p0->chroma, sp->chroma, 8)))
        return "chromaticities";
    if (sp->timecode && (!p0->timecode || memcmp(p0->timecode, sp->timecode, 8) != 0))
        return "timecode";
    return NULL;
}

/* ------------------------------------------------------------ overlaps */

/* One chunk's bytes in the file: [start, end). */
typedef struct chunk_span_t {
    uint64_t start, end;
} chunk_span_t;

static int span_cmp(const void *a, const void *b)
{
    const chunk_span_t *x = a, *y = b;
    return x->start < y->start ? -1 : x->start > y->start;
}

/* Where entry i of part p's table points, and the end of that chunk (its
 * header and the bytes its size field claims): 0, or -1 when it cannot be
 * framed there (the library names that). */
static int chunk_span(const uint8_t *b, size_t size, size_t table_end, int multipart,
                      const fp_exr_hpart_t *sp, size_t table, int64_t i, chunk_span_t *out)
{
    uint64_t off = fp_exr_rd_u64(b + table + (size_t) i * 8);
    size_t hl = (multipart ? 4 : 0) + (sp->tiled ? 16 : 4) + 4;
    if (off < table_end || off >= size || size - off < hl)
        return -1;
    int32_t packed = fp_exr_rd_i32(b + off + hl - 4);
    if (packed < 0 || (uint64_t) packed > size - off - hl)
        return -1;
    out->start = off;
    out->end = off + hl + (uint64_t) packed;
    return 0;
}

/* No two chunks may share bytes.  A size field one too large lets a
 * lenient decoder (deflate stops at its stream's end) read a chunk whose
 * last byte is the next chunk's first, while OpenEXR's C++ library, which
 * reads a scanline file's chunks one after the other, then finds the next
 * chunk one byte late: the file is corrupt. */
static int check_overlaps(const uint8_t *b, size_t size, size_t table_end, int multipart,
                          const fp_exr_hpart_t *parts, int nparts, size_t tables,
                          int64_t chunks, const char *where, long frame)
{
    chunk_span_t *sp = malloc((size_t) (chunks > 0 ? chunks : 1) * sizeof *sp);
    if (!sp)
        return fp_error("%s: frame %ld: out of memory", where, frame);
    int64_t n = 0;
    size_t table = tables;
    for (int p = 0; p < nparts; ++p) {
        for (int64_t i = 0; i < parts[p].chunk_count; ++i)
            if (chunk_span(b, size, table_end, multipart, &parts[p], table, i, &sp[n]) == 0)
                n++;
        table += (size_t) parts[p].chunk_count * 8;
    }
    qsort(sp, (size_t) n, sizeof *sp, span_cmp);
    int rc = FP_OK;
    for (int64_t k = 0; k + 1 < n && rc == FP_OK; ++k) {
        if (sp[k].end <= sp[k + 1].start)
            continue;
        /* name the chunk that runs over by its part and number */
        int part = 0;
        int64_t idx = 0;
        table = tables;
        for (int p = 0; p < nparts; ++p) {
            for (int64_t i = 0; i < parts[p].chunk_count; ++i)
                if (fp_exr_rd_u64(b + table + (size_t) i * 8) == sp[k].start) {
                    part = p;
                    idx = i;
                }
            table += (size_t) parts[p].chunk_count * 8;
        }
        rc = fp_error("%s: frame %ld: part %d: chunk %lld (at byte %llu, %llu bytes with its "
                      "header) runs into the chunk at byte %llu (corrupt EXR: chunks do not "
                      "share bytes)", where, frame, part, (long long) idx,
                      (unsigned long long) sp[k].start,
                      (unsigned long long) (sp[k].end - sp[k].start),
                      (unsigned long long) sp[k + 1].start);
    }
    free(sp);
    return rc;
}

/* ------------------------------------------------------------ the check */

int fp_exr_check_image(const void *buf, size_t size, const char *where, long frame)
{
    const uint8_t *b = buf;
    const fp_image_limits_t *lim = fp_image_limits();
    fp_exr_hpart_t *parts = NULL;
    int nparts = 0, cap = 0;
    int rc = FP_OK;

    if (size < 8 || fp_exr_rd_u32(b) != FP_EXR_MAGIC)
        return FP_OK;
    uint32_t version = fp_exr_rd_u32(b + 4);
    int multipart = (version & 0x1000) != 0;
    if ((version & 0xff) != 2 || (version & 0x800))
        return FP_OK; /* the reader refuses deep data and other versions */

    /* The headers. */
    size_t pos = 8;
    for (;;) {
        fp_exr_hpart_t sp;
        memset(&sp, 0, sizeof sp);
        sp.compression = -1;
        int empty = 1;
        for (;;) {
            char name[FP_EXR_LONG_NAME + 1], type[FP_EXR_LONG_NAME + 1];
            if (take_name(b, size, &pos, name) != 0)
                goto unframed;
            if (!name[0])
                break;
            empty = 0;
            if (take_name(b, size, &pos, type) != 0 || size - pos < 4)
                goto unframed;
            uint32_t as = fp_exr_rd_u32(b + pos);
            pos += 4;
            if (as > size - pos)
                goto unframed;
            fp_exr_hpart_take(&sp, name, type, b + pos, as);
            pos += as;
        }
        if (empty && multipart)
            break;
        if (!sp.has_dw || !sp.chans || sp.deep || sp.compression < 0 ||
            sp.compression >= EXR_COMPRESSION_LAST_TYPE)
            goto unframed; /* the library's message is the better one */
        if (!multipart && (version & 0x200))
            sp.tiled = 1;
        if (sp.tiled && !sp.has_tiles)
            goto unframed;
        if (nparts >= lim->max_parts) {
            rc = fp_error("%s: frame %ld: more than %d parts (the image budget; "
                          "--max-image-pixels raises it)", where, frame, lim->max_parts);
            goto done;
        }
        if (nparts == cap) {
            int ncap = cap ? cap * 2 : 4;
            fp_exr_hpart_t *np = realloc(parts, (size_t) ncap * sizeof *np);
            if (!np) {
                rc = fp_error("%s: frame %ld: out of memory", where, frame);
                goto done;
            }
            parts = np;
            cap = ncap;
        }
        parts[nparts++] = sp;
        if (!multipart)
            break;
    }

    /* The budget, and what the file must hold for what its headers claim. */
    int64_t chunks = 0;       /* offset table entries */
    int64_t min_bytes = 0;    /* packed bytes the pixels need at the least */
    int64_t decoded = 0;      /* bytes they decode to */
    for (int p = 0; p < nparts; ++p) {
        fp_exr_hpart_t *sp = &parts[p];
        int64_t w = (int64_t) sp->dw[2] - sp->dw[0] + 1;
        int64_t h = (int64_t) sp->dw[3] - sp->dw[1] + 1;
        chan_sum_t cs;
        int64_t bytes = 0;
        char kind[64];
        snprintf(kind, sizeof kind, "part %d: data window", p);
        if (w < 1 || h < 1)
            goto unframed; /* an empty window: the library names it */
        int wc = walk_channels(sp, &cs, 0, 1, 0, 1, &bytes);
        if (wc == -2) {
            rc = fp_error("%s: frame %ld: part %d: channel list of %u bytes does not end with "
                          "the NUL after its last channel (corrupt EXR header)", where, frame,
                          p, (unsigned) sp->chans_size);
            goto done;
        }
        if (wc != 0)
            goto unframed;
        const char *shared = p > 0 ? shared_differs(&parts[0], sp) : NULL;
        if (shared) {
            rc = fp_error("%s: frame %ld: part %d: %s differs from part 0's (the parts of a "
                          "multipart EXR share it; corrupt EXR header)", where, frame, p, shared);
            goto done;
        }
        if ((rc = fp_image_limits_check(where, frame, kind, w, h, cs.n, cs.max_bpe)) != FP_OK)
            goto done;
        if (sp->tiled && (sp->tx > (uint32_t) lim->max_dim || sp->ty > (uint32_t) lim->max_dim))
            goto unframed;
        walk_channels(sp, &cs, sp->dw[0], (int64_t) sp->dw[2] + 1, sp->dw[1],
                      (int64_t) sp->dw[3] + 1, &bytes);
        int64_t level0 = 0;
        int64_t n = fp_exr_count_chunks(sp, &level0);
        if (n < 1 || n > FP_EXR_MAX_CHUNKS)
            goto unframed;
        if (sp->has_cc)
            n = sp->chunk_count;
        if (n < 1 || n > FP_EXR_MAX_CHUNKS)
            goto unframed;
        sp->chunk_count = n;
        chunks += n;
        decoded += bytes;
        int64_t r = max_ratio(sp->compression);
        min_bytes += (bytes + r - 1) / r;
        /* every chunk has a header: its part number, coordinates and size */
        min_bytes += n * ((multipart ? 4 : 0) + (sp->tiled ? 20 : 8));
    }
    if (chunks > (int64_t) ((size - pos) / 8)) {
        rc = fp_error("%s: frame %ld: corrupt or truncated EXR (its header implies %lld "
                      "chunks, whose offset tables alone need %lld bytes; the file "
                      "has %zu)", where, frame, (long long) chunks,
                      (long long) (chunks * 8), size);
        goto done;
    }
    size_t table_end = pos + (size_t) chunks * 8;
    if (min_bytes > (int64_t) (size - table_end)) {
        rc = fp_error("%s: frame %ld: corrupt or truncated EXR (its header claims "
                      "%lld bytes of pixels, which need at least %lld bytes of %s "
                      "data; the file has %zu after its offset tables)", where,
                      frame, (long long) decoded, (long long) min_bytes,
                      nparts == 1 ? fp_exr_compression_name(parts[0].compression)
                                  : "compressed",
                      size - table_end);
        goto done;
    }

    /* Each chunk of the highest resolution against the bytes of its
     * lines.  A chunk that is not where its table says, or is not the one
     * the table names, is the library's to report. */
    size_t table = pos;
    for (int p = 0; p < nparts; ++p) {
        const fp_exr_hpart_t *sp = &parts[p];
        int64_t level0 = 0;
        fp_exr_count_chunks(sp, &level0);
        if (level0 > sp->chunk_count)
            level0 = sp->chunk_count;
        int64_t x0 = sp->dw[0], y0 = sp->dw[1];
        int64_t x1 = (int64_t) sp->dw[2] + 1, y1 = (int64_t) sp->dw[3] + 1;
        int64_t lpc = sp->tiled ? (int64_t) sp->ty : (int64_t) fp_exr_lines_per_chunk(sp->compression);
        int64_t ntx = sp->tiled ? (x1 - x0 + (int64_t) sp->tx - 1) / (int64_t) sp->tx : 1;
        int64_t r = max_ratio(sp->compression);
        for (int64_t i = 0; i < level0; ++i) {
            uint64_t off = fp_exr_rd_u64(b + table + (size_t) i * 8);
            size_t lead = (multipart ? 4 : 0) + (sp->tiled ? 16 : 4);
            if (off < table_end || off >= size || size - off < lead + 4)
                continue;
            const uint8_t *c = b + off;
            if (multipart && fp_exr_rd_i32(c) != p)
                continue;
            c += multipart ? 4 : 0;
            int64_t cx0 = x0, cx1 = x1, cy0, cy1;
            if (sp->tiled) {
                int64_t tx = i % ntx, ty = i / ntx;
                if (fp_exr_rd_i32(c) != tx || fp_exr_rd_i32(c + 4) != ty || fp_exr_rd_i32(c + 8) != 0 ||
                    fp_exr_rd_i32(c + 12) != 0)
                    continue;
                cx0 = x0 + tx * sp->tx;
                cx1 = cx0 + sp->tx < x1 ? cx0 + sp->tx : x1;
                cy0 = y0 + ty * sp->ty;
            } else {
                cy0 = y0 + i * lpc;
                if (fp_exr_rd_i32(c) != cy0)
                    continue;
            }
            cy1 = cy0 + lpc < y1 ? cy0 + lpc : y1;
            int32_t packed = fp_exr_rd_i32(c + lead - (multipart ? 4 : 0));
            if (packed < 0)
                continue;
            chan_sum_t cs;
            int64_t need = 0;
            walk_channels(sp, &cs, cx0, cx1, cy0, cy1, &need);
            int none = sp->compression == EXR_COMPRESSION_NONE;
            int64_t least = none ? need : (need + r - 1) / r;
            if (none ? packed != need : packed < least) {
                char at[96];
                if (sp->tiled)
                    snprintf(at, sizeof at, "tile %lld,%lld", (long long) (i % ntx),
                             (long long) (i / ntx));
                else
                    snprintf(at, sizeof at, "lines %lld-%lld", (long long) cy0,
                             (long long) cy1 - 1);
                rc = fp_error("%s: frame %ld: part %d: chunk %lld (%s) holds %d bytes; "
                              "its %lld bytes of pixels need %s%lld %s (corrupt EXR)",
                              where, frame, p, (long long) i, at, (int) packed,
                              (long long) need, none ? "" : "at least ", (long long) least,
                              none ? "uncompressed" : fp_exr_compression_name(sp->compression));
                goto done;
            }
        }
        table += (size_t) sp->chunk_count * 8;
    }
    rc = check_overlaps(b, size, table_end, multipart, parts, nparts, pos, chunks, where, frame);
    goto done;
unframed:
    rc = FP_OK;
done:
    free(parts);
    return rc;
}
