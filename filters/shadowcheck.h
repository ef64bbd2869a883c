/* fogpipe: is the user's sun shadow map fine enough for its casters?
 *
 * Against Cycles (issue 23), casters under about 4 texels across lose
 * their shafts along grazing rays (a 0.35 m pillar in a 0.25 m map: fog
 * up to 180% too bright beside it), and results reach Cycles' noise at
 * about 8 texels across the thinnest caster.  The same holds for gaps
 * (slits) the shafts come through.  This finds the thinnest of both in a
 * depth map and says what map would hold them.
 *
 * The measure.  Along each row and each column (both ways), a caster is
 * a run of texels in front of the texels on both its sides by more than a
 * depth step (a discontinuity: more than the surface under the sun can
 * change over a texel or two), found with a stack of open runs, so a
 * pillar in front of a wall is its own run inside the wall's.  Of runs
 * that end at the same edge only the outermost counts, and a texel's
 * width along an axis is the larger of the two directions' (a surface
 * seen at grazing angle from the sun falls away in steps, each a
 * "run" from one side only).  A gap is the same of -z (nothing seen:
 * infinitely far).  A texel's width is the smaller of its widths along
 * the map's x and y; texels narrower than FP_SHADOWCHECK_TEXELS form
 * 4-connected features, and a feature counts when it is long for its
 * width (at least 4 texels, and twice its median width): a caster's
 * silhouette, not the tip of a roof or the corner of a box, where rows
 * cross a wide object narrowly for a few texels; and at least 1/128 of
 * the map's side (a sliver of a 4096-texel map 7 texels long is 1/600 of
 * what the map covers: no shaft to speak of). */
#ifndef FP_SHADOWCHECK_H
#define FP_SHADOWCHECK_H

#include <stddef.h>

/* Texels across the thinnest caster that Cycles' noise is reached at. */
#define FP_SHADOWCHECK_TEXELS 8

typedef struct fp_smap_thin_t {
    int found;            /* a feature narrower than FP_SHADOWCHECK_TEXELS */
    int width;            /* its median width, texels */
    double width_units;   /* the same in scene units (the texel along its axis) */
    double x, y;          /* its centroid, texel coordinates (x right, y down) */
    int length;           /* its extent, texels (the longer side of its box) */
    int axis;             /* 0: measured along the map's x, 1: along its y */
    long count;           /* features narrower than FP_SHADOWCHECK_TEXELS */
} fp_smap_thin_t;

typedef struct fp_smap_report_t {
    int w, h;
    double texel[2];      /* scene units per texel along the map's x and y */
    double step;          /* depth step taken as a discontinuity, scene units */
    fp_smap_thin_t caster, gap;
} fp_smap_report_t;

/* The report of a w x h depth map z (the sun camera's z, +inf/NaN:
 * nothing seen), texel_x, texel_y scene units per texel, step the depth
 * step (scene units) that separates a caster from what is behind it.
 * Returns 0, or -1 when out of memory. */
int fp_shadowcheck(const float *z, int w, int h, double texel_x, double texel_y, double step,
                   fp_smap_report_t *r);

/* The texel size (scene units, the larger of the two axes' if
 * different: a square map over the same area) that holds the feature t
 * FP_SHADOWCHECK_TEXELS texels across, and the map size that it takes
 * over the area of r. */
double fp_shadowcheck_needed(const fp_smap_report_t *r, const fp_smap_thin_t *t, long *w,
                             long *h);

/* One frame's map, as fp_scatter_frame loads it: the report under -v,
 * and when casters or gaps narrower than FP_SHADOWCHECK_TEXELS are found,
 * one warning per process (the first frame that has them; later frames'
 * maps are only checked under -v).  ndc (16) and cz (4): the map's
 * projection from fog space as the light parameters pack it
 * (FP_LT_SM_NDC: texel coordinates over W and H, FP_LT_SM_Z: the map's
 * z), up the world's up axis (FP_UP_*): where a feature is, in world
 * coordinates. */
void fp_shadowcheck_frame(const char *path, long frame, const float *z, int w, int h,
                          double texel_x, double texel_y, double step, const double *ndc,
                          const double *cz, int up);

/* A look that wants the sun's shadow map (a preset's "wants =
 * shadow-map") fogged without one (has_map 0) and without --shadows
 * chosen: one warning per process naming the preset, what to give, and
 * that its sun is the sample scene's (a frame's rig or --sun replaces
 * it). */
struct fp_params_t;
void fp_shadowcheck_wants(const struct fp_params_t *p, int has_map);

#endif
