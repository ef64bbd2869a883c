#include "pipeline.h"
#include "camera.h"
#include "clrt.h"
#include "composite.h"
#include "exrio.h"
#include "fogmap.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "seq.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define IO(f) offsetof(fp_params_t, io.f)
const fp_option_t fp_io_options[] = {
    { "input", 'i', FP_OPT_STRING, IO(input), 0, 0, "-", 0, 0, NULL, "PATTERN",
      "input EXR: a file, a sequence (shot.####.exr, shot.%04d.exr), or - for a stream on stdin",
      NULL, 0 },
    { "output", 'o', FP_OPT_STRING, IO(output), 0, 0, "-", 0, 0, NULL, "PATTERN",
      "output EXR: a file, a sequence pattern, or - for a stream on stdout", NULL, 0 },
    { "frames", 'f', FP_OPT_STRING, IO(frames), 0, 0, NULL, 0, 0, NULL, "LIST",
      "frames of a sequence: 1001-1100, 1-100x2, 5, -3, 1,3,7-9 (default: all found on disk; "
      "for a stream, the numbers given to its frames)", NULL, 0 },
    { "depth", 0, FP_OPT_STRING, IO(depth), 0, 0, NULL, 0, 0, NULL, "PATTERN",
      "take depth from a separate EXR sequence (same frame numbers and data window)", NULL, 0 },
    { "color-layer", 0, FP_OPT_STRING, IO(color_layer), 0, 0, NULL, 0, 0, NULL, "PREFIX",
      "color channels PREFIX.R, PREFIX.G, PREFIX.B[, PREFIX.A] (default: R,G,B,A, "
      "else the first <layer>.Combined)", NULL, 0 },
    { "depth-channel", 0, FP_OPT_STRING, IO(depth_channel), 0, 0, NULL, 0, 0, NULL, "NAME",
      "depth channel name (default: Z, depth.Z, else <layer>.Depth.Z)", NULL, 0 },
    { "float", 0, FP_OPT_FLAG, IO(use_float), 0, 0, NULL, 0, 1, NULL, NULL,
      "write color as 32-bit float (default: half)", NULL, 0 },
    { "compression", 0, FP_OPT_STRING, IO(compression), 0, 0, "input", 0, 0, NULL, "NAME",
      "output compression: input (the input's), none, rle, zips, zip, piz, pxr24, b44, b44a, "
      "dwaa, dwab", NULL, 0 },
    { "device", 'd', FP_OPT_STRING, IO(device), 0, 0, NULL, 0, 0, NULL, "N|NAME",
      "OpenCL device: index from --list-devices or part of its name (default: "
      "$FOGPIPE_DEVICE, else the first GPU, else the first device)", NULL, 0 },
    { "cpu", 0, FP_OPT_FLAG, IO(cpu), 0, 0, NULL, 0, 1, NULL, NULL,
      "compute with the C double-precision reference instead of OpenCL (slow; for checks)",
      NULL, 0 },
    { "preset", 0, FP_OPT_STRING, IO(preset), 0, 0, NULL, 0, 0, NULL, "FILE",
      "read options from FILE (key = value lines); the command line wins", NULL,
      FP_OPTF_CLI_ONLY },
    { "quiet", 'q', FP_OPT_FLAG, IO(quiet), 0, 0, NULL, 0, 1, NULL, NULL,
      "no warnings or progress on stderr", NULL, 0 },
    { "verbose", 'v', FP_OPT_FLAG, IO(verbose), 0, 0, NULL, 0, 1, NULL, NULL,
      "report device, program cache and per-frame timing on stderr", NULL, 0 },
    FP_OPT_END
};

typedef struct run_t {
    fp_params_t *p;
    fp_exr_select_t sel;
    fp_exr_write_opts_t wopts;
    fp_integrate_data_t fog;
    fp_cl_t *cl;
    fp_integrate_cl_t icl;
    fp_fogmap_stage_t fogmap;
    int use_cl;
} run_t;

static int is_stream(const char *s) { return !s || strcmp(s, "-") == 0; }

