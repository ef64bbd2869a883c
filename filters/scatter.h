/* fogpipe stage "scatter": light in the fog.  Single scattering of the
 * ambient light, the sun (phase function, shadow map or screen-space
 * shadows, fog self-shadowing) and local point and spot lights, integrated
 * along each view ray (kernels/scatter_core.h, with the shared pieces in
 * kernels/light_core.h).  CPU reference in double (fp_scatter_process),
 * OpenCL in single precision (fp_scatter_process_cl, kernels/scatter.cl).
 * The Monte Carlo reference (filters/reference.h) reads the same data. */
#ifndef FP_SCATTER_H
#define FP_SCATTER_H

#include "camera.h"
#include "clrt.h"
#include "integrate.h"
#include "params.h"
#include "options.h"

#include <stddef.h>

#define FP_LT_COUNT_ 795   /* kernels/light_core.h FP_LT_COUNT */
#define FP_LL_STRIDE_ 28   /* kernels/light_core.h FP_LL_STRIDE: reals per light */

/* Add a light to the run's (any number, up to FP_MAX_LIGHTS): --light
 * and the frame's rig go through here.  The light is checked (kind,
 * finite numbers, non-negative color and intensity, a direction, cone
 * angles, an area's axes and sizes); FP_OK, or an error naming what is
 * wrong with it ("light N: ..."), l unchanged.  The storage grows as
 * needed and is freed by fp_light_clear (fp_options_free calls it). */
int fp_light_append(fp_light_params_t *l, const fp_light_t *li);
void fp_light_clear(fp_light_params_t *l);
#define FP_SCATTER_MAX_STEPS 256

/* Per run (commit) and per frame (fp_scatter_frame): the light parameters
 * and the frame's shadow map and self-shadow grid. */
/* What a self-shadow grid (--self-shadow map) was filled from.  The grid
 * is a function of the light parameters, the fog parameters and the
 * fogmap tables alone, so it is filled again only when one of them
 * changed: the depth-edge pass of --fog-edges reuses the frame's, and a
 * still camera over still fog keeps it from frame to frame. */
typedef struct fp_grid_key_t {
    int valid;
    double lt[FP_LT_COUNT_], fp[FP_F_COUNT_];
    unsigned long tables;     /* serial of the fogmap tables (0: none) */
} fp_grid_key_t;

typedef struct fp_scatter_data_t {
    int active;               /* anything beyond ambient fog with albedo 1 */
    double lt[FP_LT_COUNT_];  /* FP_LT_* */
    /* The lights' table, nlights rows of FP_LL_STRIDE_ (kernels/light_core.h
     * FP_LL_*): FP_LT_NLIGHTS local lights, then FP_LT_NDIR directional. */
    double *lights;
    int nlights;
    /* This frame's sun shadow map (--shadow-map), packed by
     * fp_shafts_build: biased z per texel, then its min-max pyramid. */
    float *smap;
    int smap_w, smap_h;
    size_t smap_n;            /* floats in smap */
    /* This frame's self-shadow grid (--self-shadow map): optical depth to
     * the sun at each node. */
    float *grid;
    size_t grid_n;
    fp_grid_key_t grid_key;   /* what grid holds */
    unsigned long serial;     /* changes when smap or grid change (device copies) */
    int lamp_shadows;         /* --lamp-shadows screen with local lights: FP_LT_LS_ON per frame */
    /* The shadow map's depths as read (W x H) and what its packing
     * depended on besides (its projection, the sun, the bias, the up axis,
     * its size): a frame whose map holds the same keeps smap as it is
     * (filters/scatter_frame.c). */
    float *smap_z;
    double smap_key[25];
    unsigned long smap_serial; /* changes when smap changes (0: unknown) */
} fp_scatter_data_t;

/* Check and pack the light options (fog space).  d->active = 0 when the
 * options ask for nothing the integrate stage does not already do.  d is
 * overwritten (fp_scatter_release frees what a commit made). */
int fp_scatter_commit(const fp_params_t *p, fp_scatter_data_t *d);

/* Per frame: the view's projection for screen-space shadows, the shadow
 * map of this frame, the self-shadow grid.  Errors name the file and frame. */
int fp_scatter_frame(const fp_params_t *p, fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                     const fp_view_t *view, const float *depth, long frame);

/* --shadows screen: the depth buffer the walk toward the sun reads, from
 * this view and depth (fp_scatter_frame makes it from its own; nothing
 * otherwise).  The walk takes the buffer's size and pixels from it, not
 * from the view traced, so a strided view (--fog-resolution) and the
 * frame's own pixels (--fog-edges exact) can walk the frame's full-
 * resolution depth buffer alike: made again from that after
 * fp_scatter_frame on the strided view. */
