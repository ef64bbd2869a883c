/* fogpipe: the fogmap image's values checked (filters/fogmap_image.h). */
#include "fogmap_image.h"
#include "fp.h"

#include <math.h>
#include <stddef.h>

void fp_fogmap_clamp_negative(const char *name, float *img, int w, int h)
{
    size_t count = 0, n = (size_t)w * h;
    float lowest = 0;
    for (size_t i = 0; i < n; i++)
        if (img[i] < 0) {
            count++;
            lowest = fminf(lowest, img[i]);
            img[i] = 0;
        }
    if (count)
        fp_warn("%s: %zu pixels below 0 (the lowest %g) clamped to 0: density cannot be "
                "negative", name, count, lowest);
}

/* Seed 000's wavelet levels are sums of positive and negative details kept
 * in single precision, so each level's rounding error is about 1e-7 of the
 * fogmap's largest value: a value whose optical depth across one fogmap
 * pixel is 1e4 (opaque many times over) already moves tau elsewhere by
 * 1e-3, and larger ones give tau > 1, inf and NaN.  Refused with the
 * figures, so that a corrupt fogmap is not a frame of NaN. */
#define FP_FOGMAP_OD_PER_PIXEL_MAX 1e4

double fp_fogmap_od_scale(const fp_params_t *p, int w, int h)
{
    const double *r = p->fogmap.rect;
    return p->fog.density * fmin((r[2] - r[0]) / w, (r[3] - r[1]) / h);
}

int fp_fogmap_check_values(const char *name, const float *img, int w, int h, double od_scale)
{
    for (size_t i = 0; i < (size_t)w * h; i++) {
        size_t x = i % (size_t)w, y = i / (size_t)w;
        if (!(img[i] >= 0) || isinf(img[i]))
            return fp_error("%s: pixel (%zu, %zu) is %g (expected finite values >= 0)", name, x,
                            y, img[i]);
        if (img[i] * od_scale > FP_FOGMAP_OD_PER_PIXEL_MAX)
            return fp_error("%s: pixel (%zu, %zu) is %g: at this --density and --fog-rect its "
                            "optical depth across one fogmap pixel is %.3g (expected at most %g; "
                            "the fog is opaque long before, and larger values spoil the "
                            "single-precision wavelet levels)", name, x, y, img[i],
                            img[i] * od_scale, FP_FOGMAP_OD_PER_PIXEL_MAX);
    }
    return FP_OK;
}
