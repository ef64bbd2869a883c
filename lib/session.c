/* fogpipe: frames in memory (lib/session.h), what the public API's
 * fogpipe_apply and fogpipe_apply_deep run: the pipeline's run
 * (lib/pipeline.h) for each frame, the fog layers of --aov handed out
 * whatever the options say. */
#include "session.h"
#include "pipeline.h"

#include "aov.h"
#include "fp.h"

#include <stdlib.h>

struct fp_session_t {
    fp_run_t *r;
    fp_params_t *p;
};

int fp_session_open(fp_params_t *p, fp_session_t **out)
{
    *out = NULL;
    fp_session_t *s = calloc(1, sizeof *s);
    if (!s)
        return fp_error("out of memory");
    s->p = p;
    int rc = fp_run_open(p, &s->r);
    if (rc) {
        free(s);
        return rc;
    }
    *out = s;
    return FP_OK;
}

int fp_session_frame(fp_session_t *s, const fp_frame_info_t *info, float *rgba,
                     const float *depth, const char *name, long frame, float *fog_rgba,
                     float *transmittance)
{
    fp_camera_t cam;
    int rc = fp_camera_resolve(s->p, info, name, frame, &cam);
    if (rc)
        return rc;
    size_t n = (size_t)info->width * info->height;
    float *fog = malloc(n * 4 * sizeof *fog);
    if (!fog)
        return fp_error("%s: frame %ld: out of memory", name, frame);
    fp_color_frame_t color;
    rc = fp_run_composite(s->r, &cam, info, rgba, depth, name, frame, fog,
                          fog_rgba || transmittance, &color);
    if (rc == FP_OK && (fog_rgba || transmittance)) {
        /* The layers of --aov, whatever the options say. */
        fp_params_t q = *s->p;
        q.aov.aov = 1;
        fp_aov_frame_t a;
        if ((rc = fp_aov_make(&q, &color, fog, n, name, frame, &a)) == FP_OK) {
            for (size_t i = 0; i < n; i++)
                for (int c = 0; c < 4; c++) {
                    if (fog_rgba)
                        fog_rgba[4 * i + c] = a.planes[(size_t)c * n + i];
                    if (transmittance && c < 3)
                        transmittance[3 * i + c] = a.planes[(size_t)(4 + c) * n + i];
                }
            fp_aov_free(&a);
        }
    }
    free(fog);
    return rc;
}

int fp_session_deep(fp_session_t *s, const fp_frame_info_t *info, const float *rgba,
                    const float *depth, const char *name, long frame, fp_deep_image_t **out)
{
    fp_params_t q = *s->p;
    q.deep.deep = 1;
    fp_deep_data_t dd;
    fp_camera_t cam;
    fp_color_frame_t color;
    int rc = fp_deep_commit(&q, &dd);
    if (rc == FP_OK && (rc = fp_camera_resolve(s->p, info, name, frame, &cam)) == FP_OK)
        rc = fp_run_deep(s->r, &dd, &cam, info, rgba, depth, name, frame, &color, out);
    return rc;
}

void fp_session_close(fp_session_t *s)
{
    if (!s)
        return;
    fp_run_close(s->r);
    free(s);
}
