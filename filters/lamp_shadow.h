/* fogpipe: the local lights' screen-space shadows (--lamp-shadows), the
 * device's pass: kernels/lamp_shadow_core.h holds the rule, the C
 * reference runs it in filters/scatter.c (ray_at), and the depth pyramid
 * it walks is made with the sun's (fp_scatter_screen). */
#ifndef FP_LAMP_SHADOW_H
#define FP_LAMP_SHADOW_H

#include "scatter.h"

/* After scatter_lights on the device: the lamps' shadows taken out of the
 * fog layer ic->fog (the frame, or the npix pixels pix[] as listed; pix
 * already uploaded by the launch before).  FP_OK at once when off. */
int fp_lamp_shadow_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                      const fp_view_t *v, const int *pix, size_t npix);

#endif
