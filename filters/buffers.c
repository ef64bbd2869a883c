#include "buffers.h"
#include "fp.h"
#include "options.h"

#include "buffers_core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* --fog-resolution 1 | 1/2 | 1/4, stored as the factor 1, 2, 4. */
static int set_resolution(fp_params_t *p, const fp_option_t *o, const char *value)
{
    static const struct { const char *name; int f; } v[] = {
        { "1", 1 }, { "1/2", 2 }, { "1/4", 4 }
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(v); i++)
        if (strcmp(value, v[i].name) == 0) {
            *(int *)((char *)p + o->offset) = v[i].f;
            return FP_OK;
        }
    return fp_usage_error("--%s: unknown value '%s' (expected %s)", o->name, value, o->choices);
}

#define BUF(f) offsetof(fp_params_t, buffers.f)
const fp_option_t fp_buffers_options[] = {
    { "blur", 0, FP_OPT_ENUM, BUF(blur), 0, 0, "off", 0, 0, "off|bilateral", NULL,
      "blur the fog layer (in-scattered light and transmittance, never the plate): a Gaussian "
      "made edge-aware by weighing each neighbour by how close its distance from the camera is "
      "to the pixel's, so fog never smears across a depth edge and sky blends only with sky",
      NULL, 0 },
    { "blur-radius", 0, FP_OPT_INT, BUF(radius), 0, 0, "4", 1, FP_BLUR_MAX_RADIUS, NULL, "PX",
      "radius of the blur in pixels: each pixel blends the (2 PX + 1) x (2 PX + 1) square "
      "around it", NULL, 0 },
    { "blur-sigma", 0, FP_OPT_REAL, BUF(sigma), 0, 0, "0", 0, 1000, NULL, "PX",
      "standard deviation of the blur's Gaussian in pixels (0: half the radius)", NULL, 0 },
    { "blur-range", 0, FP_OPT_REAL, BUF(range), 0, 0, "0.05", 1e-6, 1e6, NULL, "R",
      "range sigma: how far apart two pixels' distances from the camera may be and still "
      "blend, as a relative difference |d1 - d2| / min(d1, d2) (0.05: 5%); also guides the "
      "upsampling of --fog-resolution", NULL, 0 },
    { "blur-iterations", 0, FP_OPT_INT, BUF(iterations), 0, 0, "1", 1, 8, NULL, "N",
      "apply the blur N times (smoother, still edge-aware)", NULL, 0 },
    { "blur-falloff", 0, FP_OPT_REAL, BUF(falloff), 0, 0, "0", 0, INFINITY, NULL, "D",
      "no blur within D scene units of the camera, fading in linearly to the full blur at 2 D "
      "(0: blur everywhere)", NULL, 0 },
    { "blur-separable", 0, FP_OPT_ENUM, BUF(separable), 0, 0, "on", 0, 0, "off|on", NULL,
      "on: a horizontal then a vertical pass, both weighing distance against the pixel being "
      "blurred (fast, close to the full kernel; the README gives the measured difference); "
      "off: the full 2D kernel", NULL, 0 },
    { "fog-resolution", 0, FP_OPT_ENUM, BUF(resolution), 0, 0, "1", 0, 0, "1|1/2|1/4", NULL,
      "compute the fog at full, half or quarter resolution in each direction and bring it back "
      "by joint bilateral upsampling guided by the full-resolution depth; at depth edges a "
      "pixel takes the nearest sample at its own distance (see --fog-edges)", set_resolution, 0 },
    { "fog-edges", 0, FP_OPT_ENUM, BUF(edges), 0, 0, "exact", 0, 0, "upsample|exact", NULL,
      "at --fog-resolution 1/2 or 1/4, the pixels at depth edges (the low-resolution samples "
      "around a pixel differ in distance from it by more than --fog-edge-threshold): exact "
      "computes them again at full resolution, so their fog is the full-resolution fog (a few "
      "percent of the pixels; the README gives the measured cost); upsample keeps the "
      "upsampled value", NULL, 0 },
    { "fog-edge-threshold", 0, FP_OPT_REAL, BUF(edge_threshold), 0, 0, "0.1", 1e-4, 1e6, NULL,
      "R", "relative difference of distance |d1 - d2| / min(d1, d2) between a pixel and one "
      "of the 4 low-resolution samples around it that makes it a depth-edge pixel for "
      "--fog-edges exact (sky against geometry always does)", NULL, 0 },
    FP_OPT_END
};

int fp_buffers_active(const fp_params_t *p)
{
    return p->buffers.blur != FP_BLUR_OFF || p->buffers.resolution > 1;
}

double fp_buffers_sigma(const fp_buffers_params_t *b)
{
    return b->sigma > 0 ? b->sigma : 0.5 * b->radius;
}

