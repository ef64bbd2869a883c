/* fogpipe: EXR frames in and out through OpenEXR's C API (openexr.h).
 *
 * Read: the whole file is in memory; the library reads it through
 * mem_read (the in-memory stream pattern of ImfCheckFile.cpp).  Every
 * channel of every part is decoded raw, in its own type, into a plane
 * over its (sub-sampled) data window: colour and depth are converted to
 * float from there, and every other channel is kept as bytes so that
 * writing can pass it through untouched.  The read context stays open
 * with the frame (its header is the source of every attribute we write);
 * the file's bytes are released once decoded.
 *
 * Write: a new context whose write callback (mem_write) fills a growable
 * buffer, so one encoder serves files and stdout alike.
 *
 * Stream framing (fp_exr_stream_next) does not use the library: a pipe
 * cannot seek and holds several files back to back, so we walk the bytes
 * (header, offset tables, last chunk) ourselves to know where one ends. */
#include "exrio.h"
#include "fp.h"

#include <openexr.h>

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* Sanity limits against corrupt headers: a frame larger than these is far
 * beyond what a compositor filter holds in memory, and refusing early
 * turns a bad header into a message instead of a huge allocation. */
#define FP_EXR_MAX_DIM        (1 << 20)            /* pixels along one axis */
#define FP_EXR_MAX_PIXELS     ((int64_t) 1 << 30)  /* pixels in one part */
#define FP_EXR_MAX_PARTS      4096
#define FP_EXR_MAX_ATTR_SIZE  ((int64_t) 1 << 28)  /* one attribute value */
#define FP_EXR_MAX_ATTRS      100000               /* attributes in one header */
#define FP_EXR_MAX_CHUNKS     ((int64_t) 1 << 26)  /* offset table entries */
#define FP_EXR_MAX_FILE       ((uint64_t) 1 << 40) /* bytes in one frame */

#define FP_EXR_MAGIC 20000630
#define FP_EXR_MSG_LEN 512

/* What a channel is to the encoder: passed through, or colour R..A. */
enum { ROLE_PASS = 0, ROLE_R, ROLE_G, ROLE_B, ROLE_A };

/* One channel of a part, as read. */
typedef struct fp_chan_t {
    const char *name;    /* owned by the read context */
    int type;            /* exr_pixel_type_t */
    int p_linear;
    int xs, ys;          /* sub-sampling */
    int w, h;            /* samples per line, lines */
    size_t bpe;          /* bytes per sample */
    uint8_t *raw;        /* w*h samples, host byte order; NULL once consumed */
} fp_chan_t;

typedef struct fp_part_t {
    int storage;         /* exr_storage_t of the input */
    exr_attr_box2i_t dw, disp;
    int compression;
    int lineorder;
    int num_chans;
    fp_chan_t *chans;    /* in the order of the part's (sorted) channel list */
} fp_part_t;

/* The library's data for a context: the memory image read from, the
 * buffer written to, and the text of the library's last complaint. */
typedef struct fp_exr_io_t {
    const uint8_t *rd;
    size_t rd_size;
    uint8_t *wr;
    size_t wr_size, wr_cap;
    int wr_failed;
    char msg[FP_EXR_MSG_LEN];
} fp_exr_io_t;

struct fp_frame_t {
    void *buf;           /* the file's bytes, read through io */
    size_t size;
    fp_exr_io_t io;
    exr_context_t ctx;
    int num_parts;
    fp_part_t *parts;
    int main_part;       /* colour's part, else depth's, else 0 */
    int color_part, color_chan[4];
    int depth_part, depth_chan;
    float *rgba;
    float *depth;
    fp_frame_info_t info;
};

/* ------------------------------------------------------------ library glue */

/* The error callback cannot ask the context for its user data:
 * exr_get_user_data takes the context's lock, which a write context holds
 * while it reports, and deadlocks.  The library calls the handler on the
 * thread that made the failing call, so a thread-local pointer to the
 * message buffer of the call in progress is both safe and reentrant. */
static _Thread_local char *tl_msg;

static void lib_error_handler(exr_const_context_t ctxt, exr_result_t code,
                              const char *msg)
{
    (void) ctxt;
    char *dst = tl_msg;
    if (!dst || dst[0])
        return; /* keep the first message: later ones follow from it */
    snprintf(dst, FP_EXR_MSG_LEN, "%s",
             msg ? msg : exr_get_default_error_message(code));
    for (char *p = dst; *p; ++p)
        if (*p == '\n' || *p == '\r')
            *p = ' ';
}

/* The library's text for a failure: what its handler said, else the
 * generic text of the code.  Clears the buffer for the next call. */
static const char *lib_text(fp_exr_io_t *io, exr_result_t rv, char *out,
                            size_t n)
{
    if (io->msg[0])
        snprintf(out, n, "%s", io->msg);
    else
        snprintf(out, n, "%s: %s", exr_get_error_code_as_string(rv),
                 exr_get_default_error_message(rv));
    io->msg[0] = '\0';
    return out;
}

static int64_t mem_read(exr_const_context_t ctxt, void *userdata, void *buffer,
                        uint64_t sz, uint64_t offset,
                        exr_stream_error_func_ptr_t error_cb)
{
    fp_exr_io_t *io = userdata;
    if (offset > io->rd_size) {
        if (error_cb)
            error_cb(ctxt, EXR_ERR_READ_IO,
                     "read past the end of the data (offset %llu, %llu bytes held)",
                     (unsigned long long) offset,
                     (unsigned long long) io->rd_size);
        return -1;
    }
    uint64_t n = io->rd_size - offset;
    if (n > sz)
        n = sz;
    memcpy(buffer, io->rd + offset, (size_t) n);
    /* A short count is how a truncated file shows: the library reports it. */
    return (int64_t) n;
}

static int64_t mem_size(exr_const_context_t ctxt, void *userdata)
{
    (void) ctxt;
    return (int64_t) ((fp_exr_io_t *) userdata)->rd_size;
}

/* pwrite semantics: the library writes the offset table last, at an
 * offset before the chunks, so writes land anywhere in the buffer. */
static int64_t mem_write(exr_const_context_t ctxt, void *userdata,
                         const void *buffer, uint64_t sz, uint64_t offset,
                         exr_stream_error_func_ptr_t error_cb)
{
    fp_exr_io_t *io = userdata;
    if (offset > FP_EXR_MAX_FILE || sz > FP_EXR_MAX_FILE) {
        io->wr_failed = 1;
        if (error_cb)
            error_cb(ctxt, EXR_ERR_WRITE_IO, "output too large");
        return -1;
    }
    size_t end = (size_t) (offset + sz);
    if (end > io->wr_cap) {
        size_t cap = io->wr_cap ? io->wr_cap : 65536;
        while (cap < end)
            cap *= 2;
        uint8_t *nb = realloc(io->wr, cap);
        if (!nb) {
            io->wr_failed = 1;
            if (error_cb)
                error_cb(ctxt, EXR_ERR_OUT_OF_MEMORY, "out of memory");
            return -1;
        }
        io->wr = nb;
        io->wr_cap = cap;
    }
    if (offset > io->wr_size)
        memset(io->wr + io->wr_size, 0, (size_t) offset - io->wr_size);
    memcpy(io->wr + offset, buffer, (size_t) sz);
    if (end > io->wr_size)
        io->wr_size = end;
    return (int64_t) sz;
}

/* ------------------------------------------------------------ small helpers */

static int64_t floordiv(int64_t a, int64_t b)
{
    int64_t q = a / b;
    if ((a % b) != 0 && ((a < 0) != (b < 0)))
        q--;
    return q;
}

/* How many v in [lo, hi) have v mod s == 0: the samples a sub-sampled
 * channel holds over that range (OpenEXR samples at multiples of s). */
static int64_t sampled_count(int64_t lo, int64_t hi, int s)
{
    if (hi <= lo)
        return 0;
    return floordiv(hi - 1, s) - floordiv(lo - 1, s);
}

static size_t type_size(int type)
{
    return type == EXR_PIXEL_HALF ? 2 : 4;
}

