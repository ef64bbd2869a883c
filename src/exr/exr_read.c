/* fogpipe: reading EXR frames (exrio.h).  The whole file is in memory and
 * the library reads it through fp_exr_mem_read (the in-memory stream
 * pattern of ImfCheckFile.cpp).  Colour and depth are found by name; the
 * chunks are decoded by the chunk workers, colour straight into float RGBA
 * and depth converted to float chunk by chunk; every other channel is kept
 * as bytes in its own type over its (sub-sampled) data window, so that the
 * writer can pass it through untouched.  The read context stays open with
 * the frame (its header is the source of every attribute written); the
 * file's bytes are released once decoded. */
#include "exr_dwa.h"
#include "exr_internal.h"
#include "fp.h"
#include "fp_limits.h"
#include "textfile.h"

#include <errno.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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

/* A channel's samples [first, first + n) as floats, every `stride` floats
 * from dst: one loop per sample type (this runs over every colour and depth
 * sample). */
static void samples_to_float(const fp_chan_t *ch, size_t first, size_t n,
                             float *dst, size_t stride)
{
    const uint8_t *src = ch->raw + first * ch->bpe;
    switch (ch->type) {
    case EXR_PIXEL_HALF:
        for (size_t i = 0; i < n; ++i) {
            uint16_t h;
            memcpy(&h, src + i * 2, 2);
            dst[i * stride] = half_to_float(h);
        }
        break;
    case EXR_PIXEL_UINT:
        for (size_t i = 0; i < n; ++i) {
            uint32_t u;
            memcpy(&u, src + i * 4, 4);
            dst[i * stride] = (float) u;
        }
        break;
    default:
        for (size_t i = 0; i < n; ++i)
            memcpy(&dst[i * stride], src + i * 4, 4);
        break;
    }
}

/* ------------------------------------------------------------ whole files */

/* Read a file into a malloc'd buffer without printing; *err is the errno. */
static int slurp(const char *path, void **buf, size_t *size, int *err, int exr)
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
    int regular = fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
    cap = (regular && st.st_size > 0)
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
        /* A device or a pipe may never end (/dev/zero): an EXR stops at
         * its first bytes when they are not the magic number (the parser
         * then says so), and nothing grows beyond the image budget. */
        if (!regular && exr && len >= 4 && memcmp(b, "\x76\x2f\x31\x01", 4) != 0)
            break;
        if (!regular && (int64_t) len > fp_image_file_max_bytes()) {
            *err = EFBIG;
            goto done;
        }
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
    if (slurp(path, buf, size, &err, 0) != FP_OK)
        return fp_error("%s: cannot read (%s)", path, strerror(err));
    return FP_OK;
}

/* ------------------------------------------------------------ reading */

/* Which of R, G, B, A (0-3) channel c of part p is, or -1. */
static int color_role(const fp_frame_t *f, int p, int c)
{
    if (p != f->color_part)
        return -1;
    for (int i = 0; i < 4; ++i)
        if (f->color_chan[i] == c)
            return i;
    return -1;
}

/* Describe a part's channels (their planes come with alloc_planes). */
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
                        p, fp_exr_lib_text(&f->io, rv, lt, sizeof lt));
    if (st == EXR_STORAGE_DEEP_SCANLINE || st == EXR_STORAGE_DEEP_TILED)
        return fp_error("%s: frame %ld: part %d holds deep data, which is not "
                        "supported (expected flat scanline or tiled images)",
                        where, frame, p);
    pt->storage = st;
    pt->compression = comp;
    pt->lineorder = lo;

    /* fp_exr_check_image has checked this from the bytes; the library's
     * reading of the header is held to the same budget. */
    int64_t w = (int64_t) pt->dw.max.x - pt->dw.min.x + 1;
    int64_t h = (int64_t) pt->dw.max.y - pt->dw.min.y + 1;
    char kind[64];
    snprintf(kind, sizeof kind, "part %d: data window", p);
    int max_bpe = 0;
    for (int c = 0; c < cl->num_channels; ++c)
        if ((int) type_size(cl->entries[c].pixel_type) > max_bpe)
            max_bpe = (int) type_size(cl->entries[c].pixel_type);
    if (fp_image_limits_check(where, frame, kind, w, h, cl->num_channels, max_bpe) != FP_OK)
        return FP_ERR;

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
    }
    return FP_OK;
}

