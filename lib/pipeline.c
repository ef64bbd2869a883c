#include "pipeline.h"
#include "aov.h"
#include "camera.h"
#include "clrt.h"
#include "color.h"
#include "composite.h"
#include "deep_frame.h"
#include "preview.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "frameloop.h"
#include "integrate.h"
#include "fp_limits.h"
#include "scatter.h"
#include "buffers.h"
#include "reference.h"
#include "options.h"
#include "seq.h"
#include "rig_apply.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct run_t {
    fp_params_t *p;
    /* The frame's parameters (the calling thread's, process_frame): p with
     * the frame's rig applied (src/scene/rig.h); p itself when it has none. */
    fp_params_t *fp;
    fp_params_t fq;                  /* what fp points to with a rig */
    fp_rig_file_t *rigfile;          /* --rig FILE */
    uint64_t light_key;              /* what `light` was committed from (fp_rig_light_key) */
    fp_rig_seen_t light_warned;      /* its commits' warnings, each said once a run */
    int has_rig;                     /* --rig, or the first frame carries a rig */
    fp_exr_select_t sel;
    fp_exr_write_opts_t wopts;
    fp_integrate_data_t fog;
    fp_cl_t *cl;
    fp_integrate_cl_t icl;
    fp_scatter_data_t light;         /* sun, lights, shadows (filters/scatter.h) */
    fp_scatter_cl_t scl;
    fp_reference_cl_t rcl;           /* --integrator reference */
    int reference;
    fp_buffers_cl_t bcl;             /* --blur, --fog-resolution */
    int buffers;
    fp_fogmap_stage_t fogmap;
    int use_cl;
    /* The frame loop (lib/frameloop.h).  The reader and writer threads only
     * read run_t (p, sel, wopts and what follows); fog, cl, icl and fogmap
     * belong to the calling thread, which runs process_frame. */
    const fp_frame_list_t *frames;   /* file input: the frames of the run */
    const unsigned char *skip;       /* file input: frame k's output exists (--skip-existing) */
    const fp_frame_list_t *labels;   /* stream input: numbers from --frames, or NULL */
    int out_seq;                     /* stream input: written to a sequence pattern */
    FILE *out_stream;                /* stdout, or NULL for files */
    double setup_ms;                 /* device, programs, fogmap: for --stats */
    double fogmap_setup_ms;
    pthread_mutex_t pool_mu;         /* fog layers handed back by the writer, reused */
    float *pool[3];
    size_t pool_px[3];
    fp_color_t color;                /* OpenColorIO spaces and processors (thread-safe) */
    fp_preview_t preview;            /* previews written, for the contact sheet (locked) */
    fp_deep_data_t deep;             /* --deep (filters/deep.h) */
    fp_deep_stats_t deep_stats;      /* samples written (calling thread) */
} run_t;

/* One frame between the stages: read_frame (reader thread), process_frame
 * (calling thread), write_frame (writer thread).  What a stage hands on to
 * a later one lives here, never in run_t: frames in flight are at different
 * stages at once. */
typedef struct frame_state_t {
    fp_frame_t *f;
    float *fog;                  /* S.rgb, tau per pixel, fog_px pixels */
    size_t fog_px;
    fp_exr_write_opts_t wopts;   /* this frame's write options (per-frame data points into
                                    this frame, which lives until it is written) */
    fp_color_frame_t color;      /* this frame's color spaces (filters/color.h) */
    fp_aov_frame_t aov;          /* fog layers written with it (filters/aov.h) */
    fp_deep_image_t *din, *dout; /* --deep: a deep input; the deep output */
} frame_state_t;

/* A fog layer of n pixels: one handed back by an earlier frame if any. */
static float *fog_get(run_t *r, size_t n)
{
    float *buf = NULL;
    pthread_mutex_lock(&r->pool_mu);
    for (size_t i = 0; i < FP_ARRAY_LEN(r->pool); i++)
        if (r->pool[i] && r->pool_px[i] == n) {
            buf = r->pool[i];
            r->pool[i] = NULL;
            break;
        }
    pthread_mutex_unlock(&r->pool_mu);
    /* Page-aligned: a device in the host's memory writes the layer into it
     * without a copy (filters/integrate.c). */
    if (!buf && posix_memalign((void **)&buf, 4096, n * 4 * sizeof(float)))
        buf = NULL;
    return buf;
}

static void fog_put(run_t *r, float *buf, size_t n)
{
    if (!buf)
        return;
    pthread_mutex_lock(&r->pool_mu);
    for (size_t i = 0; buf && i < FP_ARRAY_LEN(r->pool); i++)
        if (!r->pool[i]) {
            r->pool[i] = buf;
            r->pool_px[i] = n;
            buf = NULL;
        }
    pthread_mutex_unlock(&r->pool_mu);
    free(buf);
}

static int is_stream(const char *s) { return !s || strcmp(s, "-") == 0; }

/* Stage 1, reader thread: decode a frame's bytes (taking `buf`) and its
 * depth from --depth.  job->in and job->frame are set. */