static float half_to_float(uint16_t h)
{
    uint32_t sign = (uint32_t) (h & 0x8000) << 16;
    uint32_t exp = (h >> 10) & 0x1f;
    uint32_t man = h & 0x3ff;
    uint32_t bits;
    if (exp == 0) {
        if (man == 0) {
            bits = sign;
        } else {
            /* subnormal half: normalise into a float */
            exp = 127 - 15 + 1;
            while (!(man & 0x400)) {
                man <<= 1;
                exp--;
            }
            man &= 0x3ff;
            bits = sign | (exp << 23) | (man << 13);
        }
    } else if (exp == 31) {
        bits = sign | 0x7f800000u | (man << 13);
    } else {
        bits = sign | ((exp + 127 - 15) << 23) | (man << 13);
    }
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static float sample_as_float(const fp_chan_t *ch, size_t i)
{
    switch (ch->type) {
    case EXR_PIXEL_HALF: {
        uint16_t h;
        memcpy(&h, ch->raw + i * 2, 2);
        return half_to_float(h);
    }
    case EXR_PIXEL_UINT: {
        uint32_t u;
        memcpy(&u, ch->raw + i * 4, 4);
        return (float) u;
    }
    default: {
        float v;
        memcpy(&v, ch->raw + i * 4, 4);
        return v;
    }
    }
}

static const char *const comp_names[] = {
    "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"
};

int fp_exr_compression_from_name(const char *name)
{
    if (!name)
        return -1;
    for (size_t i = 0; i < FP_ARRAY_LEN(comp_names); ++i)
        if (strcasecmp(name, comp_names[i]) == 0)
            return (int) i;
    return -1;
}

const char *fp_exr_compression_name(int compression)
{
    if (compression < 0 || (size_t) compression >= FP_ARRAY_LEN(comp_names))
        return "unknown";
    return comp_names[compression];
}

/* ------------------------------------------------------------ whole files */

/* Read a file into a malloc'd buffer without printing; *err is the errno. */
static int slurp(const char *path, void **buf, size_t *size, int *err)
{
    int rc = FP_ERR;
    int fd = -1;
    uint8_t *b = NULL;
    size_t len = 0, cap = 0;
    struct stat st;

    *buf = NULL;
    *size = 0;
    *err = 0;
    fd = open(path, O_RDONLY);
    if (fd < 0) {
        *err = errno;
        goto done;
    }
    if (fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
        *err = EISDIR;
        goto done;
    }
    /* A regular file's size is a good first guess; pipes grow the buffer. */
    cap = (fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0)
              ? (size_t) st.st_size + 1
              : 65536;
    b = malloc(cap);
    if (!b) {
        *err = ENOMEM;
        goto done;
    }
    for (;;) {
        if (len == cap) {
            uint8_t *nb = realloc(b, cap * 2);
            if (!nb) {
                *err = ENOMEM;
                goto done;
            }
            b = nb;
            cap *= 2;
        }
        ssize_t n = read(fd, b + len, cap - len);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            *err = errno;
            goto done;
        }
        if (n == 0)
            break;
        len += (size_t) n;
    }
    *buf = b;
    *size = len;
    b = NULL;
    rc = FP_OK;
done:
    if (fd >= 0)
        close(fd);
    free(b);
    return rc;
}

int fp_read_whole_file(const char *path, void **buf, size_t *size)
{
    int err;
    if (slurp(path, buf, size, &err) != FP_OK)
        return fp_error("%s: cannot read (%s)", path, strerror(err));
    return FP_OK;
}

/* Temporary in the same directory, so rename() is atomic. */
static int write_atomic(const char *path, const void *buf, size_t size,
                        const char *label)
{
    int rc = FP_ERR;
    int fd = -1;
    char *tmp = NULL;
    const char *slash = strrchr(path, '/');
    size_t dirlen = slash ? (size_t) (slash - path) + 1 : 0;
    const char *base = slash ? slash + 1 : path;
    size_t n = dirlen + strlen(base) + 64;
    const char *what = "cannot write";
    int err = 0;

    if (!*base) {
        err = EISDIR;
        goto fail;
    }
    tmp = malloc(n);
    if (!tmp) {
        err = ENOMEM;
        goto fail;
    }
    snprintf(tmp, n, "%.*s.%s.tmp.%ld", (int) dirlen, path, base,
             (long) getpid());
    fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    if (fd < 0) {
        err = errno;
        free(tmp);
        tmp = NULL; /* nothing was created */
        goto fail;
    }
    const uint8_t *p = buf;
    size_t left = size;
    while (left > 0) {
        ssize_t w = write(fd, p, left);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            err = errno;
            goto fail;
        }
        p += w;
        left -= (size_t) w;
    }
    if (close(fd) != 0) {
        fd = -1;
        err = errno;
        goto fail;
    }
    fd = -1;
    if (rename(tmp, path) != 0) {
        err = errno;
        what = "cannot rename the temporary into place";
        goto fail;
    }
    free(tmp);
    tmp = NULL;
    rc = FP_OK;
    goto done;
fail:
    fp_error("%s%s: %s (%s)", path, label, what, strerror(err));
done:
    if (fd >= 0)
        close(fd);
    if (tmp) {
        unlink(tmp);
        free(tmp);
    }
    return rc;
}

int fp_write_file_atomic(const char *path, const void *buf, size_t size)
{
    return write_atomic(path, buf, size, "");
}

/* ------------------------------------------------------------ reading */

/* Find a channel by exact name, in part `prefer` first, then in the
 * others in file order. */
static int find_channel(const fp_frame_t *f, const char *name, int prefer,
                        int *part, int *chan)
{
    for (int k = -1; k < f->num_parts; ++k) {
        int p = k < 0 ? prefer : k;
        if (p < 0 || (k >= 0 && p == prefer))
            continue;
        const fp_part_t *pt = &f->parts[p];
        for (int c = 0; c < pt->num_chans; ++c)
            if (strcmp(pt->chans[c].name, name) == 0) {
                *part = p;
                *chan = c;
                return 1;
            }
    }
    return 0;
}

static int find_in_part(const fp_part_t *pt, const char *name)
{
    for (int c = 0; c < pt->num_chans; ++c)
        if (strcmp(pt->chans[c].name, name) == 0)
            return c;
    return -1;
}

/* Colour is prefix+R, G, B (and optional A) in one part. */
static int try_color(fp_frame_t *f, const char *prefix, int only_part)
{
    static const char *const comp[4] = { "R", "G", "B", "A" };
    char names[4][300];
    for (int i = 0; i < 4; ++i)
        snprintf(names[i], sizeof names[i], "%s%s", prefix, comp[i]);
    for (int p = 0; p < f->num_parts; ++p) {
        if (only_part >= 0 && p != only_part)
            continue;
        int idx[4];
        for (int i = 0; i < 4; ++i)
            idx[i] = find_in_part(&f->parts[p], names[i]);
        if (idx[0] < 0 || idx[1] < 0 || idx[2] < 0)
            continue;
        f->color_part = p;
        for (int i = 0; i < 4; ++i)
            f->color_chan[i] = idx[i];
        return 1;
    }
    return 0;
}

/* Locate colour and depth by name (see fp_exr_select_t).  `layer` gets
 * the view layer of the colour, whose depth is preferred. */
