/* fogpipe: deep scanline EXR in and out (see exr_deep.h).
 *
 * A deep scanline chunk is one line: its sample count table (per pixel
 * the running total of samples, int32) and its sample data (per channel,
 * in the channel list's order, every sample of every pixel of the line),
 * each compressed on its own by the part's codec: NONE, RLE or ZIPS, the
 * only ones OpenEXR allows for deep data.  RLE and ZIPS first split the
 * bytes into even and odd halves and take differences (fp_zip_deconstruct,
 * OpenEXR's internal_zip.c / ImfRleCompressor.cpp); a block whose
 * compressed size is not below its raw size is stored raw. */
#include "exr_deep.h"
#include "exr_internal.h"
#include "fp.h"
#include "fp_limits.h"

#include <libdeflate.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct fp_deep_src_t {
    void *buf;
    size_t size;
    fp_exr_io_t io;
    exr_context_t ctx;
};

/* ------------------------------------------------------------ half floats */

static float half_to_float(uint16_t h)
{
    uint32_t s = (uint32_t)(h & 0x8000) << 16, e = (h >> 10) & 0x1f, m = h & 0x3ff, bits;
    if (e == 0) {
        if (m == 0) {
            bits = s;
        } else {   /* subnormal */
            float v = ldexpf((float)m, -24);
            return s ? -v : v;
        }
    } else if (e == 31) {
        bits = s | 0x7f800000u | (m << 13);
    } else {
        bits = s | ((e + 112) << 23) | (m << 13);
    }
    float f;
    memcpy(&f, &bits, 4);
    return f;
}

/* Round to nearest even, as OpenEXR's half. */
static uint16_t float_to_half(float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t s = (x >> 16) & 0x8000, e = (x >> 23) & 0xff, m = x & 0x7fffff;
    if (e == 0xff)
        return (uint16_t)(s | 0x7c00 | (m ? 0x200 | (m >> 13) : 0));
    int ee = (int)e - 127 + 15;
    if (ee >= 31)
        return (uint16_t)(s | 0x7c00);
    if (ee <= 0) {
        if (ee < -10)
            return (uint16_t)s;
        m |= 0x800000;
        int shift = 14 - ee;
        uint32_t hm = m >> shift, rem = m & ((1u << shift) - 1), half = 1u << (shift - 1);
        if (rem > half || (rem == half && (hm & 1)))
            hm++;
        return (uint16_t)(s | hm);
    }
    uint32_t hm = m >> 13, rem = m & 0x1fff;
    uint32_t h = s | ((uint32_t)ee << 10) | hm;
    if (rem > 0x1000 || (rem == 0x1000 && (hm & 1)))
        h++;   /* may carry into the exponent: right */
    return (uint16_t)h;
}

/* ------------------------------------------------------------ codecs */

/* OpenEXR's RLE (ImfRle.cpp): a run of 3..128 equal bytes as (n - 1, byte),
 * else up to 127 literal bytes as (-n, bytes). */
static size_t rle_compress(const uint8_t *in, size_t n, uint8_t *out)
{
    const uint8_t *end = in + n, *rs = in, *re = in + 1;
    uint8_t *w = out;
    while (rs < end) {
        while (re < end && *rs == *re && re - rs - 1 < 127)
            ++re;
        if (re - rs >= 3) {
            *w++ = (uint8_t)((re - rs) - 1);
            *w++ = *rs;
            rs = re;
        } else {
            while (re < end && ((re + 1 >= end || *re != *(re + 1)) ||
                                (re + 2 >= end || *(re + 1) != *(re + 2))) &&
                   re - rs < 127)
                ++re;
            *w++ = (uint8_t)(-(int)(re - rs));
            while (rs < re)
                *w++ = *rs++;
        }
        ++re;
    }
    return (size_t)(w - out);
}

static int rle_uncompress(const uint8_t *in, size_t n, uint8_t *out, size_t out_n)
{
    size_t o = 0, i = 0;
    while (i < n) {
        int8_t c = (int8_t)in[i++];
        if (c < 0) {
            size_t k = (size_t)(-(int)c);
            if (i + k > n || o + k > out_n)
                return -1;
            memcpy(out + o, in + i, k);
            o += k;
            i += k;
        } else {
            size_t k = (size_t)c + 1;
            if (i >= n || o + k > out_n)
                return -1;
            memset(out + o, in[i++], k);
            o += k;
        }
    }
    return o == out_n ? 0 : -1;
}

