/* The scatter stage on an OpenCL device: kernels/scatter.cl's launches
 * and the buffers they read. */
#include "scatter.h"
#include "options.h"
#include "fp.h"
#include "lamp_shadow.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"
#include "../kernels/ms_core.h"

static const float no_map[1] = { INFINITY };

int fp_scatter_cl_init(fp_cl_t *cl, fp_scatter_cl_t *s)
{
    memset(s, 0, sizeof *s);
    s->cl = cl;
    cl_program prog;
    /* No -cl-fast-relaxed-math for scatter_lights: its lanes carry
     * infinities (sky rays' length, fog without a top, empty spans), which
     * that option lets the compiler assume away (it dropped the lights). */
    if (fp_cl_program(cl, "scatter", "-cl-std=CL1.2", &prog) ||
        fp_cl_kernel(prog, "scatter_fog", &s->kernel) ||
        fp_cl_kernel(prog, "sun_od_grid", &s->grid_kernel) ||
        fp_cl_kernel(prog, "scatter_lights", &s->light_kernel) ||
        fp_cl_kernel(prog, "lamp_shadows", &s->ls_kernel))
        return FP_ERR;
    cl_int err;
    s->lt = clCreateBuffer(fp_cl_context(cl), CL_MEM_READ_ONLY, FP_LT_COUNT * sizeof(float), NULL,
                           &err);
    return fp_cl_check(err, "scatter: light buffer");
}

static int upload(fp_scatter_cl_t *s, const fp_scatter_data_t *d)
{
    cl_context ctx = fp_cl_context(s->cl);
    cl_command_queue q = fp_cl_queue(s->cl);
    float lt[FP_LT_COUNT];
    for (int i = 0; i < FP_LT_COUNT; i++)
        lt[i] = (float)d->lt[i];
    if (fp_cl_check(clEnqueueWriteBuffer(q, s->lt, CL_TRUE, 0, sizeof lt, lt, 0, NULL, NULL),
                    "scatter: upload light parameters"))
        return FP_ERR;
    /* The lights' table: a global buffer of any size (at least one row). */
    size_t nf = (size_t)(d->nlights > 0 ? d->nlights : 1) * FP_LL_STRIDE;
    float *lf = calloc(nf, sizeof *lf);
    if (!lf)
        return fp_error("scatter: out of memory");
    for (size_t i = 0; d->lights && i < (size_t)d->nlights * FP_LL_STRIDE; i++)
        lf[i] = (float)d->lights[i];
    cl_int err = CL_SUCCESS;
    if (!s->lights || s->lights_n != nf) {
        if (s->lights)
            clReleaseMemObject(s->lights);
        s->lights = clCreateBuffer(ctx, CL_MEM_READ_ONLY, nf * sizeof(float), NULL, &err);
        s->lights_n = err == CL_SUCCESS ? nf : 0;
    }
    if (err == CL_SUCCESS)
        err = clEnqueueWriteBuffer(q, s->lights, CL_TRUE, 0, nf * sizeof(float), lf, 0, NULL, NULL);
    free(lf);
    if (fp_cl_check(err, "scatter: upload the lights"))
        return FP_ERR;
    if (s->smap && s->uploaded == d->serial)
        return FP_OK;
    /* The map again only when it changed (a sequence's unchanged map is
     * uploaded once). */
    if (!s->smap || !d->smap_serial || s->smap_uploaded != d->smap_serial) {
        if (s->smap)
            clReleaseMemObject(s->smap);
        s->smap_uploaded = 0;
        size_t ns = d->smap ? d->smap_n : 1;
        s->smap = clCreateBuffer(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, ns * sizeof(float),
                                 (void *)(d->smap ? d->smap : no_map), &err);
        if (fp_cl_check(err, "scatter: shadow map"))
            return FP_ERR;
        s->smap_uploaded = d->smap_serial;
    }
    size_t ng = fp_scatter_uses_grid(d) ? fp_scatter_grid_nodes(d->lt) : 1;
    if (!s->grid || s->grid_n != ng) {
        if (s->grid)
            clReleaseMemObject(s->grid);
        s->grid_key.valid = 0;
        s->grid = clCreateBuffer(ctx, CL_MEM_READ_WRITE, ng * sizeof(float), NULL, &err);
        if (fp_cl_check(err, "scatter: self-shadow grid"))
            return FP_ERR;
        s->grid_n = ng;
    }
    s->uploaded = d->serial;
    return FP_OK;
}

int fp_scatter_process_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                          const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                          float *out)
{
    return fp_scatter_pixels_cl(s, ic, d, fog, v, depth, NULL, 0, out);
}

