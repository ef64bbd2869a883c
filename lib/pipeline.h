/* fogpipe: the frame pipeline.  Reads each frame (file sequence or stdin
 * stream), resolves its camera, computes the fog layer (OpenCL, or the C
 * reference with --cpu), composites and writes the frame atomically (file)
 * or whole (stdout stream); the frames go through lib/frameloop.c, which
 * reads, computes and writes on three threads. */
#ifndef FP_PIPELINE_H
#define FP_PIPELINE_H

#include "camera.h"
#include "color.h"
#include "deep.h"
#include "exr_deep.h"
#include "exrio.h"
#include "params.h"

/* Returns FP_OK, FP_ERR (runtime error), FP_EUSAGE, or FP_ESIGNAL + the
 * signal number when SIGINT or SIGTERM stopped the run (lib/frameloop.h). */
int fp_pipeline_run(fp_params_t *p);

/* The run as frames in memory use it (lib/session.c): set up, colour
 * committed, device open. */
typedef struct run_t fp_run_t;
int fp_run_open(fp_params_t *p, fp_run_t **out);
/* The fog of one frame composited into rgba (in place); `fog` receives
 * the fog layer (n x 4), `color` the frame's colour when want_layers. */
int fp_run_composite(fp_run_t *r, const fp_camera_t *cam, const fp_frame_info_t *info,
                     float *rgba, const float *depth, const char *name, long frame, float *fog,
                     int want_layers, fp_color_frame_t *color);
/* The frame as deep samples (dd from fp_deep_commit). */
int fp_run_deep(fp_run_t *r, const fp_deep_data_t *dd, const fp_camera_t *cam,
                const fp_frame_info_t *info, const float *rgba, const float *depth,
                const char *name, long frame, fp_color_frame_t *color, fp_deep_image_t **out);
void fp_run_close(fp_run_t *r);

#endif