void fp_buffers_guide(const fp_view_t *v, const float *depth, float *dist)
{
    for (int y = 0; y < v->height; y++)
        for (int x = 0; x < v->width; x++) {
            size_t i = (size_t)y * v->width + x;
            double dir[3], len;
            fp_view_ray(v, x, y, depth[i], dir, &len);
            dist[i] = isinf(len) ? INFINITY : (float)len;
        }
}

void fp_view_subsample(const fp_view_t *v, int f, fp_view_t *out)
{
    *out = *v;
    out->width = (v->width + f - 1) / f;
    out->height = (v->height + f - 1) / f;
    /* nx = (f x' + off) * scale = (x' + off / f) * (f * scale) */
    for (int i = 0; i < 2; i++) {
        out->ndc_offset[i] = v->ndc_offset[i] / f;
        out->ndc_scale[i] = v->ndc_scale[i] * f;
    }
}

void fp_depth_subsample(const float *depth, int w, int h, int f, float *out)
{
    int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
    for (int j = 0; j < lh; j++)
        for (int i = 0; i < lw; i++)
            out[(size_t)j * lw + i] = depth[(size_t)(f * j) * w + (size_t)f * i];
}

double fp_buffers_range_weight(double d1, double d2, double range)
{
    return fp_buf_range_weight(d1, d2, 1 / range);
}

/* One blur of the whole layer (a separable pass: rx or ry 0). */
static void blur(int rx, int ry, double inv2s2, double range, int w, int h, const float *dist,
                 const float *in, float *out)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            fp_real4 v = fp_buf_blur_pixel(in, dist, w, h, x, y, rx, ry, inv2s2, 1 / range);
            for (int ch = 0; ch < 4; ch++)
                out[4 * ((size_t)y * w + x) + ch] = (float)v.c[ch];
        }
}

/* The option ranges, for callers that fill the parameters themselves. */
static int check_blur(const fp_buffers_params_t *b)
{
    if (b->radius < 1 || b->radius > FP_BLUR_MAX_RADIUS || b->iterations < 1 ||
        !(b->range > 0) || !(b->sigma >= 0))
        return fp_error("buffers: blur radius %d (1..%d), iterations %d, range %g, sigma %g "
                        "out of range", b->radius, FP_BLUR_MAX_RADIUS, b->iterations, b->range,
                        b->sigma);
    return FP_OK;
}

static int check_factor(int f, double range)
{
    if (f < 1 || f > 16 || !(range > 0))
        return fp_error("buffers: upsampling factor %d (1..16) or range %g out of range", f,
                        range);
    return FP_OK;
}

int fp_buffers_blur(const fp_buffers_params_t *b, int w, int h, const float *dist, float *fog)
{
    if (b->blur == FP_BLUR_OFF || w <= 0 || h <= 0)
        return FP_OK;
    if (check_blur(b))
        return FP_ERR;
    size_t n = (size_t)w * h;
    int radius = b->radius;
    double sigma = fp_buffers_sigma(b), inv2s2 = 0.5 / (sigma * sigma);
    float *tmp = malloc(n * 4 * sizeof(float));
    float *orig = b->falloff > 0 ? malloc(n * 4 * sizeof(float)) : NULL;
    if (!tmp || (b->falloff > 0 && !orig)) {
        free(tmp);
        free(orig);
        return fp_error("buffers: out of memory");
    }
    if (orig)
        memcpy(orig, fog, n * 4 * sizeof(float));
    for (int it = 0; it < b->iterations; it++) {
        if (b->separable) {
            blur(radius, 0, inv2s2, b->range, w, h, dist, fog, tmp);
            blur(0, radius, inv2s2, b->range, w, h, dist, tmp, fog);
        } else {
            blur(radius, radius, inv2s2, b->range, w, h, dist, fog, tmp);
            memcpy(fog, tmp, n * 4 * sizeof(float));
        }
    }
    if (orig)
        for (size_t i = 0; i < n; i++) {
            double a = fp_buf_falloff(dist[i], b->falloff);
            for (int ch = 0; ch < 4; ch++)
                fog[4 * i + ch] = (float)((1 - a) * orig[4 * i + ch] + a * fog[4 * i + ch]);
        }
    free(tmp);
    free(orig);
    return FP_OK;
}

size_t fp_upsample_edges(int f, double threshold, int w, int h, const float *dist, int *pix)
{
    size_t n = 0;
    if (f <= 1)
        return 0;
    int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (fp_buf_edge_pixel(dist, f, w, lw, lh, x, y, threshold))
                pix[n++] = y * w + x;
    return n;
}