static int select_channels(fp_frame_t *f, const fp_exr_select_t *sel,
                           const char *where, long frame)
{
    char layer[300] = "";
    char prefix[300];
    const char *cl = sel && sel->color_layer ? sel->color_layer : "";
    const char *dc = sel && sel->depth_channel ? sel->depth_channel : "";
    int need_color = sel ? sel->need_color : 1;
    int need_depth = sel ? sel->need_depth : 1;

    f->color_part = f->depth_part = -1;
    f->color_chan[0] = f->color_chan[1] = f->color_chan[2] = -1;
    f->color_chan[3] = f->depth_chan = -1;

    if (*cl) {
        snprintf(prefix, sizeof prefix, "%s.", cl);
        if (try_color(f, prefix, -1)) {
            snprintf(layer, sizeof layer, "%s", cl);
        } else {
            /* "--color-layer ViewLayer" means ViewLayer.Combined.* too */
            snprintf(prefix, sizeof prefix, "%s.Combined.", cl);
            if (try_color(f, prefix, -1))
                snprintf(layer, sizeof layer, "%s", cl);
        }
        if (f->color_part < 0 && need_color)
            return fp_error("%s: frame %ld: no color channels %s.R, %s.G, %s.B "
                            "(from --color-layer)", where, frame, cl, cl, cl);
    } else if (!try_color(f, "", -1)) {
        /* Blender multilayer: <layer>.Combined.R, the first such layer */
        static const char suffix[] = ".Combined.R";
        size_t sl = sizeof suffix - 1;
        for (int p = 0; p < f->num_parts && f->color_part < 0; ++p) {
            const fp_part_t *pt = &f->parts[p];
            for (int c = 0; c < pt->num_chans && f->color_part < 0; ++c) {
                const char *n = pt->chans[c].name;
                size_t len = strlen(n);
                if (len <= sl || len - sl >= sizeof layer ||
                    strcmp(n + len - sl, suffix) != 0)
                    continue;
                snprintf(prefix, sizeof prefix, "%.*s.Combined.",
                         (int) (len - sl), n);
                if (try_color(f, prefix, p))
                    snprintf(layer, sizeof layer, "%.*s", (int) (len - sl), n);
            }
        }
        if (f->color_part < 0 && need_color)
            return fp_error("%s: frame %ld: no color channels (looked for R,G,B "
                            "and *.Combined.R,G,B; use --color-layer)",
                            where, frame);
    }
    if (f->color_part >= 0) {
        /* "<layer>.Combined" given as the layer: its view layer is <layer> */
        size_t ll = strlen(layer);
        if (ll > 9 && strcmp(layer + ll - 9, ".Combined") == 0)
            layer[ll - 9] = '\0';
    }

    if (*dc) {
        if (!find_channel(f, dc, f->color_part, &f->depth_part, &f->depth_chan)
            && need_depth)
            return fp_error("%s: frame %ld: no depth channel '%s' "
                            "(from --depth-channel)", where, frame, dc);
    } else {
        char cand[4][320];
        int nc = 0;
        if (layer[0]) {
            snprintf(cand[nc++], sizeof cand[0], "%s.Depth.Z", layer);
            snprintf(cand[nc++], sizeof cand[0], "%s.Z", layer);
        }
        snprintf(cand[nc++], sizeof cand[0], "Z");
        snprintf(cand[nc++], sizeof cand[0], "depth.Z");
        for (int i = 0; i < nc && f->depth_part < 0; ++i)
            find_channel(f, cand[i], f->color_part, &f->depth_part,
                         &f->depth_chan);
        /* any view layer's depth, the colour's part first */
        static const char suffix[] = ".Depth.Z";
        size_t sl = sizeof suffix - 1;
        for (int k = -1; k < f->num_parts && f->depth_part < 0; ++k) {
            int p = k < 0 ? f->color_part : k;
            if (p < 0 || (k >= 0 && p == f->color_part))
                continue;
            const fp_part_t *pt = &f->parts[p];
            for (int c = 0; c < pt->num_chans; ++c) {
                const char *n = pt->chans[c].name;
                size_t len = strlen(n);
                if (len > sl && strcmp(n + len - sl, suffix) == 0) {
                    f->depth_part = p;
                    f->depth_chan = c;
                    break;
                }
            }
        }
        if (f->depth_part < 0 && need_depth)
            return fp_error("%s: frame %ld: no depth channel (looked for Z, "
                            "depth.Z, *.Depth.Z; use --depth-channel)",
                            where, frame);
    }

    /* Colour and depth must be full resolution and cover the same pixels.
     * What is not needed (depth from a --depth sequence, say) is dropped
     * instead: it still passes through as an ordinary channel. */
    for (int i = 0; i < 5; ++i) {
        int p = i < 4 ? f->color_part : f->depth_part;
        int c = i < 4 ? f->color_chan[i] : f->depth_chan;
        if (p < 0 || c < 0)
            continue;
        const fp_chan_t *ch = &f->parts[p].chans[c];
        if (ch->xs == 1 && ch->ys == 1)
            continue;
        if (i < 4 ? need_color : need_depth)
            return fp_error("%s: frame %ld: channel %s is sub-sampled (%dx%d); "
                            "color and depth must be full resolution",
                            where, frame, ch->name, ch->xs, ch->ys);
        if (i < 4)
            f->color_part = -1;
        else
            f->depth_part = -1;
    }
    if (f->color_part >= 0 && f->depth_part >= 0 &&
        f->color_part != f->depth_part) {
        const exr_attr_box2i_t *a = &f->parts[f->color_part].dw;
        const exr_attr_box2i_t *b = &f->parts[f->depth_part].dw;
        if (memcmp(a, b, sizeof *a) != 0) {
            if (need_depth)
                return fp_error("%s: frame %ld: color (part %d, %dx%d at %d,%d) "
                                "and depth (part %d, %dx%d at %d,%d) have "
                                "different data windows", where, frame,
                                f->color_part, a->max.x - a->min.x + 1,
                                a->max.y - a->min.y + 1, a->min.x, a->min.y,
                                f->depth_part, b->max.x - b->min.x + 1,
                                b->max.y - b->min.y + 1, b->min.x, b->min.y);
            f->depth_part = -1;
        }
    }
    if (f->color_part < 0)
        f->color_chan[0] = f->color_chan[1] = f->color_chan[2] = f->color_chan[3] = -1;
    if (f->depth_part < 0)
        f->depth_chan = -1;
    return FP_OK;
}

/* Describe a part's channels and allocate their planes. */
static int setup_part(fp_frame_t *f, int p, const char *where, long frame)
{
    char lt[512];
    fp_part_t *pt = &f->parts[p];
    exr_storage_t st;
    exr_compression_t comp;
    exr_lineorder_t lo;
    const exr_attr_chlist_t *cl = NULL;
    exr_result_t rv;

    if ((rv = exr_get_storage(f->ctx, p, &st)) != EXR_ERR_SUCCESS ||
        (rv = exr_get_data_window(f->ctx, p, &pt->dw)) != EXR_ERR_SUCCESS ||
        (rv = exr_get_display_window(f->ctx, p, &pt->disp)) != EXR_ERR_SUCCESS ||
        (rv = exr_get_compression(f->ctx, p, &comp)) != EXR_ERR_SUCCESS ||
        (rv = exr_get_lineorder(f->ctx, p, &lo)) != EXR_ERR_SUCCESS ||
        (rv = exr_get_channels(f->ctx, p, &cl)) != EXR_ERR_SUCCESS)
        return fp_error("%s: frame %ld: part %d: bad header (%s)", where, frame,
                        p, lib_text(&f->io, rv, lt, sizeof lt));
    if (st == EXR_STORAGE_DEEP_SCANLINE || st == EXR_STORAGE_DEEP_TILED)
        return fp_error("%s: frame %ld: part %d holds deep data, which is not "
                        "supported (expected flat scanline or tiled images)",
                        where, frame, p);
    pt->storage = st;
    pt->compression = comp;
    pt->lineorder = lo;

    int64_t w = (int64_t) pt->dw.max.x - pt->dw.min.x + 1;
    int64_t h = (int64_t) pt->dw.max.y - pt->dw.min.y + 1;
    if (w < 1 || h < 1 || w > FP_EXR_MAX_DIM || h > FP_EXR_MAX_DIM ||
        w * h > FP_EXR_MAX_PIXELS)
        return fp_error("%s: frame %ld: part %d: unreasonable data window "
                        "%lldx%lld", where, frame, p, (long long) w,
                        (long long) h);

    pt->num_chans = cl->num_channels;
    pt->chans = calloc(cl->num_channels > 0 ? (size_t) cl->num_channels : 1,
                       sizeof *pt->chans);
    if (!pt->chans)
        return fp_error("%s: frame %ld: out of memory", where, frame);
    for (int c = 0; c < cl->num_channels; ++c) {
        const exr_attr_chlist_entry_t *e = &cl->entries[c];
        fp_chan_t *ch = &pt->chans[c];
        ch->name = e->name.str;
        ch->type = e->pixel_type;
        ch->p_linear = e->p_linear;
        ch->xs = e->x_sampling;
        ch->ys = e->y_sampling;
        if (ch->type < EXR_PIXEL_UINT || ch->type > EXR_PIXEL_FLOAT ||
            ch->xs < 1 || ch->ys < 1)
            return fp_error("%s: frame %ld: channel %s: bad type or sampling",
                            where, frame, ch->name);
        if ((ch->xs != 1 || ch->ys != 1) && st != EXR_STORAGE_SCANLINE)
            return fp_error("%s: frame %ld: channel %s: sub-sampled channels "
                            "in tiled parts are not supported", where, frame,
                            ch->name);
        ch->bpe = type_size(ch->type);
        ch->w = (int) sampled_count(pt->dw.min.x, (int64_t) pt->dw.max.x + 1,
                                    ch->xs);
        ch->h = (int) sampled_count(pt->dw.min.y, (int64_t) pt->dw.max.y + 1,
                                    ch->ys);
        size_t bytes = (size_t) ch->w * (size_t) ch->h * ch->bpe;
        ch->raw = calloc(bytes ? bytes : 1, 1);
        if (!ch->raw)
            return fp_error("%s: frame %ld: out of memory (%zu bytes for "
                            "channel %s)", where, frame, bytes, ch->name);
    }
    return FP_OK;
}

