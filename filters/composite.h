/* fogpipe stage "composite": out = tau * color + S (seed 000 eq. 4 with the
 * in-scatter S of the integrate stage), alpha kept.  Runs on the host: it
 * is one multiply-add per channel, bound by memory, and the colour plate
 * never needs to travel to the device. */
#ifndef FP_COMPOSITE_H
#define FP_COMPOSITE_H

#include <stddef.h>

/* rgba_in/rgba_out: n pixels of RGBA (may alias); fog: n of (S.rgb, tau). */
void fp_composite_process(const float *rgba_in, const float *fog, size_t n, float *rgba_out);

#endif