static int read_frame(run_t *r, fp_loop_job_t *job, void *buf, size_t size)
{
    fp_params_t *p = r->p;
    const char *in_name = job->in;
    long frame = job->frame;
    frame_state_t *fs = calloc(1, sizeof *fs);
    if (!fs) {
        free(buf);
        return fp_error("%s: frame %ld: out of memory", in_name, frame);
    }
    job->data = fs;
    fs->wopts = r->wopts;
    double t0 = fp_now_ms(), t_depth_read = 0;
    int deep_in = fp_exr_is_deep(buf, size);
    if (deep_in && (!r->deep.on || p->io.depth)) {
        free(buf);
        return fp_error("%s: frame %ld: a deep image (%s)", in_name, frame,
                        p->io.depth ? "it carries its own Z: no --depth"
                                    : "use --deep to fog it into deep output");
    }
    int rc = deep_in ? fp_deep_read_memory(buf, size, in_name, frame, &fs->din)
                     : fp_exr_read_memory(buf, size, in_name, frame, &r->sel, &fs->f);
    if (rc == FP_OK && p->io.depth && !deep_in) {
        char dpath[4096];
        fp_exr_select_t dsel = r->sel;
        dsel.need_color = 0;
        dsel.color_layer = NULL;
        void *dbuf = NULL;
        size_t dsize = 0;
        fp_frame_t *df = NULL;
        double t1 = fp_now_ms();
        if ((rc = fp_seq_format(p->io.depth, frame, dpath, sizeof dpath)) == FP_OK &&
            (rc = fp_exr_load_file(dpath, frame, &dbuf, &dsize)) == FP_OK) {
            t_depth_read = fp_now_ms() - t1;
            if ((rc = fp_exr_read_memory(dbuf, dsize, dpath, frame, &dsel, &df)) == FP_OK)
                rc = fp_frame_take_depth(fs->f, in_name, df, dpath, frame);
        }
        if (df)
            fp_frame_free(df);
    }
    job->ms[FP_T_READ] += t_depth_read;
    job->ms[FP_T_DECODE] = fp_now_ms() - t0 - t_depth_read;
    return rc;
}

/* The fog layer of a view (the frame's, or its strided sub-view for
 * --fog-resolution), whole (pix NULL) or at its npix pixels pix[] (into
 * fog[4*k], list order): the Monte Carlo reference, light in the fog, or
 * the extinction with ambient fog alone. */
static int compute_fog(run_t *r, const fp_view_t *view, const float *depth, const int *pix,
                       size_t npix, float *fog)
{
    fp_params_t *p = r->fp;
    size_t n = pix ? npix : (size_t)view->width * view->height;
    if (r->reference)
        return r->use_cl
                   ? fp_reference_pixels_cl(&r->rcl, p, &r->light, &r->fog, view, depth, pix, n, fog)
                   : fp_reference_pixels(p, &r->light, &r->fog, view, depth, pix, n, fog);
    if (r->light.active)
        return r->use_cl ? fp_scatter_pixels_cl(&r->scl, &r->icl, &r->light, &r->fog, view, depth,
                                                pix, n, fog)
                         : fp_scatter_pixels(&r->light, &r->fog, view, depth, pix, n, fog);
    return r->use_cl ? fp_integrate_pixels_cl(&r->icl, &r->fog, view, depth, pix, n, fog)
                     : fp_integrate_pixels(&r->fog, view, depth, pix, n, fog);
}

/* The fog layer of a frame (filters/buffers.h): at full resolution, or
 * (--fog-resolution 1/F) at every F-th pixel each way (a strided view:
 * those pixels' own rays and depths) brought back by joint bilateral
 * upsampling guided by the full-resolution depth, with the depth-edge
 * pixels computed again at full resolution (--fog-edges exact); then the
 * depth-aware blur.  Errors are reported, naming the file and frame. */
static int frame_fog(run_t *r, const fp_view_t *view, const float *depth, const char *in_name,
                     long frame, float *fog)
{
    fp_params_t *p = r->fp;
    int w = view->width, h = view->height, rc = FP_OK;
    size_t n = (size_t)w * h;
    int res = p->buffers.resolution > 1 ? p->buffers.resolution : 1;
    float *dist = NULL, *lo = NULL, *lo_depth = NULL, *edge_fog = NULL;
    int *edges = NULL;
    fp_view_t sub = *view;
    if (r->buffers) {
        dist = malloc(n * sizeof *dist);
        if (res > 1) {
            fp_view_subsample(view, res, &sub);
            size_t ns = (size_t)sub.width * sub.height;
            lo = malloc(ns * 4 * sizeof *lo);
            lo_depth = malloc(ns * sizeof *lo_depth);
            if (p->buffers.edges == FP_EDGES_EXACT)
                edges = malloc(n * sizeof *edges);
        }
        if (!dist || (res > 1 && (!lo || !lo_depth)) ||
            (res > 1 && p->buffers.edges == FP_EDGES_EXACT && !edges)) {
            rc = fp_error("%s: frame %ld: out of memory", in_name, frame);
            goto done;
        }
        fp_buffers_guide(view, depth, dist);
        if (res > 1)
            fp_depth_subsample(depth, w, h, res, lo_depth);
    }
    /* Light in the fog: this frame's shadow map and projection (a bad
     * shadow map is the user's input: its own one-line message). */
    if ((r->reference || r->light.active) &&
        (rc = fp_scatter_frame(p, &r->light, &r->fog, &sub, res > 1 ? lo_depth : depth, frame)))
        goto done;
    /* --shadows screen walks the frame's own depth buffer, at full
     * resolution, from the strided view and from the edge pixels alike:
     * the reduced fog's samples are the full-resolution fog's. */
    if (res > 1 && (rc = fp_scatter_screen(&r->light, view, depth, frame)))
        goto done;
    rc = compute_fog(r, &sub, res > 1 ? lo_depth : depth, NULL, 0, res > 1 ? lo : fog);
    if (rc == FP_OK && res > 1)
        rc = r->use_cl ? fp_upsample_cl(&r->bcl, res, p->buffers.range, w, h, dist, lo, fog)
                       : fp_upsample(res, p->buffers.range, w, h, dist, lo, fog);
    if (rc == FP_OK && edges) {
        size_t ne = fp_upsample_edges(res, p->buffers.edge_threshold, w, h, dist, edges);
        if (ne && !(edge_fog = malloc(ne * 4 * sizeof *edge_fog))) {
            rc = fp_error("%s: frame %ld: out of memory", in_name, frame);
            goto done;
        }
        if (ne && (rc = compute_fog(r, view, depth, edges, ne, edge_fog)) == FP_OK)
            for (size_t k = 0; k < ne; k++)
                memcpy(fog + 4 * (size_t)edges[k], edge_fog + 4 * k, 4 * sizeof *fog);
    }
    if (rc == FP_OK && p->buffers.blur != FP_BLUR_OFF)
        rc = r->use_cl ? fp_buffers_blur_cl(&r->bcl, &p->buffers, w, h, dist, fog)
                       : fp_buffers_blur(&p->buffers, w, h, dist, fog);
    if (rc)
        fp_error("%s: frame %ld: fog computation failed", in_name, frame);
done:
    free(dist);
    free(lo);
    free(lo_depth);
    free(edges);
    free(edge_fog);
    return rc;
}