int fp_deep_compression_ok(int c)
{
    return c == EXR_COMPRESSION_NONE || c == EXR_COMPRESSION_RLE || c == EXR_COMPRESSION_ZIPS;
}

/* Unpack one block of raw_n bytes stored in `packed` (n bytes). */
static int block_uncompress(int comp, struct libdeflate_decompressor **dec, const uint8_t *packed,
                            size_t n, uint8_t *raw, size_t raw_n)
{
    if (n == raw_n) {
        memcpy(raw, packed, n);
        return 0;
    }
    if (raw_n == 0 || comp == EXR_COMPRESSION_NONE)
        return -1;
    uint8_t *tmp = malloc(raw_n);
    int rc = -1;
    if (!tmp)
        return -1;
    if (comp == EXR_COMPRESSION_RLE) {
        rc = rle_uncompress(packed, n, tmp, raw_n);
    } else if (comp == EXR_COMPRESSION_ZIPS) {
        if (!*dec)
            *dec = libdeflate_alloc_decompressor();
        rc = *dec && libdeflate_zlib_decompress(*dec, packed, n, tmp, raw_n, NULL) ==
                         LIBDEFLATE_SUCCESS ? 0 : -1;
    }
    if (rc == 0)
        fp_zip_reconstruct(raw, tmp, raw_n);
    free(tmp);
    return rc;
}

/* Pack raw (n bytes) into *out (malloc'd, *out_n bytes). */
static int block_compress(int comp, struct libdeflate_compressor **cmp, const uint8_t *raw,
                          size_t n, uint8_t **out, size_t *out_n)
{
    size_t cap = n + n / 64 + 64;
    if (comp == EXR_COMPRESSION_ZIPS) {
        if (!*cmp)
            *cmp = libdeflate_alloc_compressor(4);
        if (!*cmp)
            return -1;
        size_t b = libdeflate_zlib_compress_bound(*cmp, n);
        if (b > cap)
            cap = b;
    }
    uint8_t *o = malloc(cap ? cap : 1), *tmp = NULL;
    if (!o)
        return -1;
    size_t c = n;
    if (comp != EXR_COMPRESSION_NONE && n > 0) {
        if (!(tmp = malloc(n))) {
            free(o);
            return -1;
        }
        fp_zip_deconstruct(tmp, raw, n);
        c = comp == EXR_COMPRESSION_RLE ? rle_compress(tmp, n, o)
                                        : libdeflate_zlib_compress(*cmp, tmp, n, o, cap);
        if (c == 0)
            c = n;
    }
    if (c >= n) {
        memcpy(o, raw, n);
        c = n;
    }
    free(tmp);
    *out = o;
    *out_n = c;
    return 0;
}

/* ------------------------------------------------------------ images */

int fp_exr_is_deep(const void *buf, size_t size)
{
    const uint8_t *b = buf;
    /* the version field's "non-image" bit: the file holds deep data */
    return size >= 8 && fp_exr_rd_u32(b) == FP_EXR_MAGIC && (fp_exr_rd_u32(b + 4) & 0x800);
}

static void find_roles(fp_deep_image_t *d)
{
    static const char *const names[FP_DCH_COUNT] = { "R", "G", "B", "A", "Z", "ZBack" };
    for (int r = 0; r < FP_DCH_COUNT; r++) {
        d->role[r] = -1;
        for (int c = 0; c < d->nchan; c++)
            if (strcmp(d->chans[c].name, names[r]) == 0)
                d->role[r] = c;
    }
}

int fp_deep_alloc(const fp_frame_info_t *info, const fp_deep_chan_t *chans, int nchan,
                  fp_deep_image_t **out)
{
    fp_deep_image_t *d = calloc(1, sizeof *d);
    *out = NULL;
    if (!d)
        return FP_ERR;
    d->info = *info;
    d->nchan = nchan;
    d->npix = (size_t)info->width * (size_t)info->height;
    d->chans = calloc((size_t)nchan ? (size_t)nchan : 1, sizeof *d->chans);
    d->data = calloc((size_t)nchan ? (size_t)nchan : 1, sizeof *d->data);
    d->counts = calloc(d->npix ? d->npix : 1, sizeof *d->counts);
    d->offsets = calloc(d->npix + 1, sizeof *d->offsets);
    if (!d->chans || !d->data || !d->counts || !d->offsets) {
        fp_deep_free(d);
        return FP_ERR;
    }
    memcpy(d->chans, chans, (size_t)nchan * sizeof *chans);
    find_roles(d);
    *out = d;
    return FP_OK;
}