int fp_scatter_pixels_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                         const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                         const int *pix, size_t npix, float *out)
{
    if (fp_integrate_cl_prepare(ic, fog, v, depth) || upload(s, d))
        return FP_ERR;
    cl_command_queue q = fp_cl_queue(s->cl);
    if (fp_scatter_uses_grid(d) && !fp_scatter_grid_current(&s->grid_key, d, fog)) {
        cl_kernel g = s->grid_kernel;
        size_t global[3] = { (size_t)d->lt[FP_LT_GRID_N], (size_t)d->lt[FP_LT_GRID_N + 1],
                             (size_t)d->lt[FP_LT_GRID_K] };
        if (FP_CL_ARG(g, 0, s->grid) || FP_CL_ARG(g, 1, ic->params) || FP_CL_ARG(g, 2, ic->lvi) ||
            FP_CL_ARG(g, 3, ic->lvf) || FP_CL_ARG(g, 4, ic->coef) || FP_CL_ARG(g, 5, ic->occ) ||
            FP_CL_ARG(g, 6, s->lt) ||
            fp_cl_check(clEnqueueNDRangeKernel(q, g, 3, NULL, global, NULL, 0, NULL, NULL),
                        "sun_od_grid")) {
            s->grid_key.valid = 0;
            return FP_ERR;
        }
    }
    int nl = (int)d->lt[FP_LT_NLIGHTS];
    int fast = d->lt[FP_LT_LIGHT_QUAD] != 0 && fog->fp[FP_F_HAS_MAP] == 0 && nl > 0;
    /* Only the local lights of the fast rule, the ambient light and fog
     * without a fogmap: what scatter_fog would give before them is tau and
     * the ambient term's closed form (fp_scatter_ray_core's first return,
     * fp_scatter_ambient_lights), S = albedo (1 - tau) L_amb: the SIMD
     * kernel of height fog writes it (about 20x faster on the CPU device
     * than scatter_fog's scalar work-items), left on the device for
     * scatter_lights. */
    int ambient = fast && d->lt[FP_LT_SUN_ON] == 0 && d->lt[FP_LT_NDIR] == 0 &&
                  d->lt[FP_LT_MS_ON] == 0 && !v->ortho && !(v->clip > 0);
    if (ambient) {
        double amb[3];
        for (int c = 0; c < 3; c++)
            amb[c] = d->lt[FP_LT_ALBEDO] * d->lt[FP_LT_AMB + c];
        if (fp_integrate_height_layer_cl(ic, fog, v, pix, npix, amb))
            return FP_ERR;
    } else {
        cl_kernel k = s->kernel;
        if (FP_CL_ARG(k, 12, s->lt) || FP_CL_ARG(k, 13, s->smap) || FP_CL_ARG(k, 14, s->grid) ||
            FP_CL_ARG(k, 15, s->lights) ||
            fp_integrate_cl_launch(ic, k, v, pix, npix, out, "scatter_fog"))
            return FP_ERR;
    }
    /* Local lights by the fast rule: scatter_fog left them out
     * (FP_LIGHTS_APART); one launch of scatter_lights adds them all to the
     * fog layer, 16 pixels per work-item (FP_LN_LANES). */
    if (!fast || (pix && npix == 0))
        return FP_OK;
    const size_t lanes = 16;   /* FP_LN_LANES in kernels/scatter_lanes.h */
    cl_kernel lk = s->light_kernel;
    cl_int w = v->width, h = v->height, cnpix = pix ? (cl_int)npix : 0;
    size_t global[2] = { ((size_t)w + lanes - 1) / lanes, (size_t)h };
    if (cnpix) {
        global[0] = (npix + lanes - 1) / lanes;
        global[1] = 1;
    }
    if (FP_CL_ARG(lk, 0, ic->depth) || FP_CL_ARG(lk, 1, ic->fog) || FP_CL_ARG(lk, 2, ic->view) ||
        FP_CL_ARG(lk, 3, w) || FP_CL_ARG(lk, 4, h) || FP_CL_ARG(lk, 5, ic->params) ||
        FP_CL_ARG(lk, 6, ic->pix) || FP_CL_ARG(lk, 7, cnpix) || FP_CL_ARG(lk, 8, s->lt) ||
        FP_CL_ARG(lk, 9, s->lights) ||
        fp_cl_check(clEnqueueNDRangeKernel(q, lk, 2, NULL, global, NULL, 0, NULL, NULL),
                    "scatter_lights") ||
        fp_lamp_shadow_cl(s, ic, d, v, pix, npix))
        return FP_ERR;
    size_t nout = cnpix ? npix : (size_t)w * h;
    return fp_cl_check(clEnqueueReadBuffer(q, ic->fog, CL_TRUE, 0, nout * 4 * sizeof(float), out, 0,
                                           NULL, NULL),
                       "scatter: read the fog layer with the local lights");
}

void fp_scatter_cl_release(fp_scatter_cl_t *s)
{
    if (s->kernel)
        clReleaseKernel(s->kernel);
    if (s->grid_kernel)
        clReleaseKernel(s->grid_kernel);
    if (s->light_kernel)
        clReleaseKernel(s->light_kernel);
    if (s->ls_kernel)
        clReleaseKernel(s->ls_kernel);
    cl_mem *mems[] = { &s->lt, &s->smap, &s->grid, &s->lights };
    for (size_t i = 0; i < FP_ARRAY_LEN(mems); i++)
        if (*mems[i])
            clReleaseMemObject(*mems[i]);
    memset(s, 0, sizeof *s);
}