/* Fog one frame held as RGBA and depth (info: its size, windows, camera
 * attributes, chromaticities) and composite it in place, into the output
 * color space; `fog` (n*4) gets S.rgb (working space) and tau; the frame's
 * color conversions in *color (the fog layers need them).  `ms` gets the
 * fogmap's and the fog's milliseconds.  Used by the frame loop and by the
 * library's frames from memory (fp_session_frame). */
static int fog_composite(run_t *r, const fp_camera_t *cam, const fp_frame_info_t *info,
                         float *rgba, const float *depth, const char *in_name, long frame,
                         float *fog, int layer, fp_color_frame_t *color, double *ms,
                         double *decompose_ms)
{
    fp_params_t *p = r->fp;
    double t0 = fp_now_ms();
    fp_view_t view;
    int rc;
    if ((rc = fp_view_setup(cam, p, info, &view)))
        return rc;
    double t_fogmap = fp_now_ms();
    /* The fog at this frame's time (wind, animated fogmap; its errors name
     * the fogmap's file and the frame). */
    if ((rc = fp_fogmap_frame(p, r->cl, &r->fogmap, frame, &view, &r->fog)))
        return rc;
    ms[FP_T_FOGMAP] = fp_now_ms() - t_fogmap;
    *decompose_ms = r->fogmap.decompose_ms;
    size_t n = (size_t)info->width * info->height;
    /* NaN or negative (!(d >= 0), branch-free: one SIMD pass). */
    long suspicious = 0;
    for (size_t i = 0; i < n; i++)
        suspicious += !(depth[i] >= 0);
    /* Height fog alone, on a device in the host's memory, no fog layer
     * asked for: the kernel composites over the plate itself (the same
     * frame to the bit, without the layer's 33 MB a 1080p frame written
     * and read again). */
    if (!layer && r->use_cl && !r->reference && !r->light.active && !r->buffers &&
        p->fog.sky != 1 && fp_integrate_over_ok(&r->icl, &r->fog, &view, rgba)) {
        if ((rc = fp_color_frame(&r->color, info, in_name, frame, color)))
            return rc;
        fp_color_to_working(color, rgba, n);
        if ((rc = fp_integrate_over_cl(&r->icl, &r->fog, &view, depth, rgba)))
            return fp_error("%s: frame %ld: fog computation failed", in_name, frame);
        if (suspicious)
            fp_warn("%s: frame %ld: %ld pixels with NaN or negative depth treated as sky",
                    in_name, frame, suspicious);
        double t_out = fp_now_ms();
        ms[FP_T_FOG] = t_out - t0 - ms[FP_T_FOGMAP];
        fp_color_to_output(color, rgba, n);
        ms[FP_T_COMPOSITE] = fp_now_ms() - t_out;
        return FP_OK;
    }
    if ((rc = frame_fog(r, &view, depth, in_name, frame, fog)))
        return rc;
    if (suspicious)
        fp_warn("%s: frame %ld: %ld pixels with NaN or negative depth treated as sky",
                in_name, frame, suspicious);
    if (p->fog.sky == 1) {
        /* --sky keep: no fog where there is no geometry. */
        for (size_t i = 0; i < n; i++) {
            int s;
            if (fp_view_is_sky(&view, depth[i], &s)) {
                fog[4 * i] = fog[4 * i + 1] = fog[4 * i + 2] = 0;
                fog[4 * i + 3] = 1;
            }
        }
    }
    double t_composite = fp_now_ms();
    ms[FP_T_FOG] = t_composite - t0 - ms[FP_T_FOGMAP];
    /* Plate input -> working space, composite and fog layers there, then
     * -> output space (filters/color.h; nothing happens by default). */
    if ((rc = fp_color_frame(&r->color, info, in_name, frame, color)))
        return rc;
    fp_color_to_working(color, rgba, n);
    fp_composite_process(rgba, fog, n, rgba);
    fp_color_to_output(color, rgba, n);
    ms[FP_T_COMPOSITE] = fp_now_ms() - t_composite;
    return FP_OK;
}

/* fp_scatter_commit for a frame: its messages (about the options and the
 * rig together) name the file and the frame. */