int fp_deep_alloc_samples(fp_deep_image_t *d, const uint32_t *counts)
{
    uint64_t t = 0;
    for (size_t i = 0; i < d->npix; i++) {
        d->counts[i] = counts[i];
        d->offsets[i] = t;
        t += counts[i];
    }
    d->offsets[d->npix] = t;
    d->total = t;
    for (int c = 0; c < d->nchan; c++) {
        free(d->data[c]);
        d->data[c] = calloc(t ? t : 1, sizeof(uint32_t));
        if (!d->data[c])
            return FP_ERR;
    }
    return FP_OK;
}

void fp_deep_free(fp_deep_image_t *d)
{
    if (!d)
        return;
    if (d->data)
        for (int c = 0; c < d->nchan; c++)
            free(d->data[c]);
    free(d->data);
    free(d->chans);
    free(d->counts);
    free(d->offsets);
    if (d->src) {
        if (d->src->ctx)
            exr_finish(&d->src->ctx);
        free(d->src->buf);
        free(d->src);
    }
    free(d);
}

static void read_info(exr_context_t ctx, fp_deep_image_t *d, const exr_attr_box2i_t *dw,
                      const exr_attr_box2i_t *disp)
{
    fp_frame_info_t *in = &d->info;
    in->data_x0 = dw->min.x;
    in->data_y0 = dw->min.y;
    in->width = dw->max.x - dw->min.x + 1;
    in->height = dw->max.y - dw->min.y + 1;
    in->disp_x0 = disp->min.x;
    in->disp_y0 = disp->min.y;
    in->disp_w = disp->max.x - disp->min.x + 1;
    in->disp_h = disp->max.y - disp->min.y + 1;
    in->pixel_aspect = 1.0f;
    exr_get_pixel_aspect_ratio(ctx, 0, &in->pixel_aspect);
    in->num_parts = 1;
    int32_t na = 0;
    exr_get_attribute_count(ctx, 0, &na);
    for (int32_t i = 0; i < na; i++) {
        const exr_attribute_t *a = NULL;
        if (exr_get_attribute_by_index(ctx, 0, EXR_ATTR_LIST_FILE_ORDER, i, &a) ||
            !a)
            continue;
        int cam = strcmp(a->name, "worldToCamera") == 0, ndc = strcmp(a->name, "worldToNDC") == 0;
        if ((cam || ndc) && (a->type == EXR_ATTR_M44F || a->type == EXR_ATTR_M44D)) {
            double *m = cam ? in->world_to_camera : in->world_to_ndc;
            for (int k = 0; k < 16; k++)
                m[k] = a->type == EXR_ATTR_M44F ? a->m44f->m[k] : a->m44d->m[k];
            *(cam ? &in->has_world_to_camera : &in->has_world_to_ndc) = 1;
        } else if (a->type == EXR_ATTR_CHROMATICITIES && strcmp(a->name, "chromaticities") == 0) {
            const exr_attr_chromaticities_t *c = a->chromaticities;
            const float v[8] = { c->red_x, c->red_y, c->green_x, c->green_y,
                                 c->blue_x, c->blue_y, c->white_x, c->white_y };
            memcpy(in->chromaticities, v, sizeof v);
            in->has_chromaticities = 1;
        } else if (a->type == EXR_ATTR_STRING && a->string && a->string->str &&
                   a->string->length > 0 && a->string->length < (int)sizeof in->camera_text) {
            char v[sizeof in->camera_text];
            memcpy(v, a->string->str, (size_t)a->string->length);
            v[a->string->length] = '\0';
            if (!in->camera_text[0] && strstr(v, "fogpipe-camera")) {
                memcpy(in->camera_text, v, (size_t)a->string->length + 1);
                snprintf(in->camera_text_attr, sizeof in->camera_text_attr, "%s", a->name);
            } else if (in->lens_mm == 0 && strcmp(a->name, "Lens") == 0) {
                double mm = strtod(v, NULL);
                if (mm > 0 && mm < 1e6)
                    in->lens_mm = mm;
            }
        }
    }
}

