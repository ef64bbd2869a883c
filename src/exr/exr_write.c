/* fogpipe: writing EXR frames (exrio.h): a new context whose write
 * callback (fp_exr_mem_write) fills a growable buffer, so one encoder
 * serves files and stdout alike; every part, attribute and pass-through
 * channel of the input kept, colour from the frame's floats; chunks
 * encoded by the chunk workers and written in order.  Files are written
 * atomically (temporary + rename). */
#include "exr_dwa.h"
#include "exr_internal.h"
#include "fp.h"

#include <errno.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* What a channel is to the encoder: passed through, or colour R..A. */
enum { ROLE_PASS = 0, ROLE_R, ROLE_G, ROLE_B, ROLE_A };

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
int fp_exr_is_structural_attr(const char *name)
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

exr_result_t fp_exr_copy_attr(exr_context_t o, int op, const exr_attribute_t *a)
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

/* Whether any attribute name, attribute type name or channel name of the
 * output's `nparts` parts is longer than OpenEXR's short limit (31). */
static int needs_long_names(exr_context_t o, int nparts)
{
    for (int p = 0; p < nparts; ++p) {
        int32_t na = 0;
        if (exr_get_attribute_count(o, p, &na) != EXR_ERR_SUCCESS)
            return 1;
        for (int32_t i = 0; i < na; ++i) {
            const exr_attribute_t *a = NULL;
            if (exr_get_attribute_by_index(o, p, EXR_ATTR_LIST_FILE_ORDER, i, &a) !=
                    EXR_ERR_SUCCESS || !a)
                return 1;
            if (a->name_length > FP_EXR_SHORT_NAME || a->type_name_length > FP_EXR_SHORT_NAME)
                return 1;
            if (a->type == EXR_ATTR_CHLIST)
                for (int c = 0; c < a->chlist->num_channels; ++c)
                    if (a->chlist->entries[c].name.length > FP_EXR_SHORT_NAME)
                        return 1;
        }
    }
    return 0;
}

/* The chunks of one output part, packed and compressed by workers that
 * each claim the next chunk and run their own pipeline, each keeping its
 * chunk's bytes; the calling thread then writes them in chunk order (the
 * order the library requires), so the file is the same bytes whatever the
 * number of workers.  Once the header is written the library no longer
 * changes the context while it encodes. */
typedef struct enc_job_t {
    exr_context_t o;
    int idx;
    const out_part_t *op;
    const exr_attr_box2i_t *dw;
    const exr_chunk_info_t *ci;
    uint8_t **data;              /* each chunk's bytes, as written */
    uint64_t *size;
    int64_t n;
    atomic_llong next;
    atomic_int stop;
} enc_job_t;

static exr_result_t encode_chunk(enc_job_t *j, exr_encode_pipeline_t *enc,
                                 fp_zip_t *zip, int *inited, int *map, int64_t k)
{
    const out_part_t *op = j->op;
    const exr_chunk_info_t *ci = &j->ci[k];
    exr_result_t rv = *inited ? exr_encoding_update(j->o, j->idx, ci, enc)
                              : exr_encoding_initialize(j->o, j->idx, ci, enc);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    for (int c = 0; c < enc->channel_count; ++c) {
        exr_coding_channel_info_t *cc = &enc->channels[c];
        if (!*inited) {
            map[c] = -1;
            for (int i = 0; i < op->num; ++i)
                if (strcmp(op->ch[i].name, cc->channel_name) == 0)
                    map[c] = i;
        }
        if (map[c] < 0)
            return EXR_ERR_INVALID_ARGUMENT;
        const out_chan_t *oc = &op->ch[map[c]];
        int64_t row = sampled_count(j->dw->min.y, ci->start_y, oc->ys);
        cc->encode_from_ptr = oc->base + (size_t) row * oc->line_stride;
        cc->user_pixel_stride = oc->pixel_stride;
        cc->user_line_stride = (int32_t) oc->line_stride;
        cc->user_bytes_per_element = (int16_t) oc->user_bpe;
        cc->user_data_type = (uint16_t) oc->user_type;
    }
    if (!*inited) {
        rv = exr_encoding_choose_default_routines(j->o, j->idx, enc);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
        /* kept here and written in order by the caller */
        enc->yield_until_ready_fn = NULL;
        enc->write_fn = NULL;
        exr_compression_t comp = EXR_COMPRESSION_NONE;
        rv = exr_get_compression(j->o, j->idx, &comp);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
        if (fp_zip_enabled() && fp_zip_is_zip(comp))
            fp_zip_use_encoder(enc, zip); /* libdeflate for OpenEXR's zlib */
        *inited = 1;
    }
    rv = exr_encoding_run(j->o, j->idx, enc);
    if (rv != EXR_ERR_SUCCESS)
        return rv;
    j->size[k] = enc->compressed_bytes;
    j->data[k] = malloc(enc->compressed_bytes ? (size_t) enc->compressed_bytes : 1);
    if (!j->data[k])
        return EXR_ERR_OUT_OF_MEMORY;
    memcpy(j->data[k], enc->compressed_buffer, (size_t) enc->compressed_bytes);
    return EXR_ERR_SUCCESS;
}