/* Decode one chunk whose first pixel is (x0, y0), absolute coordinates. */
static exr_result_t decode_chunk(fp_frame_t *f, int p, exr_decode_pipeline_t *dec,
                                 int *inited, const exr_chunk_info_t *ci,
                                 int x0, int y0)
{
    fp_part_t *pt = &f->parts[p];
    exr_result_t rv = *inited ? exr_decoding_update(f->ctx, p, ci, dec)
                              : exr_decoding_initialize(f->ctx, p, ci, dec);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    for (int c = 0; c < dec->channel_count; ++c) {
        exr_coding_channel_info_t *cc = &dec->channels[c];
        int k = c < pt->num_chans && strcmp(pt->chans[c].name, cc->channel_name) == 0
                    ? c
                    : find_in_part(pt, cc->channel_name);
        if (k < 0) {
            cc->decode_to_ptr = NULL;
            continue;
        }
        fp_chan_t *ch = &pt->chans[k];
        int64_t row = sampled_count(pt->dw.min.y, y0, ch->ys);
        int64_t col = sampled_count(pt->dw.min.x, x0, ch->xs);
        cc->decode_to_ptr = ch->raw + ((size_t) row * (size_t) ch->w + (size_t) col) * ch->bpe;
        cc->user_pixel_stride = (int32_t) ch->bpe;
        cc->user_line_stride = (int32_t) ((size_t) ch->w * ch->bpe);
        cc->user_bytes_per_element = (int16_t) ch->bpe;
        cc->user_data_type = (uint16_t) ch->type;
    }
    if (!*inited) {
        rv = exr_decoding_choose_default_routines(f->ctx, p, dec);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
        *inited = 1;
    }
    return exr_decoding_run(f->ctx, p, dec);
}

static int decode_part(fp_frame_t *f, int p, const char *where, long frame)
{
    char lt[512];
    fp_part_t *pt = &f->parts[p];
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    exr_chunk_info_t ci;
    int inited = 0;
    int rc = FP_ERR;
    exr_result_t rv = EXR_ERR_SUCCESS;
    int at_x = pt->dw.min.x, at_y = pt->dw.min.y;

    if (pt->num_chans == 0)
        return FP_OK;
    if (pt->storage == EXR_STORAGE_SCANLINE) {
        int32_t lpc = 0;
        rv = exr_get_scanlines_per_chunk(f->ctx, p, &lpc);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
        for (int64_t y = pt->dw.min.y; y <= pt->dw.max.y; y += lpc) {
            at_y = (int) y;
            rv = exr_read_scanline_chunk_info(f->ctx, p, (int) y, &ci);
            if (rv == EXR_ERR_SUCCESS)
                rv = decode_chunk(f, p, &dec, &inited, &ci, pt->dw.min.x, (int) y);
            if (rv != EXR_ERR_SUCCESS)
                goto fail;
        }
    } else {
        /* tiled: the highest resolution level (0,0) only */
        int32_t tw = 0, th = 0;
        rv = exr_get_tile_sizes(f->ctx, p, 0, 0, &tw, &th);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
        int64_t w = (int64_t) pt->dw.max.x - pt->dw.min.x + 1;
        int64_t h = (int64_t) pt->dw.max.y - pt->dw.min.y + 1;
        int64_t ntx = (w + tw - 1) / tw, nty = (h + th - 1) / th;
        for (int64_t ty = 0; ty < nty; ++ty)
            for (int64_t tx = 0; tx < ntx; ++tx) {
                at_x = (int) (pt->dw.min.x + tx * tw);
                at_y = (int) (pt->dw.min.y + ty * th);
                rv = exr_read_tile_chunk_info(f->ctx, p, (int) tx, (int) ty, 0, 0, &ci);
                if (rv == EXR_ERR_SUCCESS)
                    rv = decode_chunk(f, p, &dec, &inited, &ci, at_x, at_y);
                if (rv != EXR_ERR_SUCCESS)
                    goto fail;
            }
    }
    rc = FP_OK;
    goto done;
fail:
    fp_error("%s: frame %ld: part %d: cannot decode pixels at %d,%d (%s%s)",
             where, frame, p, at_x, at_y, lib_text(&f->io, rv, lt, sizeof lt),
             rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED
                 ? "; this OpenEXR C library cannot read it: re-encode the input"
                 : "");
done:
    exr_decoding_destroy(f->ctx, &dec);
    return rc;
}

static void read_matrix(fp_frame_t *f, const char *name, int *has, double m[16])
{
    for (int k = -1; k < f->num_parts && !*has; ++k) {
        int p = k < 0 ? f->main_part : k;
        if (k >= 0 && p == f->main_part)
            continue;
        const exr_attribute_t *a = NULL;
        if (exr_get_attribute_by_name(f->ctx, p, name, &a) != EXR_ERR_SUCCESS || !a)
            continue;
        if (a->type == EXR_ATTR_M44F) {
            for (int i = 0; i < 16; ++i)
                m[i] = a->m44f->m[i];
            *has = 1;
        } else if (a->type == EXR_ATTR_M44D) {
            for (int i = 0; i < 16; ++i)
                m[i] = a->m44d->m[i];
            *has = 1;
        }
    }
    f->io.msg[0] = '\0'; /* a missing attribute is not an error */
}

/* String attributes that describe the camera without OpenEXR's matrices:
 * "fogpipe-camera ..." text (Blender's stamp Note written by
 * samples/blender/fogpipe_camera.py) and Blender's stamp "Lens". */
static void read_camera_text(fp_frame_t *f, fp_frame_info_t *in)
{
    for (int p = 0; p < f->num_parts; ++p) {
        int32_t n = 0;
        if (exr_get_attribute_count(f->ctx, p, &n) != EXR_ERR_SUCCESS)
            continue;
        for (int32_t i = 0; i < n; ++i) {
            const exr_attribute_t *a = NULL;
            if (exr_get_attribute_by_index(f->ctx, p, EXR_ATTR_LIST_FILE_ORDER, i, &a) !=
                    EXR_ERR_SUCCESS || !a || a->type != EXR_ATTR_STRING || !a->string ||
                !a->string->str)
                continue;
            int len = a->string->length;
            char v[sizeof in->camera_text];
            if (len <= 0 || len >= (int) sizeof v)
                continue;
            memcpy(v, a->string->str, (size_t) len);
            v[len] = '\0';
            if (!in->camera_text[0] && strstr(v, "fogpipe-camera")) {
                memcpy(in->camera_text, v, (size_t) len + 1);
                snprintf(in->camera_text_attr, sizeof in->camera_text_attr, "%s", a->name);
            } else if (in->lens_mm == 0 && strcmp(a->name, "Lens") == 0) {
                double mm = strtod(v, NULL);
                if (mm > 0 && mm < 1e6)
                    in->lens_mm = mm;
            }
        }
    }
    f->io.msg[0] = '\0';
}