int fp_scatter_screen(fp_scatter_data_t *d, const fp_view_t *view, const float *depth,
                      long frame);

void fp_scatter_release(fp_scatter_data_t *d);

/* The view ray's fog layer in double precision: S (3) and returns tau. */
double fp_scatter_ray(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                      const fp_view_t *v, const float *view_packed, const float *depth,
                      const double o[3], const double dir[3], double len, double S[3]);

/* The same with the samples along the ray shifted by `offset` of a
 * segment (interleaved sampling, fp_interleave_offset). */
double fp_scatter_ray_at(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                         const fp_view_t *v, const float *view_packed, const float *depth,
                         const double o[3], const double dir[3], double len, double offset,
                         double S[3]);

/* Brute force for the sun's share of one ray (issue 13's judge):
 * int sigma tau V tau_sun dt over the ray's fog by the midpoint rule with
 * n steps, the camera's optical depth carried step by step exactly,
 * tau_sun exact per point (when self-shadowing is on), V point-sampled:
 * vis(ctx, p) when given, else the shadow map's texel (fp_shadow_map).  An
 * unbounded ray stops where less than 1e-9 of its light is left. */
double fp_scatter_sun_brute(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                            const double o[3], const double dir[3], double len, long n,
                            double (*vis)(void *ctx, const double p[3]), void *ctx);

/* CPU reference for a whole frame: fog[4*i] = (S.r, S.g, S.b, tau). */
int fp_scatter_process(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                       const fp_view_t *v, const float *depth, float *out);
/* The npix pixels pix[] of the frame (indices y * width + x; depth is the
 * whole frame's) into out[4*k], list order: the same values
 * fp_scatter_process gives them.  pix NULL: all pixels in order. */
int fp_scatter_pixels(const fp_scatter_data_t *d, const fp_integrate_data_t *fog,
                      const fp_view_t *v, const float *depth, const int *pix, size_t npix,
                      float *out);

typedef struct fp_scatter_cl_t {
    fp_cl_t *cl;
    cl_kernel kernel, grid_kernel, light_kernel, ls_kernel;
    cl_mem lt, smap, grid, lights;
    size_t lights_n;          /* floats the device's light table holds */
    fp_grid_key_t grid_key;   /* what grid holds */
    size_t grid_n;
    unsigned long uploaded;   /* serial of smap/grid on the device */
    unsigned long smap_uploaded; /* smap_serial of smap on the device (0: none) */
} fp_scatter_cl_t;

/* The OpenCL version shares the integrate stage's buffers (depth, fog
 * layer, view, fog parameters and tables). */
int fp_scatter_cl_init(fp_cl_t *cl, fp_scatter_cl_t *s);
int fp_scatter_process_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                          const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                          float *out);
/* As fp_scatter_pixels, on the device (pix NULL: the whole frame). */
int fp_scatter_pixels_cl(fp_scatter_cl_t *s, fp_integrate_cl_t *ic, const fp_scatter_data_t *d,
                         const fp_integrate_data_t *fog, const fp_view_t *v, const float *depth,
                         const int *pix, size_t npix, float *out);
void fp_scatter_cl_release(fp_scatter_cl_t *s);

/* ---- Shared by the stage's files (filters/scatter.c: the options, the
 * commit, the C reference, the lights' parsing, checks and table;
 * filters/scatter_frame.c: the per-frame shadow map, depth buffer and
 * self-shadow grid bounds; filters/scatter_cl.c: the OpenCL launch), not
 * by the other stages. */

/* --light's option setter (the row in fp_scatter_options). */
int fp_scatter_set_light(fp_params_t *p, const fp_option_t *o, const char *value);

/* The lights' table (kernels/light_core.h FP_LL_*) in d->lights, fog
 * space, local lights first; d->nlights, FP_LT_NLIGHTS and FP_LT_NDIR. */
int fp_scatter_pack_lights(const fp_params_t *p, fp_scatter_data_t *d);

/* Whether d looks up a self-shadow grid, and its number of nodes. */
int fp_scatter_uses_grid(const fp_scatter_data_t *d);
size_t fp_scatter_grid_nodes(const double *lt);

/* 1 when the grid filled from k is the one d and fog ask for; else k
 * becomes theirs (the caller fills the grid, and clears k->valid if that
 * fails). */
int fp_scatter_grid_current(fp_grid_key_t *k, const fp_scatter_data_t *d,
                            const fp_integrate_data_t *fog);

/* Unit vector in place (v non-zero). */
void fp_scatter_normalize3(double v[3]);

#endif