static void *enc_work(void *arg)
{
    fp_exr_worker_t *w = arg;
    enc_job_t *j = w->job;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    fp_zip_t zip = { 0 };
    int inited = 0;
    int *map = malloc((size_t) (j->op->num > 0 ? j->op->num : 1) * sizeof *map);
    char *saved = fp_exr_tl_msg;
    fp_exr_tl_msg = w->msg;
    for (;;) {
        int64_t k = atomic_fetch_add(&j->next, 1);
        if (k >= j->n || atomic_load(&j->stop))
            break;
        exr_result_t rv = map ? encode_chunk(j, &enc, &zip, &inited, map, k)
                              : EXR_ERR_OUT_OF_MEMORY;
        if (rv != EXR_ERR_SUCCESS) {
            w->fail = k;
            w->rv = rv;
            atomic_store(&j->stop, 1);
            break;
        }
    }
    if (inited || enc.channels)
        exr_encoding_destroy(j->o, &enc);
    fp_zip_release(&zip);
    free(map);
    fp_exr_tl_msg = saved;
    return NULL;
}

static int encode_part(exr_context_t o, int idx, const out_part_t *op,
                       const exr_attr_box2i_t *dw, fp_exr_io_t *io,
                       const char *where, long frame)
{
    char lt[512];
    int rc = FP_ERR;
    int32_t lpc = 0;
    int64_t y = dw->min.y, n = 0;
    const char *why = NULL;
    exr_chunk_info_t *ci = NULL;
    uint8_t **data = NULL;
    uint64_t *size = NULL;
    fp_exr_worker_t *wk = NULL;
    int64_t w = (int64_t) dw->max.x - dw->min.x + 1;
    int64_t h = (int64_t) dw->max.y - dw->min.y + 1;
    exr_result_t rv = exr_get_scanlines_per_chunk(o, idx, &lpc);
    if (rv != EXR_ERR_SUCCESS)
        goto fail;
    n = (h + lpc - 1) / lpc;
    ci = malloc((size_t) n * sizeof *ci);
    data = calloc((size_t) n, sizeof *data);
    size = calloc((size_t) n, sizeof *size);
    int nw = fp_exr_workers(w * h, n);
    wk = calloc((size_t) nw, sizeof *wk);
    if (!ci || !data || !size || !wk) {
        rv = EXR_ERR_OUT_OF_MEMORY;
        goto fail;
    }
    /* Chunks in increasing order, as the part's line order says. */
    for (int64_t k = 0; k < n; ++k) {
        y = dw->min.y + k * lpc;
        rv = exr_write_scanline_chunk_info(o, idx, (int) y, &ci[k]);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
    }
    enc_job_t job = { o, idx, op, dw, ci, data, size, n, 0, 0 };
    const fp_exr_worker_t *first = fp_exr_run_workers(enc_work, &job, wk, nw);
    if (first) {
        y = dw->min.y + first->fail * lpc;
        rv = first->rv;
        why = first->msg;
        goto fail;
    }
    for (int64_t k = 0; k < n; ++k) {
        y = dw->min.y + k * lpc;
        rv = exr_write_scanline_chunk(o, idx, (int) y, data[k], size[k]);
        if (rv != EXR_ERR_SUCCESS)
            goto fail;
    }
    rc = FP_OK;
    goto done;
fail:
    fp_exr_fail_text(io, why, rv, lt, sizeof lt);
    fp_error("%s: frame %ld: cannot encode part %d at line %lld (%s%s)", where,
             frame, idx, (long long) y, lt,
             rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED
                 ? "; this OpenEXR C library cannot write it: choose another compression"
                 : "");
done:
    if (data)
        for (int64_t k = 0; k < n; ++k)
            free(data[k]);
    free(data);
    free(size);
    free(ci);
    free(wk);
    return rc;
}

