/* fogpipe stage "aov": see aov.h. */
#include "aov.h"
#include "fp.h"
#include "options.h"

#include <stdlib.h>

#define AO(f) offsetof(fp_params_t, aov.f)
const fp_option_t fp_aov_options[] = {
    { "aov", 0, FP_OPT_FLAG, AO(aov), 0, 0, NULL, 0, 1, NULL, NULL,
      "also write the fog as layers: fog.R/G/B (in-scattered light, premultiplied), fog.A "
      "(1 - mean transmittance), transmittance.R/G/B; fog over the plate = the composite",
      NULL, 0 },
    { "aov-only", 0, FP_OPT_FLAG, AO(aov_only), 0, 0, NULL, 0, 1, NULL, NULL,
      "write only the fog layers of --aov (no color, no other channel)", NULL, 0 },
    FP_OPT_END
};

static const char *const layer_names[FP_AOV_LAYERS] = {
    "fog.R", "fog.G", "fog.B", "fog.A", "transmittance.R", "transmittance.G", "transmittance.B"
};

int fp_aov_make(const fp_params_t *p, const fp_color_frame_t *cf, const float *fog, size_t n,
                const char *where, long frame, fp_aov_frame_t *a)
{
    static const fp_aov_frame_t none = FP_AOV_FRAME_INITIALIZER;
    *a = none;
    if (!p->aov.aov && !p->aov.aov_only)
        return FP_OK;
    a->planes = malloc(n * FP_AOV_LAYERS * sizeof(float));
    if (!a->planes)
        return fp_error("%s: frame %ld: out of memory for the fog layers", where, frame);
    float *pl[FP_AOV_LAYERS];
    for (int k = 0; k < FP_AOV_LAYERS; k++) {
        pl[k] = a->planes + (size_t)k * n;
        a->extra[k].name = layer_names[k];
        a->extra[k].data = pl[k];
    }
    for (size_t i = 0; i < n; i++) {
        const float *f = fog + 4 * i;
        float tau = f[3];
        pl[0][i] = f[0];
        pl[1][i] = f[1];
        pl[2][i] = f[2];
        /* 1 - mean transmittance; the fog's tau is one value (grey). */
        pl[3][i] = 1.0f - tau;
        pl[4][i] = tau;
        pl[5][i] = tau;
        pl[6][i] = tau;
    }
    /* S is light: the same linear map as the composite (working -> output);
     * tau and fog.A are factors, the same in every linear space. */
    if (cf->to_out)
        fp_ocio_apply_planar(cf->to_out, pl[0], pl[1], pl[2], n);
    a->num = FP_AOV_LAYERS;
    return FP_OK;
}

void fp_aov_write_opts(const fp_params_t *p, const fp_aov_frame_t *a, fp_exr_write_opts_t *w)
{
    if (!a->num)
        return;
    w->extra = a->extra;
    w->num_extra = a->num;
    if (p->aov.aov_only) {
        w->color_only = 1;
        w->drop_color = 1;
    }
}

void fp_aov_free(fp_aov_frame_t *a)
{
    free(a->planes);
    a->planes = NULL;
    a->num = 0;
}

void fp_aov_over(const fp_aov_frame_t *a, const float *plate, size_t n, float *out)
{
    const float *pl = a->planes;
    for (size_t i = 0; i < n; i++) {
        float keep = 1.0f - pl[3 * n + i];
        for (int c = 0; c < 3; c++)
            out[4 * i + c] = pl[(size_t)c * n + i] + plate[4 * i + c] * keep;
        out[4 * i + 3] = plate[4 * i + 3];
    }
}
