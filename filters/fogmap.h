/* fogpipe stage "fogmap": the wavelet fogmap (seed 000): load the image
 * (OpenImageIO, as data), decompose it into B-spline wavelet levels
 * (filters/wavelet.c, OpenCL or the C reference), and lay the levels out
 * for the integrator (coefficients, level table, occupancy blocks for
 * sparse skipping). */
#ifndef FP_FOGMAP_H
#define FP_FOGMAP_H

#include "clrt.h"
#include "fogmap_image.h"
#include "integrate.h"
#include "params.h"
#include "wavelet.h"

struct fp_animate_t;

typedef struct fp_fogmap_stage_t {
    fp_fogmap_t map;          /* the decomposition made at commit (the still fogmap, or the
                                 first key of a sequence) */
    fp_fog_tables_t tables;   /* what the integrator reads (d->tables points here) */
    fp_fog_tables_t prev;     /* the previous frame's tables, freed one frame later, so a
                                 frame still in flight keeps its coefficients */
    double decompose_ms;      /* time of the decompositions: at commit, then of each frame
                                 (0 for a frame that needed none) */
    double animate_ms;        /* time of the fogmap's whole per-frame work (decomposition,
                                 advection, turbulence, tables); 0 when nothing animates */
    int decompositions;       /* decompositions done for the last frame */
    int used_cl;              /* the last decomposition ran in OpenCL */
    double cell_to_fog;
    struct fp_animate_t *anim; /* NULL when the fogmap does not change per frame */
} fp_fogmap_stage_t;

/* Load and decompose --fogmap (nothing when it is not set: *active = 0),
 * fill the fogmap entries of `d` and point it at the tables.  A sequence
 * (--fogmap fog.####.png), --turbulence or --advect make the fogmap change
 * per frame (filters/animate.h): its first key, or the still fogmap, is
 * decomposed here and every frame's in fp_fogmap_frame.  `cl` may be NULL
 * (C reference). */
int fp_fogmap_commit(const fp_params_t *p, fp_cl_t *cl, fp_fogmap_stage_t *s,
                     fp_integrate_data_t *d, int *active);

/* The same from pixels in memory (w x h, row 0 at the fogmap's first row):
 * what fp_fogmap_commit does after loading, without animation. */
int fp_fogmap_setup(const fp_params_t *p, fp_cl_t *cl, const float *img, int w, int h,
                    fp_fogmap_stage_t *s, fp_integrate_data_t *d);

/* Animate a stage set up by fp_fogmap_setup from `img` (what
 * fp_fogmap_commit does for an animated fogmap; for the tests). */
int fp_fogmap_animate(const fp_params_t *p, const float *img, int w, int h,
                      fp_fogmap_stage_t *s, const fp_integrate_data_t *d);

/* Per frame, before the fog is integrated: the parameters that depend on
 * the camera (--lod-footprint), the fog's placement at t = frame / --fps
 * (--wind), and, when the fogmap animates, its decomposition for this
 * frame and new tables (s->decompose_ms, s->animate_ms updated; reported
 * under -v).  Nothing else per frame when nothing animates.  `s` may be
 * NULL (no fogmap stage), `cl` NULL (C reference).  The previous tables
 * stay valid until the next call. */
int fp_fogmap_frame(const fp_params_t *p, fp_cl_t *cl, fp_fogmap_stage_t *s, long frame,
                    const fp_view_t *v, fp_integrate_data_t *d);

/* --fogmap-preview DIR: one PNG per level and the reconstructed fogmap. */
int fp_fogmap_preview(const fp_fogmap_stage_t *s, const char *dir);

void fp_fogmap_release(fp_fogmap_stage_t *s);

#endif