int fp_deep_read_memory(void *buf, size_t size, const char *where_file, long frame,
                        fp_deep_image_t **out)
{
    const char *where = where_file ? where_file : "<input>";
    char lt[512];
    char *saved_msg = fp_exr_tl_msg;
    fp_deep_src_t *src = calloc(1, sizeof *src);
    fp_deep_image_t *d = NULL;
    uint8_t *packed = NULL, *raw = NULL, *table = NULL;
    uint32_t *counts = NULL;
    struct libdeflate_decompressor *dec = NULL;
    int rc = FP_ERR;
    exr_result_t rv;
    *out = NULL;
    if (!src) {
        free(buf);
        return fp_error("%s: frame %ld: out of memory", where, frame);
    }
    src->buf = buf;
    src->size = size;
    src->io.rd = buf;
    src->io.rd_size = size;
    fp_exr_tl_msg = src->io.msg;
    if (!fp_exr_is_deep(buf, size)) {
        fp_error("%s: frame %ld: not a deep EXR file (expected deep scanline data)", where, frame);
        goto fail;
    }
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = fp_exr_lib_error_handler;
    init.user_data = &src->io;
    init.read_fn = fp_exr_mem_read;
    init.size_fn = fp_exr_mem_size;
    const fp_image_limits_t *lim = fp_image_limits();
    int max_dim = lim->max_dim < INT32_MAX ? (int)lim->max_dim : INT32_MAX;
    init.max_image_width = init.max_image_height = max_dim;
    init.max_tile_width = init.max_tile_height = max_dim;
    init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION | EXR_CONTEXT_FLAG_STRICT_HEADER;
    if ((rv = exr_start_read(&src->ctx, where, &init)) != EXR_ERR_SUCCESS) {
        src->ctx = NULL;
        fp_error("%s: frame %ld: cannot read deep EXR header (%s)", where, frame,
                 fp_exr_lib_text(&src->io, rv, lt, sizeof lt));
        goto fail;
    }
    exr_context_t ctx = src->ctx;
    int nparts = 0;
    exr_storage_t st = EXR_STORAGE_SCANLINE;
    exr_get_count(ctx, &nparts);
    exr_get_storage(ctx, 0, &st);
    if (nparts != 1 || st != EXR_STORAGE_DEEP_SCANLINE) {
        fp_error("%s: frame %ld: deep input must be one deep scanline part (found %d part%s, "
                 "the first %s)", where, frame, nparts, nparts == 1 ? "" : "s",
                 st == EXR_STORAGE_DEEP_TILED ? "deep tiled" : "not deep scanline");
        goto fail;
    }
    exr_attr_box2i_t dw, disp;
    exr_compression_t comp = EXR_COMPRESSION_NONE;
    const exr_attr_chlist_t *cl = NULL;
    if (exr_get_data_window(ctx, 0, &dw) || exr_get_display_window(ctx, 0, &disp) ||
        exr_get_compression(ctx, 0, &comp) || exr_get_channels(ctx, 0, &cl) || !cl) {
        fp_error("%s: frame %ld: deep EXR header lacks its windows, compression or channels",
                 where, frame);
        goto fail;
    }
    if (!fp_deep_compression_ok(comp)) {
        fp_error("%s: frame %ld: deep data compressed with %s (expected none, rle or zips, "
                 "the codecs OpenEXR allows for deep data)", where, frame,
                 fp_exr_compression_name(comp));
        goto fail;
    }
    int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
    if (w < 1 || h < 1) {
        fp_error("%s: frame %ld: empty data window", where, frame);
        goto fail;
    }
    if (fp_image_limits_check(where, frame, "deep data window", w, h, cl->num_channels, 4))
        goto fail;
    fp_deep_chan_t *chans = calloc((size_t)cl->num_channels + 1, sizeof *chans);
    if (!chans)
        goto oom;
    for (int c = 0; c < cl->num_channels; c++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[c];
        if (e->x_sampling != 1 || e->y_sampling != 1) {
            free(chans);
            fp_error("%s: frame %ld: deep channel %s is sub-sampled (expected 1x1)", where,
                     frame, e->name.str);
            goto fail;
        }
        snprintf(chans[c].name, sizeof chans[c].name, "%s", e->name.str);
        chans[c].type = e->pixel_type;
    }
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = (int)w;
    info.height = (int)h;
    int rca = fp_deep_alloc(&info, chans, cl->num_channels, &d);
    free(chans);
    if (rca)
        goto oom;
    read_info(ctx, d, &dw, &disp);
    d->info.compression = comp;
    d->info.has_alpha = d->role[FP_DCH_A] >= 0;
    src->io.msg[0] = '\0';
    if (d->role[FP_DCH_R] < 0 || d->role[FP_DCH_G] < 0 || d->role[FP_DCH_B] < 0 ||
        d->role[FP_DCH_Z] < 0) {
        fp_error("%s: frame %ld: deep input needs channels R, G, B and Z (A and ZBack "
                 "optional)", where, frame);
        goto fail;
    }
    for (int r = 0; r < FP_DCH_COUNT; r++)
        if (d->role[r] >= 0 && d->chans[d->role[r]].type == EXR_PIXEL_UINT) {
            fp_error("%s: frame %ld: deep channel %s is UINT (expected HALF or FLOAT)", where,
                     frame, d->chans[d->role[r]].name);
            goto fail;
        }
    size_t bps = 0;   /* bytes of one sample, all channels */
    for (int c = 0; c < d->nchan; c++)
        bps += d->chans[c].type == EXR_PIXEL_HALF ? 2 : 4;
    counts = calloc(d->npix, sizeof *counts);
    table = malloc((size_t)w * 4);
    if (!counts || !table)
        goto oom;

    /* Pass 1: the sample count tables, checked, and the total against the
     * budget before any sample is held. */
    uint64_t total = 0;
    for (int64_t y = 0; y < h; y++) {
        exr_chunk_info_t ci;
        int yy = (int)(dw.min.y + y);
        if ((rv = exr_read_scanline_chunk_info(ctx, 0, yy, &ci)) != EXR_ERR_SUCCESS)
            goto lib_fail_line;
        if (ci.sample_count_table_size > (uint64_t)w * 4 || ci.packed_size > size ||
            ci.unpacked_size > (uint64_t)1 << 40) {
            fp_error("%s: frame %ld: deep line %d: chunk sizes beyond the file (table %llu, "
                     "data %llu bytes)", where, frame, yy,
                     (unsigned long long)ci.sample_count_table_size,
                     (unsigned long long)ci.packed_size);
            goto fail;
        }
        free(packed);
        packed = malloc(ci.sample_count_table_size ? ci.sample_count_table_size : 1);
        if (!packed)
            goto oom;
        if ((rv = exr_read_deep_chunk(ctx, 0, &ci, NULL, packed)) != EXR_ERR_SUCCESS)
            goto lib_fail_line;
        if (block_uncompress(comp, &dec, packed, ci.sample_count_table_size, table,
                             (size_t)w * 4)) {
            fp_error("%s: frame %ld: deep line %d: corrupt sample count table", where, frame,
                     yy);
            goto fail;
        }
        uint32_t prev = 0;
        for (int64_t x = 0; x < w; x++) {
            uint32_t cum = fp_exr_rd_u32(table + 4 * x);
            if (cum < prev || (int32_t)cum < 0 || cum - prev > FP_DEEP_MAX_PIXEL_SAMPLES) {
                fp_error("%s: frame %ld: deep line %d: sample count table not increasing or "
                         "beyond %d samples a pixel at x %lld", where, frame, yy,
                         FP_DEEP_MAX_PIXEL_SAMPLES, (long long)(dw.min.x + x));
                goto fail;
            }
            counts[y * w + x] = cum - prev;
            prev = cum;
        }
        if ((uint64_t)prev * bps != ci.unpacked_size) {
            fp_error("%s: frame %ld: deep line %d: %u samples of %zu bytes but %llu bytes of "
                     "data", where, frame, yy, prev, bps, (unsigned long long)ci.unpacked_size);
            goto fail;
        }
        total += prev;
        if (total > (uint64_t)lim->max_pixels) {
            fp_error("%s: frame %ld: deep image holds more than %lld samples (the image "
                     "budget; --max-image-pixels raises it)", where, frame,
                     (long long)lim->max_pixels);
            goto fail;
        }
    }
    if (fp_deep_alloc_samples(d, counts))
        goto oom;

    /* Pass 2: the samples. */
    for (int64_t y = 0; y < h; y++) {
        exr_chunk_info_t ci;
        int yy = (int)(dw.min.y + y);
        if ((rv = exr_read_scanline_chunk_info(ctx, 0, yy, &ci)) != EXR_ERR_SUCCESS)
            goto lib_fail_line;
        free(packed);
        free(raw);
        packed = malloc(ci.packed_size ? ci.packed_size : 1);
        raw = malloc(ci.unpacked_size ? ci.unpacked_size : 1);
        if (!packed || !raw)
            goto oom;
        if ((rv = exr_read_deep_chunk(ctx, 0, &ci, packed, NULL)) != EXR_ERR_SUCCESS)
            goto lib_fail_line;
        if (block_uncompress(comp, &dec, packed, ci.packed_size, raw, ci.unpacked_size)) {
            fp_error("%s: frame %ld: deep line %d: corrupt sample data", where, frame, yy);
            goto fail;
        }
        uint64_t first = d->offsets[y * w], nline = d->offsets[(y + 1) * w] - first;
        const uint8_t *p = raw;
        for (int c = 0; c < d->nchan; c++) {
            uint32_t *dst = d->data[c] + first;
            if (d->chans[c].type == EXR_PIXEL_HALF) {
                for (uint64_t k = 0; k < nline; k++, p += 2) {
                    float v = half_to_float((uint16_t)(p[0] | p[1] << 8));
                    memcpy(&dst[k], &v, 4);
                }
            } else {
                for (uint64_t k = 0; k < nline; k++, p += 4)
                    dst[k] = fp_exr_rd_u32(p);
            }
        }
    }
    d->src = src;
    src = NULL;
    *out = d;
    d = NULL;
    rc = FP_OK;
    goto fail;
lib_fail_line:
    fp_error("%s: frame %ld: cannot read deep chunk (%s)", where, frame,
             fp_exr_lib_text(&src->io, rv, lt, sizeof lt));
    goto fail;
oom:
    fp_error("%s: frame %ld: out of memory", where, frame);
fail:
    fp_exr_tl_msg = saved_msg;
    libdeflate_free_decompressor(dec);
    free(packed);
    free(raw);
    free(table);
    free(counts);
    fp_deep_free(d);
    if (src) {
        if (src->ctx)
            exr_finish(&src->ctx);
        free(src->buf);
        free(src);
    }
    return rc;
}

