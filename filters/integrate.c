#include "integrate.h"
#include "fp.h"
#include "options.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int set_visibility(fp_params_t *p, const fp_option_t *o, const char *value)
{
    char *end;
    double d = strtod(value, &end);
    if (end == value || *end || !(d > 0) || isinf(d))
        return fp_usage_error("--visibility: expected a distance > 0 in scene units, got '%s'",
                              value);
    /* Visibility: the distance at which 90% of light is lost. */
    p->fog.density = log(10.0) / d;
    return FP_OK;
}

#define FOG(f) offsetof(fp_params_t, fog.f)
const fp_option_t fp_integrate_options[] = {
    { "density", 0, FP_OPT_REAL, FOG(density), 0, 0, "0.02", 0, 1e6, NULL, "SIGMA",
      "extinction per scene unit at the base of the fog", NULL, 0 },
    { "visibility", 0, FP_OPT_REAL, FOG(density), 0, 0, NULL, 0, INFINITY, NULL, "D",
      "set the density by visibility: 90% of light lost over D scene units "
      "(sigma = ln(10)/D)", set_visibility, 0 },
    { "height", 0, FP_OPT_VEC, FOG(height), 3, 2, "0,20,inf", -1e9, INFINITY, NULL, "Y0,H[,TOP]",
      "height profile: full density below Y0, exp(-(y-Y0)/H) above it, none above TOP "
      "(H = inf: homogeneous)", NULL, 0 },
    { "fog-color", 0, FP_OPT_VEC, FOG(color), 3, 3, "0.7,0.75,0.8", 0, 1e6, NULL, "R,G,B",
      "fog color: in-scattered ambient radiance, scene-linear", NULL, 0 },
    FP_OPT_END
};

int fp_integrate_commit(const fp_params_t *p, fp_integrate_data_t *d)
{
    memset(d, 0, sizeof *d);
    d->sigma = p->fog.density;
    d->y0 = p->fog.height[0];
    d->H = p->fog.height[1];
    d->top = p->fog.height[2];
    if (!(d->H > 0))
        return fp_usage_error("--height: the scale height H must be > 0 (got %g)", d->H);
    if (!(d->top > d->y0))
        return fp_usage_error("--height: TOP (%g) must be above Y0 (%g)", d->top, d->y0);
    memcpy(d->fog_color, p->fog.color, sizeof d->fog_color);
    return FP_OK;
}

/* [a, b] within [0, len] where lo <= oy + t dy < hi; 0 if empty. */
static int slab_interval(double oy, double dy, double lo, double hi, double len,
                         double *a, double *b)
{
    double t0, t1;
    if (dy == 0) {
        if (oy < lo || oy >= hi)
            return 0;
        t0 = 0;
        t1 = len;
    } else {
        double u = (lo - oy) / dy, v = (hi - oy) / dy;
        t0 = fmax(fmin(u, v), 0);
        t1 = fmin(fmax(u, v), len);
    }
    *a = t0;
    *b = t1;
    return t1 > t0;
}

/* (1 - exp(-x)) / x, x >= 0, without cancellation. */
static double expm1_ratio(double x)
{
    return x < 1e-8 ? 1 - 0.5 * x : -expm1(-x) / x;
}

double fp_integrate_optical_depth(const fp_integrate_data_t *d, double oy, double dy,
                                  double len)
{
    double od = 0, a, b;
    if (d->sigma <= 0)
        return 0;
    if (slab_interval(oy, dy, -INFINITY, fmin(d->y0, d->top), len, &a, &b))
        od += b - a;
    if (slab_interval(oy, dy, d->y0, d->top, len, &a, &b)) {
        /* Heights in units of H from the base; the integral of exp(-y) from
         * the lowest point m over a rise D is exp(-m) (1 - exp(-D)). */
        double ya = (oy + a * dy - d->y0) / d->H;
        if (isinf(b)) {
            if (dy > 0)
                od += exp(-ya) * d->H / dy;
            else if (exp(-ya) > 0)
                od = INFINITY;
        } else {
            double D = fabs(dy) * (b - a) / d->H;
            double m = dy < 0 ? ya - D : ya;
            od += (b - a) * exp(-m) * expm1_ratio(D);
        }
    }
    return d->sigma * od;
}