int fp_exr_read_memory(const void *buf, size_t size, const char *where_file,
                       long frame, const fp_exr_select_t *sel,
                       fp_frame_t **out)
{
    char lt[512];
    char *saved_msg = tl_msg;
    int rc = FP_ERR;
    exr_result_t rv;
    fp_frame_t *f = calloc(1, sizeof *f);
    const char *where = where_file ? where_file : "<input>";

    *out = NULL;
    if (!f) {
        free((void *) buf);
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    f->buf = (void *) buf;
    f->size = size;
    f->io.rd = buf;
    f->io.rd_size = size;
    tl_msg = f->io.msg;

    const uint8_t *b = buf;
    if (size < 8 || ((uint32_t) b[0] | (uint32_t) b[1] << 8 | (uint32_t) b[2] << 16 |
                     (uint32_t) b[3] << 24) != FP_EXR_MAGIC) {
        fp_error("%s: frame %ld: not an EXR file (bad magic number)", where, frame);
        goto done;
    }

    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = lib_error_handler;
    init.user_data = &f->io;
    init.read_fn = mem_read;
    init.size_fn = mem_size;
    init.max_image_width = FP_EXR_MAX_DIM;
    init.max_image_height = FP_EXR_MAX_DIM;
    init.max_tile_width = FP_EXR_MAX_DIM;
    init.max_tile_height = FP_EXR_MAX_DIM;
    /* A missing chunk must fail loudly, not be searched for. */
    init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    rv = exr_start_read(&f->ctx, where, &init);
    if (rv != EXR_ERR_SUCCESS) {
        f->ctx = NULL;
        fp_error("%s: frame %ld: cannot read EXR header (%s)", where, frame,
                 lib_text(&f->io, rv, lt, sizeof lt));
        goto done;
    }
    rv = exr_get_count(f->ctx, &f->num_parts);
    if (rv != EXR_ERR_SUCCESS || f->num_parts < 1) {
        fp_error("%s: frame %ld: cannot read EXR header (%s)", where, frame,
                 lib_text(&f->io, rv, lt, sizeof lt));
        goto done;
    }
    f->parts = calloc((size_t) f->num_parts, sizeof *f->parts);
    if (!f->parts) {
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    for (int p = 0; p < f->num_parts; ++p)
        if (setup_part(f, p, where, frame) != FP_OK)
            goto done;
    if (select_channels(f, sel, where, frame) != FP_OK)
        goto done;
    for (int p = 0; p < f->num_parts; ++p)
        if (decode_part(f, p, where, frame) != FP_OK)
            goto done;
    /* Every pixel is decoded and the context has parsed the header into
     * its own memory: the file's bytes are no longer needed, and frames
     * in flight in a pipeline should not hold two copies. */
    free(f->buf);
    f->buf = NULL;
    f->size = 0;
    f->io.rd = NULL;
    f->io.rd_size = 0;

    f->main_part = f->color_part >= 0 ? f->color_part
                   : f->depth_part >= 0 ? f->depth_part : 0;
    const fp_part_t *mp = &f->parts[f->main_part];
    size_t w = (size_t) (mp->dw.max.x - mp->dw.min.x + 1);
    size_t h = (size_t) (mp->dw.max.y - mp->dw.min.y + 1);

    if (f->color_part >= 0) {
        fp_part_t *pt = &f->parts[f->color_part];
        f->rgba = malloc(w * h * 4 * sizeof(float));
        if (!f->rgba) {
            fp_error("%s: frame %ld: out of memory", where, frame);
            goto done;
        }
        for (int k = 0; k < 4; ++k) {
            int c = f->color_chan[k];
            if (c < 0) {
                for (size_t i = 0; i < w * h; ++i)
                    f->rgba[i * 4 + 3] = 1.0f;
                continue;
            }
            for (size_t i = 0; i < w * h; ++i)
                f->rgba[i * 4 + (size_t) k] = sample_as_float(&pt->chans[c], i);
        }
        /* Colour is written from rgba, so its raw bytes are not needed;
         * a depth channel that is also a colour channel keeps its own. */
        for (int k = 0; k < 4; ++k) {
            int c = f->color_chan[k];
            if (c >= 0 && !(f->depth_part == f->color_part && f->depth_chan == c)) {
                free(pt->chans[c].raw);
                pt->chans[c].raw = NULL;
            }
        }
    }
    if (f->depth_part >= 0) {
        const fp_chan_t *ch = &f->parts[f->depth_part].chans[f->depth_chan];
        f->depth = malloc(w * h * sizeof(float));
        if (!f->depth) {
            fp_error("%s: frame %ld: out of memory", where, frame);
            goto done;
        }
        for (size_t i = 0; i < w * h; ++i)
            f->depth[i] = sample_as_float(ch, i);
    }

    fp_frame_info_t *in = &f->info;
    in->data_x0 = mp->dw.min.x;
    in->data_y0 = mp->dw.min.y;
    in->width = (int) w;
    in->height = (int) h;
    in->disp_x0 = mp->disp.min.x;
    in->disp_y0 = mp->disp.min.y;
    in->disp_w = mp->disp.max.x - mp->disp.min.x + 1;
    in->disp_h = mp->disp.max.y - mp->disp.min.y + 1;
    in->pixel_aspect = 1.0f;
    if (exr_get_pixel_aspect_ratio(f->ctx, f->main_part, &in->pixel_aspect) != EXR_ERR_SUCCESS)
        in->pixel_aspect = 1.0f;
    f->io.msg[0] = '\0';
    read_matrix(f, "worldToCamera", &in->has_world_to_camera, in->world_to_camera);
    read_matrix(f, "worldToNDC", &in->has_world_to_ndc, in->world_to_ndc);
    read_camera_text(f, in);
    exr_attr_chromaticities_t chr;
    if (exr_attr_get_chromaticities(f->ctx, f->main_part, "chromaticities", &chr) ==
        EXR_ERR_SUCCESS) {
        const float c[8] = { chr.red_x, chr.red_y, chr.green_x, chr.green_y,
                             chr.blue_x, chr.blue_y, chr.white_x, chr.white_y };
        memcpy(in->chromaticities, c, sizeof c);
        in->has_chromaticities = 1;
    }
    f->io.msg[0] = '\0'; /* a missing attribute is not an error */
    in->compression = mp->compression;
    in->num_parts = f->num_parts;
    if (f->color_part >= 0) {
        in->has_alpha = f->color_chan[3] >= 0;
        for (int k = 0; k < 4; ++k)
            if (f->color_chan[k] >= 0)
                snprintf(in->color_names[k], sizeof in->color_names[k], "%s",
                         f->parts[f->color_part].chans[f->color_chan[k]].name);
    }
    if (f->depth_part >= 0)
        snprintf(in->depth_name, sizeof in->depth_name, "%s",
                 f->parts[f->depth_part].chans[f->depth_chan].name);
    rc = FP_OK;
done:
    tl_msg = saved_msg;
    if (rc == FP_OK) {
        *out = f;
    } else {
        fp_frame_free(f);
    }
    return rc;
}

int fp_exr_load_file(const char *path, long frame, void **buf, size_t *size)
{
    int err = 0;
    if (slurp(path, buf, size, &err) != FP_OK)
        return fp_error("%s: frame %ld: cannot read (%s)", path, frame,
                        strerror(err));
    return FP_OK;
}

int fp_exr_read_file(const char *path, long frame, const fp_exr_select_t *sel,
                     fp_frame_t **out)
{
    void *buf = NULL;
    size_t size = 0;
    *out = NULL;
    if (fp_exr_load_file(path, frame, &buf, &size) != FP_OK)
        return FP_ERR;
    return fp_exr_read_memory(buf, size, path, frame, sel, out);
}

const fp_frame_info_t *fp_frame_info(const fp_frame_t *f)
{
    return &f->info;
}

float *fp_frame_rgba(fp_frame_t *f)
{
    return f->rgba;
}

float *fp_frame_depth(fp_frame_t *f)
{
    return f->depth;
}

int fp_frame_take_depth(fp_frame_t *f, const char *f_name, fp_frame_t *depth,
                        const char *depth_name, long frame)
{
    const fp_frame_info_t *a = &f->info, *b = &depth->info;
    if (!depth->depth)
        return fp_error("%s: frame %ld: no depth channel (looked for Z, depth.Z, "
                        "*.Depth.Z; use --depth-channel)", depth_name, frame);
    if (a->data_x0 != b->data_x0 || a->data_y0 != b->data_y0 ||
        a->width != b->width || a->height != b->height)
        return fp_error("%s: frame %ld: data window %dx%d at %d,%d differs from "
                        "the depth file %s: %dx%d at %d,%d", f_name, frame,
                        a->width, a->height, a->data_x0, a->data_y0, depth_name,
                        b->width, b->height, b->data_x0, b->data_y0);
    free(f->depth);
    f->depth = depth->depth;
    depth->depth = NULL;
    snprintf(f->info.depth_name, sizeof f->info.depth_name, "%s",
             depth->info.depth_name);
    return FP_OK;
}

void fp_frame_free(fp_frame_t *f)
{
    if (!f)
        return;
    if (f->parts) {
        for (int p = 0; p < f->num_parts; ++p) {
            for (int c = 0; c < f->parts[p].num_chans; ++c)
                free(f->parts[p].chans[c].raw);
            free(f->parts[p].chans);
        }
        free(f->parts);
    }
    if (f->ctx) {
        char *saved = tl_msg;
        tl_msg = f->io.msg;
        exr_finish(&f->ctx);
        tl_msg = saved;
    }
    free(f->rgba);
    free(f->depth);
    free(f->buf);
    free(f);
}

/* ------------------------------------------------------------ writing */

/* One channel of an output part and where its samples come from. */
typedef struct out_chan_t {
    const char *name;
    int type;              /* in the file */
    int p_linear, xs, ys;
    const uint8_t *base;   /* first sample */
    int user_type;         /* in memory */
    int user_bpe;
    int pixel_stride;
    size_t line_stride;
} out_chan_t;

typedef struct out_part_t {
    int src;               /* input part */
    int num;
    out_chan_t *ch;
} out_part_t;

/* Attributes the library sets from our calls, or that describe the
 * input's layout (tiling, chunk count), not the image. */
static int is_structural_attr(const char *name)
{
    static const char *const names[] = {
        "channels", "compression", "dataWindow", "displayWindow", "lineOrder",
        "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth",
        "tiles", "type", "name", "version", "chunkCount"
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(names); ++i)
        if (strcmp(name, names[i]) == 0)
            return 1;
    return 0;
}

static exr_result_t copy_attr(exr_context_t o, int op, const exr_attribute_t *a)
{
    const char *n = a->name;
    switch (a->type) {
    case EXR_ATTR_BOX2I: return exr_attr_set_box2i(o, op, n, a->box2i);
    case EXR_ATTR_BOX2F: return exr_attr_set_box2f(o, op, n, a->box2f);
    case EXR_ATTR_CHLIST: return exr_attr_set_channels(o, op, n, a->chlist);
    case EXR_ATTR_CHROMATICITIES:
        return exr_attr_set_chromaticities(o, op, n, a->chromaticities);
    case EXR_ATTR_COMPRESSION:
        return exr_attr_set_compression(o, op, n, (exr_compression_t) a->uc);
    case EXR_ATTR_DOUBLE: return exr_attr_set_double(o, op, n, a->d);
    case EXR_ATTR_ENVMAP: return exr_attr_set_envmap(o, op, n, (exr_envmap_t) a->uc);
    case EXR_ATTR_FLOAT: return exr_attr_set_float(o, op, n, a->f);
    case EXR_ATTR_FLOAT_VECTOR:
        return exr_attr_set_float_vector(o, op, n, a->floatvector->length,
                                         a->floatvector->arr);
    case EXR_ATTR_INT: return exr_attr_set_int(o, op, n, a->i);
    case EXR_ATTR_KEYCODE: return exr_attr_set_keycode(o, op, n, a->keycode);
    case EXR_ATTR_LINEORDER:
        return exr_attr_set_lineorder(o, op, n, (exr_lineorder_t) a->uc);
    case EXR_ATTR_M33F: return exr_attr_set_m33f(o, op, n, a->m33f);
    case EXR_ATTR_M33D: return exr_attr_set_m33d(o, op, n, a->m33d);
    case EXR_ATTR_M44F: return exr_attr_set_m44f(o, op, n, a->m44f);
    case EXR_ATTR_M44D: return exr_attr_set_m44d(o, op, n, a->m44d);
    case EXR_ATTR_PREVIEW: return exr_attr_set_preview(o, op, n, a->preview);
    case EXR_ATTR_RATIONAL: return exr_attr_set_rational(o, op, n, a->rational);
    case EXR_ATTR_STRING:
        return exr_attr_set_string(o, op, n, a->string->str ? a->string->str : "");
    case EXR_ATTR_STRING_VECTOR: {
        int32_t k = a->stringvector->n_strings;
        const char **sv = calloc(k > 0 ? (size_t) k : 1, sizeof *sv);
        if (!sv)
            return EXR_ERR_OUT_OF_MEMORY;
        for (int32_t i = 0; i < k; ++i)
            sv[i] = a->stringvector->strings[i].str ? a->stringvector->strings[i].str : "";
        exr_result_t rv = exr_attr_set_string_vector(o, op, n, k, sv);
        free(sv);
        return rv;
    }
    case EXR_ATTR_TILEDESC: return exr_attr_set_tiledesc(o, op, n, a->tiledesc);
    case EXR_ATTR_TIMECODE: return exr_attr_set_timecode(o, op, n, a->timecode);
    case EXR_ATTR_V2I: return exr_attr_set_v2i(o, op, n, a->v2i);
    case EXR_ATTR_V2F: return exr_attr_set_v2f(o, op, n, a->v2f);
    case EXR_ATTR_V2D: return exr_attr_set_v2d(o, op, n, a->v2d);
    case EXR_ATTR_V3I: return exr_attr_set_v3i(o, op, n, a->v3i);
    case EXR_ATTR_V3F: return exr_attr_set_v3f(o, op, n, a->v3f);
    case EXR_ATTR_V3D: return exr_attr_set_v3d(o, op, n, a->v3d);
    case EXR_ATTR_OPAQUE:
        /* unknown types travel as their packed bytes */
        return exr_attr_set_user(o, op, n, a->type_name, a->opaque->size,
                                 a->opaque->packed_data);
    default: return EXR_ERR_SUCCESS;
    }
}

/* Add or replace (same name) a channel of an output part. */
static void put_chan(out_part_t *op, const out_chan_t *c)
{
    for (int i = 0; i < op->num; ++i)
        if (strcmp(op->ch[i].name, c->name) == 0) {
            op->ch[i] = *c;
            return;
        }
    op->ch[op->num++] = *c;
}

static int encode_part(exr_context_t o, int idx, const out_part_t *op,
                       const exr_attr_box2i_t *dw, fp_exr_io_t *io,
                       const char *where, long frame)
{
    char lt[512];
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    exr_chunk_info_t ci;
    int inited = 0;
    int rc = FP_ERR;
    int32_t lpc = 0;
    int *map = NULL;
    int64_t y = dw->min.y;
    exr_result_t rv = exr_get_scanlines_per_chunk(o, idx, &lpc);
    if (rv != EXR_ERR_SUCCESS)
        goto fail;
    map = malloc((size_t) (op->num > 0 ? op->num : 1) * sizeof *map);
    if (!map) {
        rv = EXR_ERR_OUT_OF_MEMORY;
        goto fail;
    }
    int64_t h = (int64_t) dw->max.y - dw->min.y + 1;
    int64_t nchunks = (h + lpc - 1) / lpc;
    /* The library takes chunks in increasing index order whatever the
     * part's line order (it refuses any other sequence unless RANDOM_Y);
     * readers find them through the offset table either way. */
    for (int64_t k = 0; k < nchunks; ++k) {
        y = dw->min.y + k * lpc;
        rv = exr_write_scanline_chunk_info(o, idx, (int) y, &ci);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
        rv = inited ? exr_encoding_update(o, idx, &ci, &enc)
                    : exr_encoding_initialize(o, idx, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
        for (int c = 0; c < enc.channel_count; ++c) {
            exr_coding_channel_info_t *cc = &enc.channels[c];
            if (!inited) {
                map[c] = -1;
                for (int i = 0; i < op->num; ++i)
                    if (strcmp(op->ch[i].name, cc->channel_name) == 0)
                        map[c] = i;
            }
            if (map[c] < 0) {
                rv = EXR_ERR_INVALID_ARGUMENT;
                goto fail;
            }
            const out_chan_t *oc = &op->ch[map[c]];
            int64_t row = sampled_count(dw->min.y, ci.start_y, oc->ys);
            cc->encode_from_ptr = oc->base + (size_t) row * oc->line_stride;
            cc->user_pixel_stride = oc->pixel_stride;
            cc->user_line_stride = (int32_t) oc->line_stride;
            cc->user_bytes_per_element = (int16_t) oc->user_bpe;
            cc->user_data_type = (uint16_t) oc->user_type;
        }
        if (!inited) {
            rv = exr_encoding_choose_default_routines(o, idx, &enc);
            if (rv != EXR_ERR_SUCCESS)
                goto fail;
            inited = 1;
        }
        rv = exr_encoding_run(o, idx, &enc);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
    }
    rc = FP_OK;
    goto done;
fail:
    fp_error("%s: frame %ld: cannot encode part %d at line %lld (%s%s)", where,
             frame, idx, (long long) y, lib_text(io, rv, lt, sizeof lt),
             rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED
                 ? "; this OpenEXR C library cannot write it: choose another compression"
                 : "");
done:
    if (inited || enc.channels)
        exr_encoding_destroy(o, &enc);
    free(map);
    return rc;
}

int fp_exr_encode(const fp_frame_t *f, const float *rgba,
                  const fp_exr_write_opts_t *opts, const char *where_file,
                  long frame, void **out, size_t *out_size)
{
    static const fp_exr_write_opts_t defaults = FP_EXR_WRITE_OPTS_INITIALIZER;
    static const char *const rgba_names[4] = { "R", "G", "B", "A" };
    char lt[512];
    char *saved_msg = tl_msg;
    const char *where = where_file ? where_file : "<output>";
    fp_exr_io_t io;
    exr_context_t o = NULL;
    out_part_t *ops = NULL;
    int *out_idx = NULL;
    int rc = FP_ERR;
    exr_result_t rv;

    memset(&io, 0, sizeof io);
    tl_msg = io.msg;
    *out = NULL;
    *out_size = 0;
    if (!opts)
        opts = &defaults;
    if (!rgba)
        rgba = f->rgba;
    if (opts->compression < -1 || opts->compression >= EXR_COMPRESSION_LAST_TYPE) {
        fp_error("%s: frame %ld: unknown compression %d", where, frame,
                 opts->compression);
        goto done;
    }
    if (opts->num_extra < 0 || (opts->num_extra > 0 && !opts->extra)) {
        fp_error("%s: frame %ld: bad extra channel list", where, frame);
        goto done;
    }

    const fp_frame_info_t *in = &f->info;
    size_t w = (size_t) in->width;
    int color_type = opts->use_float ? EXR_PIXEL_FLOAT : EXR_PIXEL_HALF;

    /* Plan every output part's channel list. */
    ops = calloc((size_t) f->num_parts, sizeof *ops);
    out_idx = calloc((size_t) f->num_parts, sizeof *out_idx);
    if (!ops || !out_idx)
        goto oom;
    for (int p = 0; p < f->num_parts; ++p) {
        const fp_part_t *pt = &f->parts[p];
        out_part_t *op = &ops[p];
        op->src = p;
        op->ch = calloc((size_t) pt->num_chans + (size_t) opts->num_extra + 4,
                        sizeof *op->ch);
        if (!op->ch)
            goto oom;
        for (int c = 0; c < pt->num_chans; ++c) {
            const fp_chan_t *ch = &pt->chans[c];
            out_chan_t oc = { ch->name, ch->type, ch->p_linear, ch->xs, ch->ys,
                              ch->raw, ch->type, (int) ch->bpe, (int) ch->bpe,
                              (size_t) ch->w * ch->bpe };
            int role = ROLE_PASS;
            for (int k = 0; k < 4; ++k)
                if (p == f->color_part && c == f->color_chan[k])
                    role = ROLE_R + k;
            if (role != ROLE_PASS) {
                if (!rgba || opts->drop_color)
                    continue;
                oc.type = color_type;
                oc.base = (const uint8_t *) (rgba + (role - ROLE_R));
                oc.user_type = EXR_PIXEL_FLOAT;
                oc.user_bpe = 4;
                oc.pixel_stride = 4 * sizeof(float);
                oc.line_stride = w * 4 * sizeof(float);
            } else if (opts->color_only || !ch->raw) {
                continue;
            }
            put_chan(op, &oc);
        }
        if (p == f->main_part) {
            if (f->color_part < 0 && rgba && !opts->drop_color) {
                /* colour for a file that had none: R, G, B, A */
                for (int k = 0; k < 4; ++k) {
                    out_chan_t oc = { rgba_names[k], color_type, 0, 1, 1,
                                      (const uint8_t *) (rgba + k),
                                      EXR_PIXEL_FLOAT, 4, 4 * sizeof(float),
                                      w * 4 * sizeof(float) };
                    put_chan(op, &oc);
                }
            }
            for (int e = 0; e < opts->num_extra; ++e) {
                out_chan_t oc = { opts->extra[e].name, EXR_PIXEL_FLOAT, 1, 1, 1,
                                  (const uint8_t *) opts->extra[e].data,
                                  EXR_PIXEL_FLOAT, 4, 4, w * 4 };
                if (!oc.name || !*oc.name || !oc.base) {
                    fp_error("%s: frame %ld: extra channel %d has no name or data",
                             where, frame, e);
                    goto done;
                }
                put_chan(op, &oc);
            }
        }
    }

    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = lib_error_handler;
    init.user_data = &io;
    init.write_fn = mem_write;
    rv = exr_start_write(&o, where, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv != EXR_ERR_SUCCESS) {
        o = NULL;
        goto lib_fail;
    }
    int nout = 0;
    for (int p = 0; p < f->num_parts; ++p) {
        const fp_part_t *pt = &f->parts[p];
        out_part_t *op = &ops[p];
        out_idx[p] = -1;
        if (op->num == 0)
            continue; /* a part with nothing left (--color-only) is dropped */
        const char *name = NULL;
        exr_get_name(f->ctx, p, &name);
        float par = 1.0f, sww = 1.0f;
        exr_attr_v2f_t swc = { { { 0.0f, 0.0f } } };
        exr_get_pixel_aspect_ratio(f->ctx, p, &par);
        exr_get_screen_window_center(f->ctx, p, &swc);
        exr_get_screen_window_width(f->ctx, p, &sww);
        io.msg[0] = '\0'; /* absent optional values are not errors */
        int lo = pt->lineorder;
        if (lo != EXR_LINEORDER_DECREASING_Y)
            lo = EXR_LINEORDER_INCREASING_Y; /* tiled RANDOM_Y has no scanline meaning */
        int comp = opts->compression >= 0 ? opts->compression : pt->compression;
        int idx = -1;
        rv = exr_add_part(o, name, EXR_STORAGE_SCANLINE, &idx);
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_initialize_required_attr(o, idx, &pt->disp, &pt->dw, par, &swc,
                                              sww, (exr_lineorder_t) lo,
                                              (exr_compression_t) comp);
        /* the library keeps the channel list sorted by name */
        for (int c = 0; c < op->num && rv == EXR_ERR_SUCCESS; ++c)
            rv = exr_add_channel(o, idx, op->ch[c].name,
                                 (exr_pixel_type_t) op->ch[c].type,
                                 (exr_perceptual_treatment_t) op->ch[c].p_linear,
                                 op->ch[c].xs, op->ch[c].ys);
        int32_t na = 0;
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_get_attribute_count(f->ctx, p, &na);
        for (int32_t i = 0; i < na && rv == EXR_ERR_SUCCESS; ++i) {
            const exr_attribute_t *a = NULL;
            rv = exr_get_attribute_by_index(f->ctx, p, EXR_ATTR_LIST_FILE_ORDER,
                                            i, &a);
            if (rv == EXR_ERR_SUCCESS && a && !is_structural_attr(a->name) &&
                !(p == f->main_part && opts->set_chromaticities &&
                  strcmp(a->name, "chromaticities") == 0))
                rv = copy_attr(o, idx, a);
        }
        if (rv == EXR_ERR_SUCCESS && p == f->main_part && opts->set_chromaticities > 0) {
            const float *c = opts->chromaticities;
            exr_attr_chromaticities_t chr = { c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7] };
            rv = exr_attr_set_chromaticities(o, idx, "chromaticities", &chr);
        }
        if (rv != EXR_ERR_SUCCESS)
            goto lib_fail;
        out_idx[p] = idx;
        nout++;
    }
    if (nout == 0) {
        fp_error("%s: frame %ld: nothing to write (no channels left)", where, frame);
        goto done;
    }
    rv = exr_write_header(o);
    if (rv != EXR_ERR_SUCCESS)
        goto lib_fail;
    for (int p = 0; p < f->num_parts; ++p) {
        if (out_idx[p] < 0)
            continue;
        if (encode_part(o, out_idx[p], &ops[p], &f->parts[p].dw, &io, where,
                        frame) != FP_OK)
            goto done;
    }
    /* exr_finish writes the offset tables: only then are the bytes whole */
    rv = exr_finish(&o);
    o = NULL;
    if (rv != EXR_ERR_SUCCESS || io.wr_failed)
        goto lib_fail;
    *out = io.wr;
    *out_size = io.wr_size;
    io.wr = NULL;
    rc = FP_OK;
    goto done;
oom:
    fp_error("%s: frame %ld: out of memory", where, frame);
    goto done;
lib_fail:
    fp_error("%s: frame %ld: cannot write EXR (%s)", where, frame,
             lib_text(&io, rv, lt, sizeof lt));
done:
    if (o)
        exr_finish(&o);
    tl_msg = saved_msg;
    if (ops)
        for (int p = 0; p < f->num_parts; ++p)
            free(ops[p].ch);
    free(ops);
    free(out_idx);
    free(io.wr);
    return rc;
}

int fp_exr_write_bytes(const char *path, long frame, const void *buf, size_t size)
{
    char label[64];
    snprintf(label, sizeof label, ": frame %ld", frame);
    return write_atomic(path, buf, size, label);
}

int fp_exr_write_file(const fp_frame_t *f, const float *rgba,
                      const fp_exr_write_opts_t *opts, const char *path,
                      long frame)
{
    void *buf = NULL;
    size_t size = 0;
    int rc = fp_exr_encode(f, rgba, opts, path, frame, &buf, &size);
    if (rc == FP_OK)
        rc = fp_exr_write_bytes(path, frame, buf, size);
    free(buf);
    return rc;
}

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

static uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t) p[0] | (uint32_t) p[1] << 8 | (uint32_t) p[2] << 16 |
           (uint32_t) p[3] << 24;
}