static int commit_light(const fp_params_t *q, const char *in_name, long frame,
                        fp_scatter_data_t *d, fp_rig_seen_t *warned)
{
    fp_msgbuf_t kept = { NULL, 0, 0 };
    fp_msgbuf_t *prev = fp_msg_capture(&kept);
    int rc = fp_scatter_commit(q, d);
    fp_msg_capture(prev);
    int said = 0;
    for (size_t i = 0; i < kept.len;) {
        const char *line = kept.text + i, *nl = memchr(line, '\n', kept.len - i);
        int n = (int)(nl ? (size_t)(nl - line) : kept.len - i);
        i += (size_t)n + 1;
        if (n >= 9 && strncmp(line, "fogpipe: ", 9) == 0) {
            line += 9;
            n -= 9;
        }
        if (n >= 9 && strncmp(line, "warning: ", 9) == 0) {
            if (!fp_rig_seen(warned, line + 9, n - 9))
                fp_warn("%s: frame %ld: %.*s", in_name, frame, n - 9, line + 9);
        } else if (rc && !said++)
            fp_error("%s: frame %ld: %.*s (with the rig the frame carries)", in_name, frame, n,
                     line);
    }
    fp_msg_free(&kept);
    if (rc && !said)
        fp_error("%s: frame %ld: the rig's light cannot be used", in_name, frame);
    return rc ? FP_ERR : FP_OK;
}

/* The frame's parameters (r->fp): the options with the frame's rig, and
 * the light stage committed again when what it is made from changed (an
 * animated lamp, another frame's shadow map). */
static int frame_params(run_t *r, const fp_rig_t *rig, const char *in_name, long frame)
{
    r->fp = r->p;
    int rc;
    if (rig->any) {
        if ((rc = fp_rig_apply(r->p, rig, in_name, frame, &r->fq)))
            return rc;
        r->fp = &r->fq;
    }
    uint64_t key = fp_rig_light_key(r->fp);
    if (key == r->light_key || r->p->cmd.print_camera)
        return FP_OK;
    fp_scatter_data_t d;
    if ((rc = commit_light(r->fp, in_name, frame, &d, &r->light_warned)))
        return rc;
    fp_scatter_release(&r->light);
    r->light = d;
    r->light_key = key;
    /* Light the first frames did not have: the device's light stage now. */
    if (r->use_cl && r->cl && r->light.active && !r->scl.cl &&
        (rc = fp_scatter_cl_init(r->cl, &r->scl)))
        return rc;
    return FP_OK;
}

/* --deep: a frame's fog as deep samples (filters/deep_frame.h) over a
 * plate (rgba, depth) or a deep input (din), on the host in double
 * precision whatever the device. */
static int deep_image(run_t *r, const fp_deep_data_t *dd, const fp_camera_t *cam,
                      const fp_frame_info_t *info, const fp_frame_t *plate, const float *rgba,
                      const float *depth, const fp_deep_image_t *din, const char *name,
                      long frame, fp_color_frame_t *color, fp_deep_image_t **out)
{
    /* The frame's parameters (its rig over the options) where it has them. */
    fp_params_t *p = r->fp ? r->fp : r->p;
    fp_view_t view;
    float *front = din ? fp_deep_front_depth(din, p->camera.depth_kind) : NULL;
    if (din)
        depth = front;
    int rc = depth ? FP_OK : fp_error("%s: frame %ld: out of memory", name, frame);
    if (rc == FP_OK && (rc = fp_view_setup(cam, p, info, &view)) == FP_OK &&
        (rc = fp_fogmap_frame(p, r->cl, &r->fogmap, frame, &view, &r->fog)) == FP_OK &&
        (!r->light.active ||
         (rc = fp_scatter_frame(p, &r->light, &r->fog, &view, depth, frame)) == FP_OK) &&
        (rc = fp_color_frame(&r->color, info, name, frame, color)) == FP_OK) {
        fp_deep_fog_t df = { dd, &r->fog, &r->light, &view, depth };
        rc = fp_deep_frame(&df, color, info, plate, rgba, din, name, frame, out, &r->deep_stats);
    }
    free(front);
    return rc;
}

/* Stage 2, calling thread (it owns the device): fog one decoded frame and
 * composite it in place, with the frame's parameters (frame_params). */
static int process_frame_with(run_t *r, fp_loop_job_t *job, const fp_rig_t *rig)
{
    fp_params_t *p = r->p;
    frame_state_t *fs = job->data;
    fp_frame_t *f = fs->f;
    const char *in_name = job->in;
    long frame = job->frame;
    int rc;
    const fp_frame_info_t *info = fs->din ? &fs->din->info : fp_frame_info(f);
    fp_camera_t cam;
    if ((rc = fp_camera_resolve(r->fp, info, in_name, frame, &cam)))
        return rc;
    if (p->cmd.print_camera) {
        fp_camera_print(stdout, &cam, info, in_name, frame);
        if (rig->any || r->rigfile)
            fp_rig_print(stdout, rig, r->fp);
        return FP_OK;
    }
    if (r->deep.on) {
        double t0 = fp_now_ms();
        rc = deep_image(r, &r->deep, &cam, info, f, f ? fp_frame_rgba(f) : NULL,
                        f ? fp_frame_depth(f) : NULL, fs->din, in_name, frame, &fs->color,
                        &fs->dout);
        fp_color_write_opts(&fs->color, &fs->wopts);
        job->ms[FP_T_FOG] = fp_now_ms() - t0;
        return rc;
    }
    size_t n = (size_t)info->width * info->height;
    float *fog = fs->fog = fog_get(r, n);
    if (!fog)
        return fp_error("%s: frame %ld: out of memory", in_name, frame);
    fs->fog_px = n;
    if ((rc = fog_composite(r, &cam, info, fp_frame_rgba(f), fp_frame_depth(f), in_name, frame,
                            fog, p->aov.aov || p->aov.aov_only, &fs->color, job->ms,
                            &job->decompose_ms)))
        return rc;
    double t_aov = fp_now_ms();
    if ((rc = fp_aov_make(p, &fs->color, fog, n, in_name, frame, &fs->aov)))
        return rc;
    fp_color_write_opts(&fs->color, &fs->wopts);
    fp_aov_write_opts(p, &fs->aov, &fs->wopts);
    job->ms[FP_T_COMPOSITE] += fp_now_ms() - t_aov;
    return FP_OK;
}