int fp_exr_encode(const fp_frame_t *f, const float *rgba,
                  const fp_exr_write_opts_t *opts, const char *where_file,
                  long frame, void **out, size_t *out_size)
{
    static const fp_exr_write_opts_t defaults = FP_EXR_WRITE_OPTS_INITIALIZER;
    static const char *const rgba_names[4] = { "R", "G", "B", "A" };
    char lt[512];
    char *saved_msg = fp_exr_tl_msg;
    const char *where = where_file ? where_file : "<output>";
    fp_exr_io_t io;
    exr_context_t o = NULL;
    out_part_t *ops = NULL;
    int *out_idx = NULL;
    int *out_comp = NULL;  /* each output part's compression */
    int any_dwa = 0;
    int rc = FP_ERR;
    exr_result_t rv;

    memset(&io, 0, sizeof io);
    fp_exr_tl_msg = io.msg;
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
    out_comp = calloc((size_t) f->num_parts, sizeof *out_comp);
    if (!ops || !out_idx || !out_comp)
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
    init.error_handler_fn = fp_exr_lib_error_handler;
    init.user_data = &io;
    init.write_fn = fp_exr_mem_write;
    init.alloc_fn = fp_exr_alloc; /* an empty opaque attribute leaks otherwise */
    init.free_fn = fp_exr_free;
    rv = exr_start_write(&o, where, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv != EXR_ERR_SUCCESS) {
        o = NULL;
        goto lib_fail;
    }
    /* Names of up to 255 characters (Cycles writes attributes such as
     * cycles.ViewLayer.synchronization_time, 37): allowed while the header
     * is built, and turned off again before it is written when every name
     * fits in 31, so that the long-names flag is set only when needed, as
     * OpenEXR's C++ library does. */
    rv = exr_set_longname_support(o, 1);
    if (rv != EXR_ERR_SUCCESS)
        goto lib_fail;
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
        /* Line order is normalized to increasing: it only says in which
         * order the chunks lie in the file, never what the image is, and
         * OpenEXR 3.1's C writer can only lay them out increasing (it
         * refuses any other sequence unless RANDOM_Y).  Declaring
         * decreasing over increasing chunks makes a file that OpenEXR's
         * C++ reader (OpenImageIO) reads past its end. */
        const int lo = EXR_LINEORDER_INCREASING_Y;
        int comp = opts->compression >= 0 ? opts->compression : pt->compression;
        /* DWA parts are encoded uncompressed here, then by exr_dwa.h */
        out_comp[nout] = comp;
        if (comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB) {
            any_dwa = 1;
            comp = EXR_COMPRESSION_NONE;
        }
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
            if (rv == EXR_ERR_SUCCESS && a && a->type != EXR_ATTR_FLOAT &&
                strcmp(a->name, "dwaCompressionLevel") == 0) {
                /* OpenEXR's own float: another type would make the C++
                 * library refuse the header (exr_dwa.h) */
                fp_warn("%s: frame %ld: attribute dwaCompressionLevel is of type %s "
                        "(expected float): not copied", f->src ? f->src : "<input>",
                        frame, a->type_name);
                continue;
            }
            if (rv == EXR_ERR_SUCCESS && a && !fp_exr_is_structural_attr(a->name) &&
                !(p == f->main_part && opts->set_chromaticities &&
                  strcmp(a->name, "chromaticities") == 0))
                rv = fp_exr_copy_attr(o, idx, a);
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
    if (!needs_long_names(o, nout))
        rv = exr_set_longname_support(o, 0);
    if (rv == EXR_ERR_SUCCESS)
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
    if (any_dwa) {
        void *dwa = NULL;
        size_t dwa_size = 0;
        if (fp_dwa_encode(io.wr, io.wr_size, out_comp, nout, opts->dwa_level,
                          where, frame, &dwa, &dwa_size) != FP_OK)
            goto done;
        free(io.wr);
        io.wr = dwa;
        io.wr_size = dwa_size;
    }
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
             fp_exr_lib_text(&io, rv, lt, sizeof lt));
done:
    if (o)
        exr_finish(&o);
    fp_exr_tl_msg = saved_msg;
    if (ops)
        for (int p = 0; p < f->num_parts; ++p)
            free(ops[p].ch);
    free(ops);
    free(out_idx);
    free(out_comp);
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
