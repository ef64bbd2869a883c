/* fogpipe: the rig applied to a run and to a frame's parameters
 * (lib/rig_apply.c).  Above the stages: applying a rig appends the light
 * stage's lights (fp_light_append, filters/scatter.h) and a look sets any
 * stage's options (fp_options_apply_look); the rig itself, read from a
 * frame or a file, is src/scene/rig.h. */
#ifndef FP_RIG_APPLY_H
#define FP_RIG_APPLY_H

#include <stdint.h>
#include <stdio.h>

#include "params.h"
#include "rig.h"

/* The run's up axis and look, before anything is committed: from the rig
 * file, else the first frame's rig (`first`, may be NULL: a stream).  Sets
 * p->camera.up when --up is not given, applies the look under the command
 * line and --preset (fp_options_apply_look). */
int fp_rig_prescan(fp_params_t *p, const fp_rig_file_t *file, const fp_rig_t *first,
                   const char *first_name, long first_frame);

/* --rig FILE loaded into *file (NULL without), then fp_rig_prescan with
 * the first input frame's rig (a file input's header read once more; its
 * errors, if any, are the frame loop's to report).  *has_rig: the file or
 * that frame carries a rig. */
int fp_rig_run_setup(fp_params_t *p, fp_rig_file_t **file, int *has_rig);
/* A single input file's frame number: --frame, else the number its name
 * ends with (fp_seq_frame_of_name), else 1. */
long fp_rig_single_frame(const fp_params_t *p);

/* The frame's parameters: *q = *base with the rig applied under the flags
 * (schema precedence): clip start, the brightest sun as --sun/--sun-color/
 * --sun-intensity, further suns as directional lights, local lights
 * (fp_light_append), the shadow map (relative to the frame file's
 * directory).  q's strings are base's or the rig's: q lives no longer than
 * either, and is released with fp_rig_params_release, never
 * fp_options_free. */
int fp_rig_apply(const fp_params_t *base, const fp_rig_t *rig, const char *where_file,
                 long frame, fp_params_t *q);
void fp_rig_params_release(fp_params_t *q);

/* A key of what the light stage is committed from (sun, lights, shadow
 * map, up): equal keys, the same commit. */
uint64_t fp_rig_light_key(const fp_params_t *q);

/* The warnings of the light stage's commits, one per change of the rig
 * (an animated lamp): each said once a run.  fp_rig_seen returns 1 when
 * the text was seen before, else records it (up to FP_RIG_SEEN_MAX). */
#define FP_RIG_SEEN_MAX 32
typedef struct fp_rig_seen_t {
    uint64_t h[FP_RIG_SEEN_MAX];
    int n;
} fp_rig_seen_t;
int fp_rig_seen(fp_rig_seen_t *s, const char *text, int len);

/* --print-camera: the rig understood for the frame, after the flags. */
void fp_rig_print(FILE *out, const fp_rig_t *rig, const fp_params_t *q);

#endif
