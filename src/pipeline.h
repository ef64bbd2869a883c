/* fogpipe: the frame pipeline.  Reads each frame (file sequence or stdin
 * stream), resolves its camera, computes the fog layer (OpenCL, or the C
 * reference with --cpu), composites and writes the frame atomically (file)
 * or whole (stdout stream). */
#ifndef FP_PIPELINE_H
#define FP_PIPELINE_H

#include "params.h"

/* Returns the process exit status: 0, 1 (runtime error), 2 (usage). */
int fp_pipeline_run(fp_params_t *p);

#endif