static int32_t rd_i32(const uint8_t *p)
{
    uint32_t u = rd_u32(p);
    int32_t v;
    memcpy(&v, &u, sizeof v);
    return v;
}

static uint64_t rd_u64(const uint8_t *p)
{
    return (uint64_t) rd_u32(p) | (uint64_t) rd_u32(p + 4) << 32;
}

/* Read a NUL-terminated name at *pos (at most 255 characters). */
static int sr_name(sreader_t *r, size_t *pos, const char **name, size_t *len)
{
    size_t start = *pos;
    for (;;) {
        if (sr_need(r, *pos + 1) != FP_OK)
            return FP_ERR;
        if (r->buf[*pos] == 0)
            break;
        if (*pos - start >= 255)
            return fp_error("%s: frame %ld: corrupt EXR header (name longer than "
                            "255 characters)", r->where, r->index);
        (*pos)++;
    }
    (*pos)++;
    *len = *pos - start - 1;
    *name = (const char *) r->buf + start; /* valid until the next sr_need */
    return FP_OK;
}

typedef struct spart_t {
    int has_dw, has_tiles, has_cc, deep, tiled;
    int32_t dw[4];
    int compression;
    uint32_t tx, ty;
    int level_mode, round_mode;
    int64_t chunk_count;
} spart_t;