int fp_deep_plate_pass(const fp_frame_t *f, fp_deep_pass_t **out, int *n)
{
    *out = NULL;
    *n = 0;
    int p = f->main_part;
    if (p < 0 || p >= f->num_parts)
        return FP_OK;
    const fp_part_t *pt = &f->parts[p];
    fp_deep_pass_t *v = calloc((size_t)pt->num_chans + 1, sizeof *v);
    if (!v)
        return FP_ERR;
    int k = 0;
    for (int c = 0; c < pt->num_chans; c++) {
        const fp_chan_t *ch = &pt->chans[c];
        int skip = !ch->raw || ch->xs != 1 || ch->ys != 1 ||
                   (size_t)ch->w * (size_t)ch->h != (size_t)f->info.width * f->info.height ||
                   (p == f->depth_part && c == f->depth_chan);
        for (int r = 0; r < 4; r++)
            skip |= p == f->color_part && c == f->color_chan[r];
        static const char *const taken[] = { "R", "G", "B", "A", "Z", "ZBack" };
        for (size_t r = 0; r < FP_ARRAY_LEN(taken); r++)
            skip |= strcmp(ch->name, taken[r]) == 0;
        if (skip)
            continue;
        snprintf(v[k].chan.name, sizeof v[k].chan.name, "%s", ch->name);
        v[k].chan.type = ch->type;
        v[k].raw = ch->raw;
        v[k].bpe = (int)ch->bpe;
        k++;
    }
    if (k == 0) {
        free(v);
        return FP_OK;
    }
    *out = v;
    *n = k;
    return FP_OK;
}