static int process_frame(run_t *r, fp_loop_job_t *job)
{
    frame_state_t *fs = job->data;
    fp_rig_t rig;
    /* This frame's rig (what it carries, under --rig's) over the options. */
    int rc = fp_rig_frame(r->rigfile, fs->din ? &fs->din->info : fp_frame_info(fs->f), job->in,
                          job->frame, &rig);
    if (rc)
        return rc;
    if ((rc = frame_params(r, &rig, job->in, job->frame)) == FP_OK)
        rc = process_frame_with(r, job, &rig);
    fp_rig_params_release(&r->fq);
    r->fp = r->p;
    fp_rig_free(&rig);
    return rc;
}

/* Stage 3, writer thread (frames arrive in order): encode the frame and
 * write it, atomically to its file or whole to stdout. */
static int write_frame(run_t *r, fp_loop_job_t *job)
{
    fp_params_t *p = r->p;
    frame_state_t *fs = job->data;
    fp_frame_t *f = fs->f;
    const char *out_name = job->out;
    long frame = job->frame;
    void *bytes = NULL;
    size_t nbytes = 0;
    int rc = FP_OK;

    if (p->cmd.print_camera)
        return FP_OK;
    double t0 = fp_now_ms();
    if (fs->dout || fs->din)
        rc = fs->dout ? fp_deep_encode(fs->dout, f, &fs->wopts, out_name, frame, &bytes, &nbytes)
                      : fp_error("%s: frame %ld: no deep output made", out_name, frame);
    else if (!r->preview.out_image)
        rc = fp_exr_encode(f, fp_frame_rgba(f), &fs->wopts, out_name, frame, &bytes, &nbytes);
    if (rc)
        goto done;
    double t1 = fp_now_ms();
    job->ms[FP_T_ENCODE] = t1 - t0;
    /* The preview before the frame: an output frame on disk means a whole
     * frame (--skip-existing). */
    fp_loop_commit_begin();
    if (!fs->dout)
        rc = fp_preview_frame(&r->preview, &fs->color, fp_frame_rgba(f), fp_frame_info(f)->width,
                              fp_frame_info(f)->height, frame);
    fp_loop_commit_end(NULL);
    if (rc)
        goto done;
    fp_loop_commit_begin();
    if (r->preview.out_image) {   /* -o x.png: written as the previews are */
        rc = fp_preview_output(&fs->color, fp_frame_rgba(f), fp_frame_info(f)->width,
                               fp_frame_info(f)->height, out_name, frame);
    } else if (r->out_stream) {
        /* The frame is encoded whole before the first byte goes out. */
        if (fwrite(bytes, 1, nbytes, r->out_stream) != nbytes || fflush(r->out_stream))
            rc = fp_error("<stdout>: frame %ld: write failed (%s)", frame, strerror(errno));
    } else if ((rc = fp_make_parent_dir(out_name, frame)) == FP_OK) {
        rc = fp_exr_write_bytes(out_name, frame, bytes, nbytes);
    }
    fp_loop_commit_end(rc == FP_OK ? job : NULL);
    job->ms[FP_T_WRITE] = fp_now_ms() - t1;
done:
    free(bytes);
    return rc;
}

/* The stages as the frame loop calls them. */
static int stage_process(void *ctx, fp_loop_job_t *job)
{
    run_t *r = ctx;
    /* --no-fog: the frame goes out as it came in (benchmark of the I/O). */
    return r->p->run.no_fog ? FP_OK : process_frame(r, job);
}

static int stage_write(void *ctx, fp_loop_job_t *job)
{
    return write_frame(ctx, job);
}

static void stage_release(void *ctx, fp_loop_job_t *job)
{
    run_t *r = ctx;
    frame_state_t *fs = job->data;
    if (!fs)
        return;
    if (fs->f)
        fp_frame_free(fs->f);
    fog_put(r, fs->fog, fs->fog_px);
    fp_aov_free(&fs->aov);
    fp_deep_free(fs->din);
    fp_deep_free(fs->dout);
    free(fs);
    job->data = NULL;
}

static int output_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

