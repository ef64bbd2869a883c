/* fogpipe: the local lights' screen-space shadows taken out of the fast
 * rule's light (--lamp-shadows; the walk itself is lamp_shadow_core.h).
 * Above scatter_core.h, whose fp_light_fast it corrects. */
#ifndef FP_LAMP_SHADOW_FAST_H
#define FP_LAMP_SHADOW_FAST_H

#include "scatter_core.h"
#include "lamp_shadow_core.h"

/* The fast rule (fp_light_ray, fp_ln_light_ray) integrates each local
 * light over the view ray's whole stretch in the fog, unshadowed; this
 * adds, per light that reaches the pixel, its integral over the lit
 * stretches (each by the fast rule) minus the whole: S += (lit - whole) I.
 * The lights left out by culling (fp_light_bound against --light-cull,
 * 1 - tau the ray's) are left out here too, per pixel.  Run after the
 * lights were added, in C (filters/scatter.c ray_at) and in OpenCL
 * (kernel lamp_shadows) alike; S never goes below 0. */
FP_FN void fp_ls_fix(FP_CONSTANT const fp_real *fp, FP_CONSTANT const fp_real *lt,
                     FP_GLOBAL const fp_real *lights, FP_CONSTANT const float *view,
                     FP_GLOBAL const float *smap, fp_real ox, fp_real oy, fp_real oz, fp_real dx,
                     fp_real dy, fp_real dz, fp_real len, fp_real tau, fp_real *S)
{
    int nl = (int)lt[FP_LT_NLIGHTS];
    if (lt[FP_LT_LS_ON] == 0 || nl == 0 || lt[FP_LT_LIGHT_QUAD] == 0 || fp[FP_F_HAS_MAP] != 0)
        return;
    fp_real ta, tb;
    fp_light_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb);
    if (!(tb > ta))
        return;
    fp_real budget = lt[FP_LT_CULL], smax = fp_light_sigma_max(fp), omt = 1 - tau;
    fp_real iv[2 * FP_SS_MAX_IV];
    for (int k = 0; k < nl; k++) {
        FP_GLOBAL const fp_real *row = lights + k * FP_LL_STRIDE;
        if (budget > 0) {
            fp_real b = fp_light_bound(lt, row, smax, omt, ox, oy, oz, dx, dy, dz, ta, tb);
            if (b <= budget) {
                budget -= b;
                continue;
            }
        }
        int n = fp_ls_ray_iv(lt, row, view, smap, ox, oy, oz, dx, dy, dz, ta, tb, iv);
        if (n == 0)
            continue;
        fp_real whole = fp_light_fast(fp, lt, row,
                                      fp_light_sig_c(fp, row, ox, oy, oz, dx, dy, dz, ta, tb), ox,
                                      oy, oz, dx, dy, dz, ta, tb);
        fp_real lit = 0, t = ta;
        for (int q = 0; q <= n; q++) {
            fp_real e = q < n ? iv[2 * q] : tb;
            if (e > t)
                lit += fp_light_fast(fp, lt, row,
                                     fp_light_sig_c(fp, row, ox, oy, oz, dx, dy, dz, t, e), ox, oy,
                                     oz, dx, dy, dz, t, e);
            t = q < n ? iv[2 * q + 1] : t;
        }
        if (!isfinite(lit) || !isfinite(whole))
            continue;
        for (int c = 0; c < 3; c++)
            S[c] = fmax(S[c] + (lit - whole) * row[FP_LL_I + c], (fp_real)0);
    }
}

#endif