int fp_upsample(int f, double range, int w, int h, const float *dist, const float *lo,
                float *fog)
{
    if (check_factor(f, range))
        return FP_ERR;
    if (f == 1) {   /* full resolution: nothing to bring back */
        memcpy(fog, lo, (size_t)w * h * 4 * sizeof(float));
        return FP_OK;
    }
    int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
    double sig = 0.5 * f, inv2s2 = 1 / (2 * sig * sig);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            fp_real4 v = fp_buf_upsample_pixel(lo, dist, f, w, lw, lh, x, y, inv2s2, 1 / range);
            for (int ch = 0; ch < 4; ch++)
                fog[4 * ((size_t)y * w + x) + ch] = (float)v.c[ch];
        }
    return FP_OK;
}

/* ---------------------------------------------------------------- OpenCL */

int fp_buffers_cl_init(fp_cl_t *cl, fp_buffers_cl_t *s)
{
    memset(s, 0, sizeof *s);
    s->cl = cl;
    cl_program prog;
    if (fp_cl_program(cl, "buffers", "-cl-std=CL1.2", &prog) ||
        fp_cl_kernel(prog, "blur", &s->blur) || fp_cl_kernel(prog, "blur_falloff", &s->falloff) ||
        fp_cl_kernel(prog, "upsample_fog", &s->upsample))
        return FP_ERR;
    return FP_OK;
}

static void release_mem(cl_mem *m)
{
    if (*m)
        clReleaseMemObject(*m);
    *m = NULL;
}

static int ensure_capacity(fp_buffers_cl_t *s, size_t n)
{
    if (n <= s->capacity)
        return FP_OK;
    release_mem(&s->dist);
    release_mem(&s->fog);
    release_mem(&s->tmp);
    release_mem(&s->orig);
    s->capacity = 0;
    cl_context ctx = fp_cl_context(s->cl);
    cl_int err;
    s->dist = clCreateBuffer(ctx, CL_MEM_READ_ONLY, n * sizeof(float), NULL, &err);
    if (fp_cl_check(err, "buffers: distance buffer"))
        return FP_ERR;
    cl_mem *fogs[] = { &s->fog, &s->tmp, &s->orig };
    for (size_t i = 0; i < FP_ARRAY_LEN(fogs); i++) {
        *fogs[i] = clCreateBuffer(ctx, CL_MEM_READ_WRITE, n * 4 * sizeof(float), NULL, &err);
        if (fp_cl_check(err, "buffers: fog buffer"))
            return FP_ERR;
    }
    s->capacity = n;
    return FP_OK;
}

/* The guide (n pixels) and a layer of `pixels` pixels to the device;
 * blocking, so the caller's buffers need not outlive the call. */
static int upload_layer(fp_buffers_cl_t *s, size_t n, const float *dist, cl_mem layer,
                        size_t pixels, const float *data, const char *what)
{
    cl_command_queue q = fp_cl_queue(s->cl);
    return fp_cl_check(clEnqueueWriteBuffer(q, s->dist, CL_TRUE, 0, n * sizeof(float), dist, 0,
                                            NULL, NULL), "buffers: upload distance") ||
           fp_cl_check(clEnqueueWriteBuffer(q, layer, CL_TRUE, 0, pixels * 4 * sizeof(float),
                                            data, 0, NULL, NULL), what);
}

static int run_2d(fp_buffers_cl_t *s, cl_kernel k, int w, int h, const char *what)
{
    size_t local[2] = { 16, 8 };
    size_t global[2] = { fp_cl_round_up((size_t)w, local[0]),
                         fp_cl_round_up((size_t)h, local[1]) };
    return fp_cl_check(clEnqueueNDRangeKernel(fp_cl_queue(s->cl), k, 2, NULL, global, local, 0,
                                              NULL, NULL), what);
}