static int setup(run_t *r)
{
    fp_params_t *p = r->p;
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    sel.color_layer = p->io.color_layer;
    sel.depth_channel = p->io.depth_channel;
    sel.need_depth = p->io.depth ? 0 : 1;
    r->sel = sel;
    fp_exr_write_opts_t w = FP_EXR_WRITE_OPTS_INITIALIZER;
    w.use_float = p->io.use_float;
    if (strcmp(p->io.compression, "input") != 0) {
        w.compression = fp_exr_compression_from_name(p->io.compression);
        if (w.compression < 0)
            return fp_usage_error("--compression: unknown compression '%s' (expected input, none, "
                                  "rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab)",
                                  p->io.compression);
        /* refused here, before any frame is computed, not at the first write */
        if (!fp_exr_compression_writable(w.compression))
            return fp_usage_error("--compression: %s cannot be written by this build",
                                  p->io.compression);
    }
    w.dwa_level = fp_options_given(p, "dwa-level") ? (float) p->io.dwa_level : -1.0f;
    r->wopts = w;
    /* --shadow-map without --sun: the sun may be the frames' (their rig),
     * so the light is committed with the first frame (frame_params). */
    fp_params_t q = *p;
    int defer = r->has_rig && p->light.shadow_map && !fp_options_given(p, "sun");
    if (defer)
        q.light.shadow_map = NULL;
    int rc = fp_integrate_commit(p, &r->fog);
    if (rc || (rc = fp_scatter_commit(&q, &r->light)) || (rc = fp_deep_commit(p, &r->deep)))
        return rc;
    r->fp = p;
    r->light_key = fp_rig_light_key(p) ^ (uint64_t)defer;
    r->reference = p->fogmap.integrator == FP_INTEGRATOR_REFERENCE;
    r->buffers = fp_buffers_active(p);
    r->use_cl = !p->io.cpu;
    return FP_OK;
}

/* The device, the programs and the fogmap, once per run (not for
 * --print-camera, which needs none of them). */
static int open_device(run_t *r)
{
    fp_params_t *p = r->p;
    if (p->cmd.print_camera || p->run.no_fog)
        return FP_OK;
    if (r->use_cl) {
        if (fp_cl_open(p->io.device, &r->cl))
            return FP_ERR;
        fp_info("OpenCL device: %s", fp_cl_device_label(r->cl));
        if (fp_integrate_cl_init(r->cl, &r->icl) ||
            (r->light.active && fp_scatter_cl_init(r->cl, &r->scl)) ||
            (r->reference && fp_reference_cl_init(r->cl, &r->rcl)) ||
            (r->buffers && fp_buffers_cl_init(r->cl, &r->bcl)))
            return FP_ERR;
    }
    int active;
    return fp_fogmap_commit(p, r->cl, &r->fogmap, &r->fog, &active);
}

/* Stage 1 for file input: frame job->seq of the list (reader thread). */
static int next_file(void *ctx, fp_loop_job_t *job)
{
    run_t *r = ctx;
    fp_params_t *p = r->p;
    if (job->seq >= (long)r->frames->count)
        return FP_EOF;
    long frame = job->frame = r->frames->frames[job->seq];
    int rc;
    if ((rc = fp_seq_format(p->io.input, frame, job->in, sizeof job->in)))
        return rc;
    if (r->out_stream)
        snprintf(job->out, sizeof job->out, "<stdout>");
    else if ((rc = fp_seq_format(p->io.output, frame, job->out, sizeof job->out)))
        return rc;
    if (r->skip && r->skip[job->seq]) {
        job->skipped = 1;
        fp_info("%s: frame %ld: output exists, skipped (--skip-existing)", job->out, frame);
        return FP_OK;
    }
    struct stat si, so;
    if (!r->out_stream && stat(job->in, &si) == 0 && stat(job->out, &so) == 0 &&
        si.st_dev == so.st_dev && si.st_ino == so.st_ino)
        return fp_usage_error("%s: frame %ld: output would overwrite the input", job->in, frame);
    void *buf = NULL;
    size_t size = 0;
    double t0 = fp_now_ms();
    rc = fp_exr_load_file(job->in, frame, &buf, &size);
    job->ms[FP_T_READ] = fp_now_ms() - t0;
    return rc ? rc : read_frame(r, job, buf, size);
}

/* Stage 1 for stream input: the next frame on stdin (reader thread). */
static int next_stream(void *ctx, fp_loop_job_t *job)
{
    run_t *r = ctx;
    fp_params_t *p = r->p;
    const fp_frame_list_t *labels = r->labels;
    long idx = job->seq;
    void *buf = NULL;
    size_t size = 0;
    job->frame = labels ? (idx < (long)labels->count ? labels->frames[idx] : -1) : idx + 1;
    snprintf(job->in, sizeof job->in, "<stdin>");
    double t0 = fp_now_ms();
    fp_loop_blocking_begin();
    int rc = fp_exr_stream_next(stdin, "<stdin>", idx + 1, &buf, &size);
    fp_loop_blocking_end();
    job->ms[FP_T_READ] = fp_now_ms() - t0;
    if (rc == FP_EOF)
        return idx == 0 ? fp_error("<stdin>: empty input (expected an EXR stream)") : FP_EOF;
    if (rc)
        return rc;
    if (labels && idx >= (long)labels->count) {
        free(buf);
        return fp_usage_error("<stdin>: frame %ld: more frames on stdin than --frames lists (%zu)",
                              idx + 1, labels->count);
    }
    if (!r->out_seq) {
        snprintf(job->out, sizeof job->out, "<stdout>");
    } else if ((rc = fp_seq_format(p->io.output, job->frame, job->out, sizeof job->out))) {
        free(buf);
        return rc;
    } else if (p->run.skip_existing && output_exists(job->out)) {
        /* Read off the stream all the same, to get to the next frame. */
        free(buf);
        job->skipped = 1;
        fp_info("%s: frame %ld: output exists, skipped (--skip-existing)", job->out, job->frame);
        return FP_OK;
    }
    return read_frame(r, job, buf, size);
}