/* A buffer of `bytes` at a page boundary inside a plain malloc block
 * (*mem, what free takes).  posix_memalign's split-off remainders stay
 * between the frames' blocks in glibc's heap and keep them from merging:
 * 2-3x the page faults a frame at 1080p. */
static float *alloc_aligned(size_t bytes, void **mem)
{
    *mem = malloc(bytes + 4096);
    return *mem ? (float *)(((uintptr_t)*mem + 4095) & ~(uintptr_t)4095) : NULL;
}

/* The planes of every channel that is kept as bytes: all but the colour
 * channels, which the library decodes straight into the frame's float
 * RGBA (a colour channel that is also the depth channel keeps its bytes).
 * Not when the colour's part holds nothing but the colour: OpenEXR 3.1.5
 * then takes a fast path for 3 or 4 half channels into interleaved floats
 * that puts them in file order (A,B,G,R) whatever the pointers say, so
 * those are decoded as bytes and converted here (to_float_rect). */
static int alloc_planes(fp_frame_t *f, const char *where, long frame)
{
    int ncolor = 0;
    for (int i = 0; i < 4; ++i)
        ncolor += f->color_chan[i] >= 0;
    int direct = f->color_part >= 0 && f->parts[f->color_part].num_chans > ncolor;
    for (int p = 0; p < f->num_parts; ++p) {
        fp_part_t *pt = &f->parts[p];
        for (int c = 0; c < pt->num_chans; ++c) {
            fp_chan_t *ch = &pt->chans[c];
            if (direct && color_role(f, p, c) >= 0 &&
                !(p == f->depth_part && c == f->depth_chan))
                continue;
            size_t bytes = (size_t) ch->w * (size_t) ch->h * ch->bpe;
            ch->raw = calloc(bytes ? bytes : 1, 1);
            if (!ch->raw)
                return fp_error("%s: frame %ld: out of memory (%zu bytes for "
                                "channel %s)", where, frame, bytes, ch->name);
        }
    }
    return FP_OK;
}

/* Decode one chunk whose first pixel is (x0, y0), absolute coordinates. */
static exr_result_t decode_chunk(fp_frame_t *f, int p, exr_decode_pipeline_t *dec,
                                 fp_zip_t *zip, int *inited, const exr_chunk_info_t *ci,
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
                    : fp_exr_find_in_part(pt, cc->channel_name);
        if (k < 0) {
            cc->decode_to_ptr = NULL;
            continue;
        }
        fp_chan_t *ch = &pt->chans[k];
        int64_t row = sampled_count(pt->dw.min.y, y0, ch->ys);
        int64_t col = sampled_count(pt->dw.min.x, x0, ch->xs);
        int role = ch->raw ? -1 : color_role(f, p, k);
        if (role >= 0) {
            /* straight into the float RGBA (full resolution, see
             * fp_exr_select_channels) */
            size_t at = ((size_t) row * (size_t) ch->w + (size_t) col) * 4 + (size_t) role;
            cc->decode_to_ptr = (uint8_t *) (f->rgba + at);
            cc->user_pixel_stride = 4 * (int32_t) sizeof(float);
            cc->user_line_stride = (int32_t) ((size_t) ch->w * 4 * sizeof(float));
            cc->user_bytes_per_element = (int16_t) sizeof(float);
            cc->user_data_type = (uint16_t) EXR_PIXEL_FLOAT;
            continue;
        }
        if (!ch->raw) {
            cc->decode_to_ptr = NULL;
            continue;
        }
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
        /* the file's compression (a DWA input's parts were rewritten, so
         * not pt->compression) */
        exr_compression_t comp = EXR_COMPRESSION_NONE;
        rv = exr_get_compression(f->ctx, p, &comp);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
        if (dec->decompress_fn && fp_zip_enabled() && fp_zip_is_zip(comp))
            fp_zip_use_decoder(dec, zip); /* libdeflate for OpenEXR's zlib */
        *inited = 1;
    }
    return exr_decoding_run(f->ctx, p, dec);
}

/* The chunks of one part, decoded by workers that each claim the next
 * chunk and run their own pipeline (the C API decodes chunks
 * independently; a read context is not changed by decoding). */
typedef struct dec_job_t {
    fp_frame_t *f;
    int p;
    const exr_chunk_info_t *ci;
    const int *x0, *y0;          /* each chunk's first pixel */
    int64_t n;
    atomic_llong next;
    atomic_int stop;
} dec_job_t;