/* Fog one decoded frame and emit it. */
static int process_frame(run_t *r, fp_frame_t *f, const char *in_name, long frame,
                         const char *out_name, FILE *out_stream)
{
    fp_params_t *p = r->p;
    int rc = FP_OK;
    float *fog = NULL;
    void *bytes = NULL;
    size_t nbytes = 0;
    fp_frame_t *df = NULL;

    if (p->io.depth) {
        char dpath[4096];
        fp_exr_select_t dsel = r->sel;
        dsel.need_color = 0;
        dsel.color_layer = NULL;
        if ((rc = fp_seq_format(p->io.depth, frame, dpath, sizeof dpath)) ||
            (rc = fp_exr_read_file(dpath, frame, &dsel, &df)) ||
            (rc = fp_frame_take_depth(f, in_name, df, dpath, frame)))
            goto done;
    }
    const fp_frame_info_t *info = fp_frame_info(f);
    fp_camera_t cam;
    if ((rc = fp_camera_resolve(p, info, in_name, frame, &cam)))
        goto done;
    if (p->cmd.print_camera) {
        fp_camera_print(stdout, &cam, info, in_name, frame);
        goto done;
    }
    fp_view_t view;
    if ((rc = fp_view_setup(&cam, p, info, &view)))
        goto done;
    fp_fogmap_frame(p, &view, &r->fog);
    size_t n = (size_t)info->width * info->height;
    const float *depth = fp_frame_depth(f);
    float *rgba = fp_frame_rgba(f);
    fog = malloc(n * 4 * sizeof(float));
    if (!fog) {
        rc = fp_error("%s: frame %ld: out of memory", in_name, frame);
        goto done;
    }
    long suspicious = 0;
    if (r->use_cl) {
        for (size_t i = 0; i < n; i++)
            suspicious += isnan(depth[i]) || depth[i] < 0;
        rc = fp_integrate_process_cl(&r->icl, &r->fog, &view, depth, fog);
    } else {
        rc = fp_integrate_process(&r->fog, &view, depth, fog, &suspicious);
    }
    if (rc) {
        fp_error("%s: frame %ld: fog computation failed", in_name, frame);
        goto done;
    }
    if (suspicious)
        fp_warn("%s: frame %ld: %ld pixels with NaN or negative depth treated as sky",
                in_name, frame, suspicious);
    fp_composite_process(rgba, fog, n, rgba);
    if (out_stream) {
        if ((rc = fp_exr_encode(f, rgba, &r->wopts, out_name, frame, &bytes, &nbytes)))
            goto done;
        /* The frame is encoded whole before the first byte goes out. */
        if (fwrite(bytes, 1, nbytes, out_stream) != nbytes || fflush(out_stream)) {
            rc = fp_error("<stdout>: frame %ld: write failed (%s)", frame, strerror(errno));
            goto done;
        }
    } else {
        rc = fp_exr_write_file(f, rgba, &r->wopts, out_name, frame);
    }
done:
    free(bytes);
    free(fog);
    if (df)
        fp_frame_free(df);
    return rc;
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
    }
    r->wopts = w;
    int rc = fp_integrate_commit(p, &r->fog);
    if (rc)
        return rc;
    r->use_cl = !p->io.cpu;
    return FP_OK;
}

/* The device, the programs and the fogmap, once per run (not for
 * --print-camera, which needs none of them). */
static int open_device(run_t *r)
{
    fp_params_t *p = r->p;
    if (p->cmd.print_camera)
        return FP_OK;
    if (r->use_cl) {
        if (fp_cl_open(p->io.device, &r->cl))
            return FP_ERR;
        fp_info("OpenCL device: %s", fp_cl_device_label(r->cl));
        if (fp_integrate_cl_init(r->cl, &r->icl))
            return FP_ERR;
    }
    int active;
    return fp_fogmap_commit(p, r->cl, &r->fogmap, &r->fog, &active);
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
    int rc = FP_OK;
    for (long idx = 0;; idx++) {
        void *buf = NULL;
        size_t size = 0;
        long frame = labels ? (idx < (long)labels->count ? labels->frames[idx] : -1) : idx + 1;
        rc = fp_exr_stream_next(stdin, "<stdin>", idx + 1, &buf, &size);
        if (rc == FP_EOF) {
            rc = idx == 0 ? fp_error("<stdin>: empty input (expected an EXR stream)") : FP_OK;
            break;
        }
        if (rc)
            break;
        if (labels && idx >= (long)labels->count) {
            free(buf);
            rc = fp_usage_error("<stdin>: frame %ld: more frames on stdin than --frames lists (%zu)",
                                idx + 1, labels->count);
            break;
        }
        fp_frame_t *f = NULL;
        char label[64];
        snprintf(label, sizeof label, "<stdin>");
        if ((rc = fp_exr_read_memory(buf, size, label, frame, &r->sel, &f)))
            break;
        char opath[4096] = "";
        if (out_seq)
            rc = fp_seq_format(p->io.output, frame, opath, sizeof opath);
        if (rc == FP_OK)
            rc = process_frame(r, f, label, frame, out_seq ? opath : "<stdout>",
                               out_seq ? NULL : stdout);
        fp_frame_free(f);
        if (rc)
            break;
    }
    return rc;
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
    int rc = FP_OK;
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
            frames.frames[0] = 1;
            frames.count = 1;
        }
    }
    if (rc)
        goto done;
    /* Every input must be there before anything is written. */
    for (size_t k = 0; k < frames.count; k++) {
        char path[4096];
        struct stat st;
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
    for (size_t k = 0; k < frames.count && rc == FP_OK; k++) {
        long frame = frames.frames[k];
        char in[4096], out[4096] = "";
        fp_frame_t *f = NULL;
        if ((rc = fp_seq_format(p->io.input, frame, in, sizeof in)))
            break;
        if (!out_stream && (rc = fp_seq_format(p->io.output, frame, out, sizeof out)))
            break;
        struct stat si, so;
        if (!out_stream && stat(in, &si) == 0 && stat(out, &so) == 0 &&
            si.st_dev == so.st_dev && si.st_ino == so.st_ino) {
            rc = fp_usage_error("%s: frame %ld: output would overwrite the input", in, frame);
            break;
        }
        if ((rc = fp_exr_read_file(in, frame, &r->sel, &f)))
            break;
        rc = process_frame(r, f, in, frame, out_stream ? "<stdout>" : out,
                           out_stream ? stdout : NULL);
        fp_frame_free(f);
        fp_info("%s: frame %ld done", in, frame);
    }
done:
    fp_frames_free(&frames);
    return rc;
}

int fp_pipeline_run(fp_params_t *p)
{
    run_t r;
    memset(&r, 0, sizeof r);
    r.p = p;
    int rc = setup(&r);
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
    if (rc == FP_OK)
        rc = open_device(&r);
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
    fp_fogmap_release(&r.fogmap);
    if (r.cl) {
        fp_integrate_cl_release(&r.icl);
        fp_cl_close(r.cl);
    }
    return rc;
}