static int round_log2(uint32_t x, int round_up)
{
    int y = 0;
    if (!round_up) {
        while (x > 1) {
            y++;
            x >>= 1;
        }
    } else {
        int odd = 0;
        while (x > 1) {
            if (x & 1)
                odd = 1;
            y++;
            x >>= 1;
        }
        y += odd;
    }
    return y;
}

static int64_t level_size(int64_t size, int l, int round_up)
{
    int64_t b = (int64_t) 1 << l;
    int64_t s = size / b;
    if (round_up && s * b < size)
        s++;
    return s < 1 ? 1 : s;
}

/* Chunks of a part without a chunkCount attribute (single-part files):
 * from the data window and the compression's lines per chunk, or the
 * tile description and its levels. */
static int64_t count_chunks(const spart_t *sp)
{
    static const int lines[] = { 1, 1, 1, 16, 32, 16, 32, 32, 32, 256 };
    int64_t w = (int64_t) sp->dw[2] - sp->dw[0] + 1;
    int64_t h = (int64_t) sp->dw[3] - sp->dw[1] + 1;
    if (w < 1 || h < 1 || w > INT32_MAX || h > INT32_MAX)
        return -1;
    if (!sp->tiled) {
        if (sp->compression < 0 || sp->compression >= (int) FP_ARRAY_LEN(lines))
            return -1;
        int64_t l = lines[sp->compression];
        return (h + l - 1) / l;
    }
    if (sp->tx < 1 || sp->ty < 1)
        return -1;
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
    if (sp->level_mode == EXR_TILE_RIPMAP_LEVELS) {
        for (int ly = 0; ly < ny; ++ly)
            for (int lx = 0; lx < nx; ++lx) {
                int64_t lw = level_size(w, lx, up), lh = level_size(h, ly, up);
                total += ((lw + sp->tx - 1) / sp->tx) * ((lh + sp->ty - 1) / sp->ty);
                if (total > FP_EXR_MAX_CHUNKS)
                    return total;
            }
    } else {
        for (int l = 0; l < nx; ++l) {
            int64_t lw = level_size(w, l, up), lh = level_size(h, l, up);
            total += ((lw + sp->tx - 1) / sp->tx) * ((lh + sp->ty - 1) / sp->ty);
            if (total > FP_EXR_MAX_CHUNKS)
                return total;
        }
    }
    return total;
}