uint32_t fp_deep_pass_value(const fp_deep_pass_t *p, size_t k)
{
    const uint8_t *b = p->raw + k * (size_t)p->bpe;
    if (p->bpe == 2) {
        uint16_t h;
        memcpy(&h, b, 2);
        float f = half_to_float(h);
        uint32_t u;
        memcpy(&u, &f, 4);
        return u;
    }
    uint32_t u;
    memcpy(&u, b, 4);
    return u;
}

/* ------------------------------------------------------------ writing */

int fp_deep_encode(const fp_deep_image_t *d, const fp_frame_t *plate,
                   const fp_exr_write_opts_t *opts, const char *where_file, long frame,
                   void **out, size_t *out_size)
{
    const char *where = where_file ? where_file : "<output>";
    char lt[512];
    char *saved_msg = fp_exr_tl_msg;
    fp_exr_io_t io;
    exr_context_t o = NULL;
    exr_result_t rv = EXR_ERR_SUCCESS;
    int rc = FP_ERR;
    struct libdeflate_compressor *cmp = NULL;
    uint8_t *table = NULL, *raw = NULL, *ptab = NULL, *pdat = NULL;
    int *otype = NULL, *order = NULL;
    memset(&io, 0, sizeof io);
    fp_exr_tl_msg = io.msg;
    *out = NULL;
    *out_size = 0;

    int comp = opts && opts->compression >= 0 ? opts->compression : -1;
    if (comp < 0)
        comp = fp_deep_compression_ok(d->info.compression) ? d->info.compression
                                                            : EXR_COMPRESSION_ZIPS;
    if (!fp_deep_compression_ok(comp)) {
        fp_error("%s: frame %ld: deep output cannot be compressed with %s (deep files allow "
                 "none, rle and zips)", where, frame, fp_exr_compression_name(comp));
        goto done;
    }
    otype = calloc((size_t)d->nchan + 1, sizeof *otype);
    if (!otype)
        goto oom;
    for (int c = 0; c < d->nchan; c++) {
        otype[c] = d->chans[c].type;
        int is_color = 0;
        for (int r = FP_DCH_R; r <= FP_DCH_A; r++)
            is_color |= d->role[r] == c;
        /* FLOAT whatever --float says: a flattened pixel sums every
         * sample's rounding, and half's (2^-11 of each) would be above the
         * bound of the fog's samples */
        if (is_color)
            otype[c] = EXR_PIXEL_FLOAT;
        if (c == d->role[FP_DCH_Z] || c == d->role[FP_DCH_ZBACK])
            otype[c] = EXR_PIXEL_FLOAT;
    }
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = fp_exr_lib_error_handler;
    init.user_data = &io;
    init.write_fn = fp_exr_mem_write;
    init.alloc_fn = fp_exr_alloc;
    init.free_fn = fp_exr_free;
    if ((rv = exr_start_write(&o, where, EXR_WRITE_FILE_DIRECTLY, &init)) != EXR_ERR_SUCCESS) {
        o = NULL;
        goto lib_fail;
    }
    rv = exr_set_longname_support(o, 1);
    int idx = -1;
    exr_attr_box2i_t dw, disp;
    dw.min.x = d->info.data_x0;
    dw.min.y = d->info.data_y0;
    dw.max.x = d->info.data_x0 + d->info.width - 1;
    dw.max.y = d->info.data_y0 + d->info.height - 1;
    disp.min.x = d->info.disp_x0;
    disp.min.y = d->info.disp_y0;
    disp.max.x = d->info.disp_x0 + d->info.disp_w - 1;
    disp.max.y = d->info.disp_y0 + d->info.disp_h - 1;
    exr_attr_v2f_t swc = { { { 0.0f, 0.0f } } };
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_add_part(o, NULL, EXR_STORAGE_DEEP_SCANLINE, &idx);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr(o, idx, &disp, &dw, d->info.pixel_aspect > 0
                                                                   ? d->info.pixel_aspect
                                                                   : 1.0f,
                                          &swc, 1.0f, EXR_LINEORDER_INCREASING_Y,
                                          (exr_compression_t)comp);
    for (int c = 0; c < d->nchan && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(o, idx, d->chans[c].name, (exr_pixel_type_t)otype[c],
                             EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    /* the header's attributes: the plate's main part, else the deep input's */
    exr_const_context_t hctx = plate ? plate->ctx : d->src ? d->src->ctx : NULL;
    int hpart = plate ? plate->main_part : 0;
    int32_t na = 0;
    if (rv == EXR_ERR_SUCCESS && hctx && exr_get_attribute_count(hctx, hpart, &na))
        na = 0;
    int set_chr = opts ? opts->set_chromaticities : 0;
    for (int32_t i = 0; i < na && rv == EXR_ERR_SUCCESS; i++) {
        const exr_attribute_t *a = NULL;
        if (exr_get_attribute_by_index(hctx, hpart, EXR_ATTR_LIST_FILE_ORDER, i, &a) || !a)
            continue;
        if (fp_exr_is_structural_attr(a->name) || strcmp(a->name, "maxSamplesPerPixel") == 0 ||
            strcmp(a->name, "dwaCompressionLevel") == 0 ||
            (set_chr && strcmp(a->name, "chromaticities") == 0))
            continue;
        rv = fp_exr_copy_attr(o, idx, a);
    }
    if (rv == EXR_ERR_SUCCESS && set_chr > 0) {
        const float *c = opts->chromaticities;
        exr_attr_chromaticities_t chr = { c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7] };
        rv = exr_attr_set_chromaticities(o, idx, "chromaticities", &chr);
    }
    io.msg[0] = '\0';
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_write_header(o);
    if (rv != EXR_ERR_SUCCESS)
        goto lib_fail;
    /* the library keeps the channel list sorted by name: the data go in
     * its order */
    const exr_attr_chlist_t *cl = NULL;
    if ((rv = exr_get_channels(o, idx, &cl)) != EXR_ERR_SUCCESS || !cl)
        goto lib_fail;
    order = calloc((size_t)d->nchan + 1, sizeof *order);
    if (!order)
        goto oom;
    for (int e = 0; e < cl->num_channels && e < d->nchan; e++)
        for (int c = 0; c < d->nchan; c++)
            if (strcmp(cl->entries[e].name.str, d->chans[c].name) == 0)
                order[e] = c;

    size_t w = (size_t)d->info.width, bps = 0;
    for (int c = 0; c < d->nchan; c++)
        bps += otype[c] == EXR_PIXEL_HALF ? 2 : 4;
    table = malloc(w * 4 + 4);
    if (!table)
        goto oom;
    for (int y = 0; y < d->info.height; y++) {
        size_t p0 = (size_t)y * w;
        uint64_t first = d->offsets[p0], n = d->offsets[p0 + w] - first;
        uint32_t cum = 0;
        for (size_t x = 0; x < w; x++) {
            cum += d->counts[p0 + x];
            table[4 * x] = (uint8_t)cum;
            table[4 * x + 1] = (uint8_t)(cum >> 8);
            table[4 * x + 2] = (uint8_t)(cum >> 16);
            table[4 * x + 3] = (uint8_t)(cum >> 24);
        }
        free(raw);
        raw = malloc(n * bps + 1);
        if (!raw)
            goto oom;
        uint8_t *p = raw;
        for (int e = 0; e < d->nchan; e++) {
            int c = order[e];
            const uint32_t *src = d->data[c] + first;
            for (uint64_t k = 0; k < n; k++) {
                uint32_t v = src[k];
                if (otype[c] == EXR_PIXEL_HALF) {
                    float f;
                    memcpy(&f, &v, 4);
                    uint16_t hv = float_to_half(f);
                    *p++ = (uint8_t)hv;
                    *p++ = (uint8_t)(hv >> 8);
                } else {
                    if (otype[c] == EXR_PIXEL_UINT && d->chans[c].type != EXR_PIXEL_UINT) {
                        float f;
                        memcpy(&f, &v, 4);
                        v = f > 0 ? (uint32_t)f : 0;
                    }
                    *p++ = (uint8_t)v;
                    *p++ = (uint8_t)(v >> 8);
                    *p++ = (uint8_t)(v >> 16);
                    *p++ = (uint8_t)(v >> 24);
                }
            }
        }
        size_t ntab = 0, ndat = 0;
        free(ptab);
        free(pdat);
        ptab = pdat = NULL;
        if (block_compress(comp, &cmp, table, w * 4, &ptab, &ntab) ||
            block_compress(comp, &cmp, raw, n * bps, &pdat, &ndat))
            goto oom;
        rv = exr_write_deep_scanline_chunk(o, idx, d->info.data_y0 + y, pdat, ndat, n * bps,
                                           ptab, ntab);
        if (rv != EXR_ERR_SUCCESS)
            goto lib_fail;
    }
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
    fp_error("%s: frame %ld: cannot write deep EXR (%s)", where, frame,
             fp_exr_lib_text(&io, rv, lt, sizeof lt));
done:
    if (o)
        exr_finish(&o);
    fp_exr_tl_msg = saved_msg;
    libdeflate_free_compressor(cmp);
    free(table);
    free(raw);
    free(ptab);
    free(pdat);
    free(otype);
    free(order);
    free(io.wr);
    return rc;
}