/* The colour and depth of a decoded chunk, whose first pixel is (ax, ay),
 * into the frame's floats (the chunk's pixels only, so that workers write
 * apart). */
static void to_float_rect(fp_frame_t *f, int p, const exr_chunk_info_t *ci,
                          int ax, int ay)
{
    const fp_part_t *pt = &f->parts[p];
    size_t w = (size_t) (pt->dw.max.x - pt->dw.min.x + 1);
    /* (a tile's start_x, start_y are tile numbers: its first pixel is
     * (ax, ay)) */
    int64_t x0 = (int64_t) ax - pt->dw.min.x, y0 = (int64_t) ay - pt->dw.min.y;
    int64_t cw = ci->width, ch = ci->height;
    int64_t h = (int64_t) pt->dw.max.y - pt->dw.min.y + 1;
    /* edge tiles: OpenEXR 3.1 may give a whole tile's size */
    if (x0 + cw > (int64_t) w)
        cw = (int64_t) w - x0;
    if (y0 + ch > h)
        ch = h - y0;
    if (x0 < 0 || y0 < 0 || cw < 1 || ch < 1)
        return;
    for (int64_t r = y0; r < y0 + ch; ++r) {
        size_t first = (size_t) r * w + (size_t) x0;
        if (p == f->color_part)
            for (int k = 0; k < 4; ++k) {
                float *dst = f->rgba + first * 4 + (size_t) k;
                if (f->color_chan[k] < 0)
                    for (int64_t i = 0; i < cw; ++i)
                        dst[i * 4] = 1.0f;
                else if (pt->chans[f->color_chan[k]].raw) /* see alloc_planes */
                    samples_to_float(&pt->chans[f->color_chan[k]], first,
                                     (size_t) cw, dst, 4);
            }
        if (p == f->depth_part)
            samples_to_float(&pt->chans[f->depth_chan], first, (size_t) cw,
                             f->depth + first, 1);
    }
}

static void *dec_work(void *arg)
{
    fp_exr_worker_t *w = arg;
    dec_job_t *j = w->job;
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    fp_zip_t zip = { 0 };
    int inited = 0;
    char *saved = fp_exr_tl_msg;
    fp_exr_tl_msg = w->msg;
    for (;;) {
        int64_t k = atomic_fetch_add(&j->next, 1);
        if (k >= j->n || atomic_load(&j->stop))
            break;
        exr_result_t rv = decode_chunk(j->f, j->p, &dec, &zip, &inited, &j->ci[k],
                                       j->x0[k], j->y0[k]);
        if (rv == EXR_ERR_SUCCESS)
            to_float_rect(j->f, j->p, &j->ci[k], j->x0[k], j->y0[k]);
        if (rv != EXR_ERR_SUCCESS) {
            w->fail = k;
            w->rv = rv;
            atomic_store(&j->stop, 1);
            break;
        }
    }
    exr_decoding_destroy(j->f->ctx, &dec);
    fp_zip_release(&zip);
    fp_exr_tl_msg = saved;
    return NULL;
}