/* Read one header (attributes up to the terminating NUL) at *pos.
 * *empty is set when the header has no attributes (end of a multipart
 * header list). */
static int sr_header(sreader_t *r, size_t *pos, spart_t *sp, int *empty)
{
    int nattr = 0;
    *empty = 1;
    memset(sp, 0, sizeof *sp);
    sp->compression = -1;
    for (;;) {
        const char *nm, *ty;
        size_t nl, tl;
        char name[256], type[256];
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
        int32_t size = rd_i32(r->buf + *pos);
        *pos += 4;
        if (size < 0 || size > FP_EXR_MAX_ATTR_SIZE)
            return fp_error("%s: frame %ld: corrupt EXR header (attribute %s has "
                            "size %d)", r->where, r->index, name, (int) size);
        if (sr_need(r, *pos + (size_t) size) != FP_OK)
            return FP_ERR;
        const uint8_t *v = r->buf + *pos;
        if (strcmp(name, "dataWindow") == 0 && strcmp(type, "box2i") == 0 && size == 16) {
            for (int i = 0; i < 4; ++i)
                sp->dw[i] = rd_i32(v + 4 * i);
            sp->has_dw = 1;
        } else if (strcmp(name, "compression") == 0 && size == 1) {
            sp->compression = v[0];
        } else if (strcmp(name, "tiles") == 0 && strcmp(type, "tiledesc") == 0 &&
                   size == 9) {
            sp->tx = rd_u32(v);
            sp->ty = rd_u32(v + 4);
            sp->level_mode = v[8] & 0xf;
            sp->round_mode = (v[8] >> 4) & 0xf;
            sp->has_tiles = 1;
        } else if (strcmp(name, "chunkCount") == 0 && strcmp(type, "int") == 0 &&
                   size == 4) {
            sp->chunk_count = rd_i32(v);
            sp->has_cc = 1;
        } else if (strcmp(name, "type") == 0 && strcmp(type, "string") == 0) {
            if ((size == 12 && memcmp(v, "deepscanline", 12) == 0) ||
                (size == 8 && memcmp(v, "deeptile", 8) == 0))
                sp->deep = 1;
            else if (size == 10 && memcmp(v, "tiledimage", 10) == 0)
                sp->tiled = 1;
        }
        *pos += (size_t) size;
    }
}

int fp_exr_stream_next(FILE *in, const char *where_file, long index,
                       void **buf, size_t *size)
{
    sreader_t r = { in, NULL, 0, 0, where_file ? where_file : "<stdin>", index,
                    "header" };
    spart_t *parts = NULL;
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
    if (rd_u32(r.buf) != FP_EXR_MAGIC) {
        fp_error("%s: frame %ld: not an EXR file (bad magic number)", r.where, index);
        goto done;
    }
    r.section = "version field";
    if (sr_need(&r, 8) != FP_OK)
        goto done;
    uint32_t version = rd_u32(r.buf + 4);
    int multipart = (version & 0x1000) != 0;
    if ((version & 0xff) != 2) {
        fp_error("%s: frame %ld: unsupported EXR version %u (expected 2)", r.where,
                 index, version & 0xff);
        goto done;
    }
    if (version & 0x800) {
        fp_error("%s: frame %ld: deep EXR data is not supported", r.where, index);
        goto done;
    }
    pos = 8;
    for (;;) {
        spart_t sp;
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
        if (sp.deep) {
            fp_error("%s: frame %ld: part %d holds deep data, which is not "
                     "supported", r.where, index, nparts);
            goto done;
        }
        if (sp.tiled && !sp.has_tiles) {
            fp_error("%s: frame %ld: corrupt EXR header (tiled part %d without "
                     "tile description)", r.where, index, nparts);
            goto done;
        }
        if (!sp.has_cc)
            sp.chunk_count = count_chunks(&sp);
        if (sp.chunk_count < 1 || sp.chunk_count > FP_EXR_MAX_CHUNKS) {
            fp_error("%s: frame %ld: corrupt EXR header (part %d: %lld chunks)",
                     r.where, index, nparts, (long long) sp.chunk_count);
            goto done;
        }
        if (nparts == cap) {
            int ncap = cap ? cap * 2 : 4;
            spart_t *np = realloc(parts, (size_t) ncap * sizeof *np);
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
        if (nparts > FP_EXR_MAX_PARTS) {
            fp_error("%s: frame %ld: corrupt EXR header (more than %d parts)",
                     r.where, index, FP_EXR_MAX_PARTS);
            goto done;
        }
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
        uint64_t off = rd_u64(r.buf + pos + (size_t) i * 8);
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
        part = rd_i32(r.buf + at);
        at += 4;
        if (part < 0 || part >= nparts) {
            fp_error("%s: frame %ld: corrupt EXR chunk (part number %d of %d)",
                     r.where, index, part, nparts);
            goto done;
        }
    }
    /* tiled: tile x, y, level x, y; scanline: y; then the data size */
    uint64_t lead = parts[part].tiled ? 16 : 4;
    if (sr_need(&r, at + lead + 4) != FP_OK)
        goto done;
    int32_t dsize = rd_i32(r.buf + at + lead);
    if (dsize < 0) {
        fp_error("%s: frame %ld: corrupt EXR chunk (size %d)", r.where, index,
                 (int) dsize);
        goto done;
    }
    if (sr_need(&r, at + lead + 4 + (uint64_t) dsize) != FP_OK)
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