static int run_loop(run_t *r, int (*next)(void *, fp_loop_job_t *), long total)
{
    fp_params_t *p = r->p;
    fp_loop_ops_t ops = { r, next, stage_process, stage_write, stage_release };
    fp_loop_opts_t o = { 0 };
    o.pipelined = p->run.pipeline;
    /* --pipeline off: one frame at a time on one thread */
    fp_exr_set_threads(p->run.pipeline ? p->run.io_threads : 1);
    o.progress = p->run.progress;
    if (p->io.quiet || p->cmd.print_camera)
        o.progress = FP_PROGRESS_OFF;
    else if (o.progress == FP_PROGRESS_AUTO)
        o.progress = isatty(STDERR_FILENO) ? FP_PROGRESS_BAR : FP_PROGRESS_LINES;
    o.device = r->cl ? fp_cl_device_label(r->cl) : "C reference (--cpu)";
    o.argc = p->cmd.argc;
    o.argv = p->cmd.argv;
    o.total = total;
    o.stats_path = p->run.stats;
    o.input = p->io.input;
    o.output = p->io.output;
    o.setup_ms = r->setup_ms;
    o.fogmap_setup_ms = r->fogmap_setup_ms;
    return fp_loop_run(&ops, &o);
}

static int run_stream_input(run_t *r, const fp_frame_list_t *labels)
{
    fp_params_t *p = r->p;
    int out_seq = !is_stream(p->io.output);
    if (out_seq && fp_seq_has_placeholder(p->io.output) != 1)
        return fp_usage_error("%s: output for a stream on stdin must be - or a sequence pattern "
                              "(e.g. out.####.exr)", p->io.output);
    if (isatty(STDIN_FILENO))
        return fp_usage_error("no input: give -i FILE|PATTERN, or pipe EXR frames on stdin "
                              "(see fogpipe --help)");
    r->labels = labels;
    r->out_seq = out_seq;
    r->out_stream = out_seq ? NULL : stdout;
    return run_loop(r, next_stream, labels ? (long)labels->count : 0);
}

/* --rig FILE, the run's up axis and look (src/scene/rig.h). */
static int rig_setup(run_t *r)
{
    return fp_rig_run_setup(r->p, &r->rigfile, &r->has_rig);
}

static int run_files(run_t *r)
{
    fp_params_t *p = r->p;
    int in_seq = fp_seq_has_placeholder(p->io.input);
    int out_stream = is_stream(p->io.output);
    if (in_seq < 0 || fp_seq_has_placeholder(p->io.output) < 0)
        return fp_usage_error("%s: malformed sequence pattern (expected one %%0Nd, or one run of "
                              "# or @)", in_seq < 0 ? p->io.input : p->io.output);
    int out_seq = !out_stream && fp_seq_has_placeholder(p->io.output) == 1;
    fp_frame_list_t frames = { NULL, 0 };
    unsigned char *skip = NULL;
    int rc = FP_OK;
    if (fp_options_given(p, "frame") && (in_seq || p->io.frames))
        return fp_usage_error("--frame %d: only for a single input file without --frames (a "
                              "sequence's frames: --frames)", p->io.frame);
    if (in_seq) {
        if (!out_stream && !out_seq && !p->cmd.print_camera)
            return fp_usage_error("%s: output of a sequence must be a sequence pattern "
                                  "(e.g. out.####.exr) or -", p->io.output);
        rc = p->io.frames ? fp_frames_parse(p->io.frames, &frames)
                          : fp_frames_scan(p->io.input, &frames);
    } else {
        if (p->io.frames) {
            rc = fp_frames_parse(p->io.frames, &frames);
            if (rc == FP_OK && frames.count != 1)
                rc = fp_usage_error("%s: one input file but --frames lists %zu frames",
                                    p->io.input, frames.count);
        } else {
            frames.frames = malloc(sizeof(long));
            if (!frames.frames)
                return fp_error("out of memory");
            frames.frames[0] = fp_rig_single_frame(p);
            frames.count = 1;
        }
    }
    if (rc)
        goto done;
    /* --skip-existing: a frame whose output is there is not even read. */
    if (p->run.skip_existing && !out_stream && !p->cmd.print_camera) {
        skip = calloc(frames.count ? frames.count : 1, 1);
        if (!skip) {
            rc = fp_error("out of memory");
            goto done;
        }
        for (size_t k = 0; k < frames.count; k++) {
            char path[4096];
            if ((rc = fp_seq_format(p->io.output, frames.frames[k], path, sizeof path)))
                goto done;
            skip[k] = (unsigned char)output_exists(path);
        }
    }
    /* Every input must be there before anything is written. */
    for (size_t k = 0; k < frames.count; k++) {
        char path[4096];
        struct stat st;
        if (skip && skip[k])
            continue;
        if ((rc = fp_seq_format(p->io.input, frames.frames[k], path, sizeof path)))
            goto done;
        if (stat(path, &st) != 0) {
            rc = fp_error("%s: frame %ld: missing input (%s)", path, frames.frames[k],
                          strerror(errno));
            goto done;
        }
    }
    if (out_stream && !p->cmd.print_camera && isatty(STDOUT_FILENO)) {
        rc = fp_usage_error("refusing to write EXR data to a terminal (give -o FILE|PATTERN, or "
                            "redirect stdout)");
        goto done;
    }
    r->frames = &frames;
    r->skip = skip;
    r->out_stream = out_stream ? stdout : NULL;
    rc = run_loop(r, next_file, (long)frames.count);
    r->frames = NULL;
    r->skip = NULL;
done:
    free(skip);
    fp_frames_free(&frames);
    return rc;
}

/* What setup, fp_color_commit, fp_preview_commit and open_device made.
 * The device's buffers before the fogmap's tables: on a device in the
 * host's memory they are the tables (fp_fog_tables_alloc). */
