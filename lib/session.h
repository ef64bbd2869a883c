/* fogpipe: frames in memory (lib/session.c over the pipeline's run,
 * lib/pipeline.h), what the public API's fogpipe_apply and
 * fogpipe_apply_deep run. */
#ifndef FP_SESSION_H
#define FP_SESSION_H

#include "exr_deep.h"
#include "exrio.h"
#include "params.h"

/* Frames held in memory (the library's fogpipe_apply): a session keeps the
 * device, programs, fogmap and color processors of `p` (which must outlive
 * it and not change) across frames. */
typedef struct fp_session_t fp_session_t;
int fp_session_open(fp_params_t *p, fp_session_t **out);
/* Fog and composite `rgba` (info->width x height RGBA) in place with
 * `depth`; the fog layers of --aov into fog_rgba (n*4) and transmittance
 * (n*3) when not NULL.  Messages name `name` and `frame`. */
int fp_session_frame(fp_session_t *s, const fp_frame_info_t *info, float *rgba,
                     const float *depth, const char *name, long frame, float *fog_rgba,
                     float *transmittance);
/* The fog of `rgba` (the input space) and `depth` as deep samples, as
 * --deep makes them whatever the options say (filters/deep_frame.h);
 * *out is the caller's (fp_deep_free). */
int fp_session_deep(fp_session_t *s, const fp_frame_info_t *info, const float *rgba,
                    const float *depth, const char *name, long frame, fp_deep_image_t **out);
void fp_session_close(fp_session_t *s);

#endif