static int decode_part(fp_frame_t *f, int p, const char *where, long frame)
{
    char lt[512];
    fp_part_t *pt = &f->parts[p];
    int rc = FP_ERR;
    exr_result_t rv = EXR_ERR_SUCCESS;
    int at_x = pt->dw.min.x, at_y = pt->dw.min.y;
    const char *why = NULL;      /* a worker's message, else the frame's */
    exr_chunk_info_t *ci = NULL;
    int *xy = NULL;
    fp_exr_worker_t *wk = NULL;
    int64_t n = 0, nmax;
    int64_t w = (int64_t) pt->dw.max.x - pt->dw.min.x + 1;
    int64_t h = (int64_t) pt->dw.max.y - pt->dw.min.y + 1;
    int32_t lpc = 0, tw = 0, th = 0;
    int64_t ntx = 1;

    if (pt->num_chans == 0)
        return FP_OK;
    if (pt->storage == EXR_STORAGE_SCANLINE) {
        rv = exr_get_scanlines_per_chunk(f->ctx, p, &lpc);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
        nmax = (h + lpc - 1) / lpc;
    } else {
        /* tiled: the highest resolution level (0,0) only */
        rv = exr_get_tile_sizes(f->ctx, p, 0, 0, &tw, &th);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
        ntx = (w + tw - 1) / tw;
        nmax = ntx * ((h + th - 1) / th);
    }
    ci = malloc((size_t) nmax * sizeof *ci);
    xy = malloc((size_t) nmax * 2 * sizeof *xy);
    if (!ci || !xy) {
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    /* Where every chunk is, in file order, up to the first that cannot be
     * found: the chunks before it are decoded first, so that the error
     * reported is the first in chunk order, as one thread would meet it. */
    for (; n < nmax; ++n) {
        if (pt->storage == EXR_STORAGE_SCANLINE) {
            at_y = (int) (pt->dw.min.y + n * lpc);
            rv = exr_read_scanline_chunk_info(f->ctx, p, at_y, &ci[n]);
        } else {
            int64_t tx = n % ntx, ty = n / ntx;
            at_x = (int) (pt->dw.min.x + tx * tw);
            at_y = (int) (pt->dw.min.y + ty * th);
            rv = exr_read_tile_chunk_info(f->ctx, p, (int) tx, (int) ty, 0, 0, &ci[n]);
        }
        if (rv != EXR_ERR_SUCCESS)
            break;
        xy[n] = at_x;
        xy[nmax + n] = at_y;
    }
    exr_result_t info_rv = rv;
    char info_msg[FP_EXR_MSG_LEN];
    snprintf(info_msg, sizeof info_msg, "%s", f->io.msg);
    f->io.msg[0] = '\0';

    int nw = fp_exr_workers(w * h, n);
    wk = calloc((size_t) nw, sizeof *wk);
    if (!wk) {
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    dec_job_t job = { f, p, ci, xy, xy + nmax, n, 0, 0 };
    const fp_exr_worker_t *first = fp_exr_run_workers(dec_work, &job, wk, nw);
    if (first) {
        int64_t k = first->fail;
        rv = first->rv;
        at_x = xy[k];
        at_y = xy[nmax + k];
        why = first->msg;
        goto fail;
    }
    if (info_rv != EXR_ERR_SUCCESS) {
        rv = info_rv;
        snprintf(f->io.msg, sizeof f->io.msg, "%s", info_msg);
        goto fail;
    }
    rc = FP_OK;
    goto done;
fail:
    fp_exr_fail_text(&f->io, why, rv, lt, sizeof lt);
    fp_error("%s: frame %ld: part %d: cannot decode pixels at %d,%d (%s%s)",
             where, frame, p, at_x, at_y, lt,
             rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED
                 ? "; this OpenEXR C library cannot read it: re-encode the input"
                 : "");
done:
    free(wk);
    free(xy);
    free(ci);
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
 * samples/blender/fogpipe_camera.py) and Blender's stamp "Lens"; and the
 * rig (its text form in any string attribute, its typed attributes). */
static void read_camera_text(fp_frame_t *f, fp_frame_info_t *in)
{
    for (int p = 0; p < f->num_parts; ++p) {
        int32_t n = 0;
        if (exr_get_attribute_count(f->ctx, p, &n) != EXR_ERR_SUCCESS)
            continue;
        for (int32_t i = 0; i < n; ++i) {
            const exr_attribute_t *a = NULL;
            if (exr_get_attribute_by_index(f->ctx, p, EXR_ATTR_LIST_FILE_ORDER, i, &a) !=
                    EXR_ERR_SUCCESS || !a || fp_exr_rig_attr(a, &in->rig) ||
                a->type != EXR_ATTR_STRING || !a->string || !a->string->str)
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
    char *saved_msg = fp_exr_tl_msg;
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
    f->src = strdup(where);
    f->io.rd = buf;
    f->io.rd_size = size;
    fp_exr_tl_msg = f->io.msg;

    const uint8_t *b = buf;
    if (size < 8 || ((uint32_t) b[0] | (uint32_t) b[1] << 8 | (uint32_t) b[2] << 16 |
                     (uint32_t) b[3] << 24) != FP_EXR_MAGIC) {
        fp_error("%s: frame %ld: not an EXR file (bad magic number)", where, frame);
        goto done;
    }
    /* The budget and the file's size against what its header claims,
     * before either path below allocates anything for the pixels. */
    if (fp_exr_check_image(buf, size, where, frame) != FP_OK)
        goto done;
    /* The C library has no DWA codec (and misreads float channels of
     * B44): such an input is first rewritten with those parts uncompressed
     * by the C++ library (exr_dwa.h).  The C library reads its header
     * first: the C++ library trusts a corrupt attribute's size (a box2f of
     * 64 bytes, a displayWindow of none) and reads the next bytes as
     * attributes, whose sizes it then allocates, gigabytes from a few
     * bytes; the C library says what is wrong, as it does for any other
     * input. */
    int verdict = fp_dwa_probe(buf, size);
    void *plain = NULL;
    size_t plain_size = 0;
    if (verdict) {
        if (fp_exr_start_read(&f->io, &f->ctx, where, frame) != FP_OK)
            goto done;
        exr_finish(&f->ctx);
        f->ctx = NULL;
    }
    if (verdict && fp_dwa_decode(buf, size, verdict, where, frame, &plain, &plain_size,
                                 &f->dwa_comp, &f->dwa_num_parts) != FP_OK)
        goto done;
    if (plain) {
        free(f->buf);
        f->buf = plain;
        f->size = plain_size;
        f->io.rd = plain;
        f->io.rd_size = plain_size;
    }
    if (fp_exr_start_read(&f->io, &f->ctx, where, frame) != FP_OK)
        goto done;
    rv = exr_get_count(f->ctx, &f->num_parts);
    if (rv != EXR_ERR_SUCCESS || f->num_parts < 1) {
        fp_error("%s: frame %ld: cannot read EXR header (%s)", where, frame,
                 fp_exr_lib_text(&f->io, rv, lt, sizeof lt));
        goto done;
    }
    f->parts = calloc((size_t) f->num_parts, sizeof *f->parts);
    if (!f->parts) {
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    for (int p = 0; p < f->num_parts; ++p) {
        if (setup_part(f, p, where, frame) != FP_OK)
            goto done;
        if (f->dwa_comp && p < f->dwa_num_parts)
            f->parts[p].compression = f->dwa_comp[p]; /* the input's, not NONE */
    }
    if (fp_exr_select_channels(f, sel, where, frame) != FP_OK)
        goto done;
    f->main_part = f->color_part >= 0 ? f->color_part
                   : f->depth_part >= 0 ? f->depth_part : 0;
    const fp_part_t *mp = &f->parts[f->main_part];
    size_t w = (size_t) (mp->dw.max.x - mp->dw.min.x + 1);
    size_t h = (size_t) (mp->dw.max.y - mp->dw.min.y + 1);
    /* Colour is decoded to float by the library, depth converted chunk by
     * chunk as they are decoded (to_float_rect), by the thread that decoded
     * the chunk.  Colour is written from rgba, so its bytes are not kept.
     * Both page-aligned: a device in the host's memory works in them as
     * they are (filters/integrate.h, fp_integrate_over_ok). */
    if (f->color_part >= 0 && !(f->rgba = alloc_aligned(w * h * 4 * sizeof(float), &f->rgba_mem))) {
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    if (f->depth_part >= 0 && !(f->depth = alloc_aligned(w * h * sizeof(float), &f->depth_mem))) {
        fp_error("%s: frame %ld: out of memory", where, frame);
        goto done;
    }
    if (alloc_planes(f, where, frame) != FP_OK)
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
    if (f->color_part >= 0) {
        /* Colour decoded as bytes (see alloc_planes) is written from rgba:
         * its bytes are not needed, but those of the depth channel are. */
        fp_part_t *pt = &f->parts[f->color_part];
        for (int k = 0; k < 4; ++k) {
            int c = f->color_chan[k];
            if (c >= 0 && !(f->depth_part == f->color_part && f->depth_chan == c)) {
                free(pt->chans[c].raw);
                pt->chans[c].raw = NULL;
            }
        }
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
    fp_exr_tl_msg = saved_msg;
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
    if (slurp(path, buf, size, &err, 1) != FP_OK)
        return fp_error("%s: frame %ld: cannot read (%s)", path, frame,
                        err == EFBIG ? "a device or pipe giving more bytes than the image "
                                       "budget allows" : strerror(err));
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
    free(f->depth_mem);
    f->depth = depth->depth;
    f->depth_mem = depth->depth_mem;
    depth->depth = NULL;
    depth->depth_mem = NULL;
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
        char *saved = fp_exr_tl_msg;
        fp_exr_tl_msg = f->io.msg;
        exr_finish(&f->ctx);
        fp_exr_tl_msg = saved;
    }
    fp_exr_rig_attrs_free(&f->info.rig);
    free(f->rgba_mem);
    free(f->depth_mem);
    free(f->buf);
    free(f->dwa_comp);
    free(f->src);
    free(f);
}
