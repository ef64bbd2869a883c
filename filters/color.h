/* fogpipe stage "color": color management through OpenColorIO.
 *
 * Three color spaces per frame (README, "Color"):
 *   input   -- the plate's color as read (--input-space; default: the space
 *              the EXR's chromaticities attribute identifies, else the
 *              config's scene_linear role);
 *   working -- where the fog is computed and composited, and where
 *              --fog-color is given (--working-space; default: the input's);
 *              it must be linear;
 *   output  -- what is written (--output-space; default: the input's).
 * The plate goes input -> working before the composite, the composite (and
 * the fog layers) working -> output after it.  Alpha, depth, fogmaps and
 * pass-through channels are data and never converted.
 *
 * With no color option at all OpenColorIO is not even loaded, and with all
 * three spaces the same nothing is converted: pixels are bit-identical to a
 * run without color management.
 *
 * Thread safety: after fp_color_commit, fp_color_frame and the apply
 * functions may run from several threads at once. */
#ifndef FP_COLOR_H
#define FP_COLOR_H

#include <pthread.h>
#include <stddef.h>
#include <stdio.h>

#include "exrio.h"
#include "ocio_bridge.h"
#include "params.h"

#define FP_COLOR_NAME 256
#define FP_COLOR_CACHE 32

/* A space's matrix to the config's aces_interchange space, found by
 * probing its processor (only for spaces where that is a matrix). */
typedef struct fp_color_space_t {
    char name[FP_COLOR_NAME];
    double to_ref[9];           /* row-major, ref = M * rgb */
} fp_color_space_t;

typedef struct fp_color_t {
    int active;                 /* OpenColorIO loaded (some color option given) */
    fp_ocio_t *ocio;
    char in[FP_COLOR_NAME], work[FP_COLOR_NAME], out[FP_COLOR_NAME];  /* "" = default */
    char scene_linear[FP_COLOR_NAME];                                  /* "" = no such role */
    char ref[FP_COLOR_NAME];    /* aces_interchange ("" = none: no chromaticities) */
    char display[FP_COLOR_NAME], view[FP_COLOR_NAME];
    int preview;                /* make a display processor per frame */
    int aov;                    /* fog layers requested (the output must be linear) */

    /* Filled lazily (first frame with chromaticities), under `lock`. */
    pthread_mutex_t lock;
    int lock_ok;
    int scanned;
    fp_color_space_t *spaces;   /* linear spaces of the config, scene_linear's first */
    int nspaces;
    int warned_ids;             /* unidentified chromaticities already reported */
    struct {
        char src[FP_COLOR_NAME], dst[FP_COLOR_NAME], view[FP_COLOR_NAME];
        fp_ocio_proc_t *proc;
    } cache[FP_COLOR_CACHE];
    int ncache;
} fp_color_t;

/* One frame's spaces and conversions.  Points into its fp_color_t. */
typedef struct fp_color_frame_t {
    const char *in, *work, *out;        /* NULL when inactive */
    const fp_ocio_proc_t *to_work;      /* NULL: nothing to do */
    const fp_ocio_proc_t *to_out;
    const fp_ocio_proc_t *to_display;   /* for --preview */
    int set_chromaticities;             /* as fp_exr_write_opts_t */
    float chromaticities[8];
} fp_color_frame_t;
#define FP_COLOR_FRAME_INITIALIZER { NULL, NULL, NULL, NULL, NULL, NULL, 0, { 0 } }


/* Load the config and check every name given (a usage error lists valid
 * names), once per run.  Nothing is loaded when no color option is set and
 * no preview is asked for. */
int fp_color_commit(const fp_params_t *p, fp_color_t *c);
/* The spaces and processors of one frame (its chromaticities may choose
 * the input space). */
int fp_color_frame(fp_color_t *c, const fp_frame_info_t *info, const char *where, long frame,
                   fp_color_frame_t *cf);
/* Plate input -> working; composite working -> output (RGB of n RGBA
 * pixels, alpha untouched).  No-ops when nothing is to be converted. */
void fp_color_to_working(const fp_color_frame_t *cf, float *rgba, size_t n);
void fp_color_to_output(const fp_color_frame_t *cf, float *rgba, size_t n);
/* The chromaticities attribute of the output (see fp_exr_write_opts_t). */
void fp_color_write_opts(const fp_color_frame_t *cf, fp_exr_write_opts_t *w);
void fp_color_release(fp_color_t *c);

/* --list-spaces: describe the config that would be used. */
int fp_color_list(const fp_params_t *p, FILE *out);

/* Chromaticities (red x,y, green x,y, blue x,y, white x,y) -> the matrix
 * from those RGB values to ACES2065-1 (AP0 primaries, ACES white), with a
 * Bradford adaptation from their white to the ACES white, as OpenColorIO's
 * built-in *_BFD transforms do.  Non-zero for degenerate chromaticities. */
int fp_color_chromaticities_to_ap0(const double chr[8], double m[9]);
/* The config's linear space whose matrix to aces_interchange matches the
 * chromaticities (within 2e-3 per element), or NULL; scene_linear first. */
const char *fp_color_identify(fp_color_t *c, const float chr[8]);
/* The standard chromaticities (Rec.709, P3-D65, Rec.2020, ACES AP0, AP1)
 * matching a space's matrix; non-zero when none does. */
int fp_color_space_chromaticities(fp_color_t *c, const char *space, float chr[8]);

#endif
