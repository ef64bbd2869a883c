#include "lamp_shadow.h"

#include "fp.h"

#include "../kernels/fog_core.h"
#include "../kernels/light_core.h"

int fp_lamp_shadow_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                      const fp_view_t *v, const int *pix, size_t npix)
{
    if (d->lt[FP_LT_LS_ON] == 0 || (pix && npix == 0))
        return FP_OK;
    cl_kernel k = s->ls_kernel;
    cl_int w = v->width, h = v->height, cnpix = pix ? (cl_int)npix : 0;
    size_t local[2] = { 16, 8 };
    size_t global[2] = { fp_cl_round_up((size_t)w, local[0]), fp_cl_round_up((size_t)h, local[1]) };
    if (cnpix) {
        local[0] = 128;
        local[1] = 1;
        global[0] = fp_cl_round_up(npix, local[0]);
        global[1] = 1;
    }
    if (FP_CL_ARG(k, 0, ic->depth) || FP_CL_ARG(k, 1, ic->fog) || FP_CL_ARG(k, 2, ic->view) ||
        FP_CL_ARG(k, 3, w) || FP_CL_ARG(k, 4, h) || FP_CL_ARG(k, 5, ic->params) ||
        FP_CL_ARG(k, 6, ic->pix) || FP_CL_ARG(k, 7, cnpix) || FP_CL_ARG(k, 8, s->lt) ||
        FP_CL_ARG(k, 9, s->smap) || FP_CL_ARG(k, 10, s->lights))
        return FP_ERR;
    return fp_cl_check(clEnqueueNDRangeKernel(fp_cl_queue(s->cl), k, 2, NULL, global, local, 0,
                                              NULL, NULL),
                       "lamp_shadows");
}
