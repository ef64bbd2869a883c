/* fogpipe: the frame pipeline.  Reads each frame (file sequence or stdin
 * stream), resolves its camera, computes the fog layer (OpenCL, or the C
 * reference with --cpu), composites and writes the frame atomically (file)
 * or whole (stdout stream); the frames go through src/frameloop.c, which
 * reads, computes and writes on three threads. */
#ifndef FP_PIPELINE_H
#define FP_PIPELINE_H

#include "params.h"

/* Returns FP_OK, FP_ERR (runtime error), FP_EUSAGE, or FP_ESIGNAL + the
 * signal number when SIGINT or SIGTERM stopped the run (src/frameloop.h). */
int fp_pipeline_run(fp_params_t *p);

#endif