int fp_integrate_process(const fp_integrate_data_t *d, const fp_view_t *v,
                         const float *depth, float *fog, long *suspicious)
{
    long bad = 0;
    for (int y = 0; y < v->height; y++)
        for (int x = 0; x < v->width; x++) {
            size_t i = (size_t)y * v->width + x;
            double dir[3], len;
            int s;
            fp_view_is_sky(v, depth[i], &s);
            bad += s;
            fp_view_ray(v, x, y, depth[i], dir, &len);
            double tau = exp(-fp_integrate_optical_depth(d, v->origin[1], dir[1], len));
            for (int c = 0; c < 3; c++)
                fog[4 * i + c] = (float)((1 - tau) * d->fog_color[c]);
            fog[4 * i + 3] = (float)tau;
        }
    if (suspicious)
        *suspicious = bad;
    return FP_OK;
}

int fp_integrate_cl_init(fp_cl_t *cl, fp_integrate_cl_t *s)
{
    memset(s, 0, sizeof *s);
    s->cl = cl;
    cl_program prog;
    if (fp_cl_program(cl, "integrate", "-cl-std=CL1.2", &prog))
        return FP_ERR;
    if (fp_cl_kernel(prog, "integrate_height", &s->kernel))
        return FP_ERR;
    cl_int err;
    s->view = clCreateBuffer(fp_cl_context(cl), CL_MEM_READ_ONLY,
                             FP_VIEW_FLOATS * sizeof(float), NULL, &err);
    return fp_cl_check(err, "integrate: view buffer");
}

static int ensure_capacity(fp_integrate_cl_t *s, size_t n)
{
    if (n <= s->capacity)
        return FP_OK;
    if (s->depth)
        clReleaseMemObject(s->depth);
    if (s->fog)
        clReleaseMemObject(s->fog);
    s->depth = s->fog = NULL;
    s->capacity = 0;
    cl_int err;
    s->depth = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_READ_ONLY, n * sizeof(float), NULL, &err);
    if (fp_cl_check(err, "integrate: depth buffer"))
        return FP_ERR;
    s->fog = clCreateBuffer(fp_cl_context(s->cl), CL_MEM_WRITE_ONLY, n * 4 * sizeof(float), NULL,
                            &err);
    if (fp_cl_check(err, "integrate: fog buffer"))
        return FP_ERR;
    s->capacity = n;
    return FP_OK;
}

int fp_integrate_process_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                            const fp_view_t *v, const float *depth, float *fog)
{
    size_t n = (size_t)v->width * v->height;
    if (ensure_capacity(s, n))
        return FP_ERR;
    cl_command_queue q = fp_cl_queue(s->cl);
    float view[FP_VIEW_FLOATS];
    fp_view_pack(v, view);
    cl_float4 fogp = { { (float)d->sigma, (float)d->y0, (float)d->H, (float)d->top } };
    cl_float4 color = { { (float)d->fog_color[0], (float)d->fog_color[1],
                          (float)d->fog_color[2], 0 } };
    cl_int w = v->width, h = v->height;
    if (fp_cl_check(clEnqueueWriteBuffer(q, s->view, CL_FALSE, 0, sizeof view, view, 0, NULL, NULL),
                    "integrate: upload view") ||
        fp_cl_check(clEnqueueWriteBuffer(q, s->depth, CL_FALSE, 0, n * sizeof(float), depth, 0,
                                         NULL, NULL), "integrate: upload depth"))
        return FP_ERR;
    if (FP_CL_ARG(s->kernel, 0, s->depth) || FP_CL_ARG(s->kernel, 1, s->fog) ||
        FP_CL_ARG(s->kernel, 2, s->view) || FP_CL_ARG(s->kernel, 3, w) ||
        FP_CL_ARG(s->kernel, 4, h) || FP_CL_ARG(s->kernel, 5, fogp) ||
        FP_CL_ARG(s->kernel, 6, color))
        return FP_ERR;
    size_t local[2] = { 16, 8 };
    size_t global[2] = { fp_cl_round_up((size_t)w, local[0]), fp_cl_round_up((size_t)h, local[1]) };
    if (fp_cl_check(clEnqueueNDRangeKernel(q, s->kernel, 2, NULL, global, local, 0, NULL, NULL),
                    "integrate_height"))
        return FP_ERR;
    return fp_cl_check(clEnqueueReadBuffer(q, s->fog, CL_TRUE, 0, n * 4 * sizeof(float), fog, 0,
                                           NULL, NULL), "integrate: read fog");
}

void fp_integrate_cl_release(fp_integrate_cl_t *s)
{
    if (s->kernel)
        clReleaseKernel(s->kernel);
    if (s->depth)
        clReleaseMemObject(s->depth);
    if (s->fog)
        clReleaseMemObject(s->fog);
    if (s->view)
        clReleaseMemObject(s->view);
    memset(s, 0, sizeof *s);
}