static void run_release(run_t *r)
{
    fp_preview_release(&r->preview);
    fp_color_release(&r->color);
    fp_rig_file_free(r->rigfile);
    r->rigfile = NULL;
    if (r->cl) {
        fp_scatter_cl_release(&r->scl);
        if (r->reference)
            fp_reference_cl_release(&r->rcl);
        if (r->buffers)
            fp_buffers_cl_release(&r->bcl);
        fp_integrate_cl_release(&r->icl);
        fp_cl_close(r->cl);
        r->cl = NULL;
    }
    fp_fogmap_release(&r->fogmap);
    fp_scatter_release(&r->light);
    for (size_t i = 0; i < FP_ARRAY_LEN(r->pool); i++) {
        free(r->pool[i]);
        r->pool[i] = NULL;
    }
    pthread_mutex_destroy(&r->pool_mu);
}

int fp_pipeline_run(fp_params_t *p)
{
    run_t r;
    memset(&r, 0, sizeof r);
    r.p = p;
    int rc = fp_image_limits_apply(p->run.max_image_pixels);
    if (rc == FP_OK && !p->fogmap.preview)
        rc = rig_setup(&r);
    if (rc == FP_OK)
        rc = setup(&r);
    if (rc == FP_OK && p->fogmap.preview) {
        int active;
        rc = fp_fogmap_commit(p, NULL, &r.fogmap, &r.fog, &active);
        if (rc == FP_OK && !active)
            rc = fp_usage_error("--fogmap-preview needs --fogmap FILE");
        if (rc == FP_OK)
            rc = fp_fogmap_preview(&r.fogmap, p->fogmap.preview);
        fp_fogmap_release(&r.fogmap);
        return rc;
    }
    if (rc == FP_OK && p->run.skip_existing && is_stream(p->io.output) && !p->cmd.print_camera)
        return fp_usage_error("--skip-existing needs output files (-o FILE|PATTERN), not a "
                              "stream on stdout");
    /* Before the libraries start threads (OpenColorIO, the OpenCL driver):
     * they inherit the blocked signals (lib/frameloop.h). */
    if (rc == FP_OK && p->run.catch_signals)
        rc = fp_loop_signals_start();
    /* Color spaces, display, view and preview names: checked before any
     * frame is read (filters/color.h, filters/preview.h). */
    if (rc == FP_OK)
        rc = fp_color_commit(p, &r.color);
    if (rc == FP_OK)
        rc = fp_preview_commit(p, &r.preview);
    pthread_mutex_init(&r.pool_mu, NULL);
    double t_setup = fp_now_ms();
    if (rc == FP_OK)
        rc = open_device(&r);
    r.setup_ms = fp_now_ms() - t_setup;
    r.fogmap_setup_ms = r.fogmap.decompose_ms;
    if (rc == FP_OK) {
        if (is_stream(p->io.input)) {
            fp_frame_list_t labels = { NULL, 0 };
            if (p->io.frames)
                rc = fp_frames_parse(p->io.frames, &labels);
            if (rc == FP_OK)
                rc = run_stream_input(&r, p->io.frames ? &labels : NULL);
            fp_frames_free(&labels);
        } else {
            rc = run_files(&r);
        }
    }
    if (rc == FP_OK && !p->cmd.print_camera)
        rc = fp_preview_finish(&r.preview);
    if (r.deep_stats.pixels)
        fp_info("deep: %.2f samples a pixel (%.2f of fog) over %ld pixels, %ld pixels at "
                "--deep-max-samples, %.1f fog evaluations a pixel",
                (double)r.deep_stats.samples / r.deep_stats.pixels,
                (double)r.deep_stats.fog_samples / r.deep_stats.pixels, r.deep_stats.pixels,
                r.deep_stats.capped, (double)r.deep_stats.evals / r.deep_stats.pixels);
    run_release(&r);
    fp_loop_signals_stop();
    return rc;
}

/* ------------------------------------------------------------ frames from memory
 * The run as lib/session.c drives it (lib/session.h). */

int fp_run_open(fp_params_t *p, fp_run_t **out)
{
    *out = NULL;
    run_t *r = calloc(1, sizeof *r);
    if (!r)
        return fp_error("out of memory");
    r->p = p;
    pthread_mutex_init(&r->pool_mu, NULL);
    int rc = setup(r);
    if (rc == FP_OK)
        rc = fp_color_commit(p, &r->color);
    if (rc == FP_OK)
        rc = open_device(r);
    if (rc) {
        fp_run_close(r);
        return rc;
    }
    *out = r;
    return FP_OK;
}

int fp_run_composite(fp_run_t *r, const fp_camera_t *cam, const fp_frame_info_t *info,
                     float *rgba, const float *depth, const char *name, long frame, float *fog,
                     int want_layers, fp_color_frame_t *color)
{
    double ms[FP_T_COUNT] = { 0 }, decompose_ms = 0;
    return fog_composite(r, cam, info, rgba, depth, name, frame, fog, want_layers, color, ms,
                         &decompose_ms);
}

int fp_run_deep(fp_run_t *r, const fp_deep_data_t *dd, const fp_camera_t *cam,
                const fp_frame_info_t *info, const float *rgba, const float *depth,
                const char *name, long frame, fp_color_frame_t *color, fp_deep_image_t **out)
{
    return deep_image(r, dd, cam, info, NULL, rgba, depth, NULL, name, frame, color, out);
}

void fp_run_close(fp_run_t *r)
{
    if (!r)
        return;
    run_release(r);
    free(r);
}