int fp_buffers_blur_cl(fp_buffers_cl_t *s, const fp_buffers_params_t *b, int w, int h,
                       const float *dist, float *fog)
{
    if (b->blur == FP_BLUR_OFF || w <= 0 || h <= 0)
        return FP_OK;
    if (check_blur(b))
        return FP_ERR;
    size_t n = (size_t)w * h;
    if (ensure_capacity(s, n))
        return FP_ERR;
    cl_command_queue q = fp_cl_queue(s->cl);
    if (upload_layer(s, n, dist, s->fog, n, fog, "buffers: upload fog"))
        return FP_ERR;
    int falloff = b->falloff > 0;
    if (falloff && fp_cl_check(clEnqueueCopyBuffer(q, s->fog, s->orig, 0, 0,
                                                   n * 4 * sizeof(float), 0, NULL, NULL),
                               "buffers: keep the unblurred fog"))
        return FP_ERR;
    double sigma = fp_buffers_sigma(b);
    cl_int cw = w, ch = h, radius = b->radius;
    cl_float inv2s2 = (float)(0.5 / (sigma * sigma)), inv_range = (float)(1 / b->range);
    cl_mem cur = s->fog, other = s->tmp;
    /* Each iteration: a horizontal then a vertical pass, or the full
     * kernel once. */
    for (int it = 0; it < b->iterations; it++)
        for (int pass = 0; pass < (b->separable ? 2 : 1); pass++) {
            cl_kernel k = s->blur;
            cl_int rx = b->separable && pass == 1 ? 0 : radius;
            cl_int ry = b->separable && pass == 0 ? 0 : radius;
            if (FP_CL_ARG(k, 0, cur) || FP_CL_ARG(k, 1, other) || FP_CL_ARG(k, 2, s->dist) ||
                FP_CL_ARG(k, 3, cw) || FP_CL_ARG(k, 4, ch) || FP_CL_ARG(k, 5, rx) ||
                FP_CL_ARG(k, 6, ry) || FP_CL_ARG(k, 7, inv2s2) || FP_CL_ARG(k, 8, inv_range) ||
                run_2d(s, k, w, h, "blur"))
                return FP_ERR;
            cl_mem t = cur;
            cur = other;
            other = t;
        }
    if (falloff) {
        cl_kernel k = s->falloff;
        cl_float d = (float)b->falloff;
        if (FP_CL_ARG(k, 0, s->orig) || FP_CL_ARG(k, 1, cur) || FP_CL_ARG(k, 2, s->dist) ||
            FP_CL_ARG(k, 3, cw) || FP_CL_ARG(k, 4, ch) || FP_CL_ARG(k, 5, d) ||
            run_2d(s, k, w, h, "blur_falloff"))
            return FP_ERR;
    }
    return fp_cl_check(clEnqueueReadBuffer(q, cur, CL_TRUE, 0, n * 4 * sizeof(float), fog, 0,
                                           NULL, NULL), "buffers: read fog");
}

int fp_upsample_cl(fp_buffers_cl_t *s, int f, double range, int w, int h, const float *dist,
                   const float *lo, float *fog)
{
    if (w <= 0 || h <= 0)
        return FP_OK;
    if (check_factor(f, range))
        return FP_ERR;
    size_t n = (size_t)w * h;
    if (f == 1) {
        memcpy(fog, lo, n * 4 * sizeof(float));
        return FP_OK;
    }
    int lw = (w + f - 1) / f, lh = (h + f - 1) / f;
    size_t ln = (size_t)lw * lh;
    if (ensure_capacity(s, n))
        return FP_ERR;
    cl_int err;
    if (ln > s->lo_capacity) {
        release_mem(&s->lo);
        s->lo_capacity = 0;
        s->lo = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY, ln * 4 * sizeof(float),
                               NULL, &err);
        if (fp_cl_check(err, "buffers: low-resolution fog buffer"))
            return FP_ERR;
        s->lo_capacity = ln;
    }
    cl_command_queue q = fp_cl_queue(s->cl);
    if (upload_layer(s, n, dist, s->lo, ln, lo, "buffers: upload low-resolution fog"))
        return FP_ERR;
    double sig = 0.5 * f;
    cl_int cf = f, cw = w, ch = h, clw = lw, clh = lh;
    cl_float inv2s2 = (float)(1 / (2 * sig * sig)), inv_range = (float)(1 / range);
    cl_kernel k = s->upsample;
    if (FP_CL_ARG(k, 0, s->lo) || FP_CL_ARG(k, 1, s->fog) || FP_CL_ARG(k, 2, s->dist) ||
        FP_CL_ARG(k, 3, cf) || FP_CL_ARG(k, 4, cw) || FP_CL_ARG(k, 5, ch) ||
        FP_CL_ARG(k, 6, clw) || FP_CL_ARG(k, 7, clh) || FP_CL_ARG(k, 8, inv2s2) ||
        FP_CL_ARG(k, 9, inv_range) || run_2d(s, k, w, h, "upsample_fog"))
        return FP_ERR;
    return fp_cl_check(clEnqueueReadBuffer(q, s->fog, CL_TRUE, 0, n * 4 * sizeof(float), fog, 0,
                                           NULL, NULL), "buffers: read fog");
}

void fp_buffers_cl_release(fp_buffers_cl_t *s)
{
    cl_kernel *ks[] = { &s->blur, &s->falloff, &s->upsample };
    for (size_t i = 0; i < FP_ARRAY_LEN(ks); i++)
        if (*ks[i])
            clReleaseKernel(*ks[i]);
    cl_mem *mems[] = { &s->dist, &s->fog, &s->tmp, &s->orig, &s->lo };
    for (size_t i = 0; i < FP_ARRAY_LEN(mems); i++)
        release_mem(mems[i]);
    memset(s, 0, sizeof *s);
}
