/* fogpipe stage "integrate": extinction integrated exactly along each view
 * ray (kernels/fog_core.h, shared by the kernel and the C reference), and
 * the fog layer (in-scattered light S, transmittance tau) that the
 * composite stage applies.  CPU reference in double (fp_integrate_process),
 * OpenCL in single precision (fp_integrate_process_cl, kernels/integrate.cl). */
#ifndef FP_INTEGRATE_H
#define FP_INTEGRATE_H

#include "camera.h"
#include "clrt.h"
#include "params.h"

#define FP_F_COUNT_ 80   /* kernels/fog_core.h FP_F_COUNT */
#define FP_LEVEL_TABLE 16  /* FP_MAX_LEVELS_ALL */

/* The fogmap as the integrator reads it (filled by the fogmap stage):
 * per level a table row and coefficients; the last level is the fine grid
 * (the padded fogmap itself), used by the marching baseline. */
typedef struct fp_fog_tables_t {
    int nlevels;                          /* levels summed by the exact integrator */
    int lvi[FP_LEVEL_TABLE * 8];          /* FP_LI_* rows */
    double lvf[FP_LEVEL_TABLE * 8];       /* FP_LR_* rows */
    float *coef;                          /* all levels' coefficients */
    size_t ncoef;
    unsigned char *occ;                   /* occupancy blocks of all levels */
    size_t nocc;
    unsigned long serial;                 /* unique per table set, so a device copy is
                                             never mistaken for another's */
} fp_fog_tables_t;

/* The tables, or an empty set for fog without a fogmap (the shared kernel
 * code and the device buffers take pointers either way), and the
 * arguments the kernels' C versions take. */
const fp_fog_tables_t *fp_fog_tables_or_empty(const fp_fog_tables_t *t);
/* Memory for a table (coef, occ) of n bytes, page-aligned so that a device
 * working in the host's memory (PoCL's CPU device) uses it as is, without a
 * copy of its own (fp_integrate_cl_prepare: CL_MEM_USE_HOST_PTR, the tables
 * then outliving the device's buffers); free() frees it.  NULL when out of
 * memory. */
void *fp_fog_tables_alloc(size_t n);
#define FP_TABLES3(t) (t)->lvi, (t)->lvf, (t)->coef
#define FP_TABLES(t) FP_TABLES3(t), (t)->occ

/* Derived once per run from the parameters (darktable's "commit"). */
typedef struct fp_integrate_data_t {
    double fp[FP_F_COUNT_];               /* FP_F_* parameters */
    double fog_color[3];
    const fp_fog_tables_t *tables;        /* NULL: no fogmap */
} fp_integrate_data_t;

/* Fill everything but the fogmap-specific entries (fp_fogmap_commit adds
 * those and sets `tables`). */
int fp_integrate_commit(const fp_params_t *p, fp_integrate_data_t *d);

/* --fog-offset (world axes) in fog space. */
void fp_integrate_fog_offset(const fp_params_t *p, double off[3]);

/* Optical depth along a fog-space ray, t in [0, len] (len may be INFINITY),
 * in double precision. */
double fp_integrate_optical_depth(const fp_integrate_data_t *d, const double o[3],
                                  const double dir[3], double len, double jitter);

/* The per-pixel jitter of --jitter, identical to the kernel's. */
float fp_integrate_jitter(int x, int y);

/* CPU reference for a whole frame: fog[4*i] = (S.r, S.g, S.b, tau).
 * *suspicious counts NaN/negative depth samples (treated as sky). */
int fp_integrate_process(const fp_integrate_data_t *d, const fp_view_t *v,
                         const float *depth, float *fog, long *suspicious);

/* CPU reference for the npix pixels pix[] of the frame (indices
 * y * width + x; depth is the whole frame's): fog[4*k] for pixel pix[k],
 * the same values fp_integrate_process gives them.  pix NULL: all pixels
 * in order (npix = width * height). */
int fp_integrate_pixels(const fp_integrate_data_t *d, const fp_view_t *v, const float *depth,
                        const int *pix, size_t npix, float *fog);

/* OpenCL state kept across frames (program, kernel, buffers). */
typedef struct fp_integrate_cl_t {
    fp_cl_t *cl;
    cl_kernel kernel;
    cl_kernel height, height_list;        /* fog without a fogmap: branch-free, SIMD on PoCL */
    cl_kernel height_over;                /* the same, composited over the plate in place */
    cl_kernel fogmap, fogmap_list;        /* a linear fogmap walked exactly, 16 rays a work-item */
    int no_lanes;                         /* tests: integrate_fog even where integrate_fogmap
                                             would do */
    cl_mem depth, fog, view, params, lvi, lvf, coef, occ;
    cl_mem pix;                           /* the pixel list of a list launch */
    size_t capacity;      /* pixels the buffers hold */
    size_t pix_capacity;  /* entries the pixel list buffer holds */
    unsigned long uploaded;               /* serial of the tables on the device (0: none) */
    size_t host_align;    /* the device works in the host's memory: the alignment
                           * at which it takes a host buffer as is (0: it does not) */
} fp_integrate_cl_t;

int fp_integrate_cl_init(fp_cl_t *cl, fp_integrate_cl_t *s);
/* Buffers sized for the view, fogmap tables, view, parameters and (if not
 * NULL) depth on the device: what every per-pixel fog kernel reads. */
int fp_integrate_cl_prepare(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                            const fp_view_t *v, const float *depth);
/* Run a per-pixel fog kernel whose first twelve arguments are (depth, fog
 * layer, view, width, height, parameters, lvi, lvf, coef, occ, pixel
 * list, its length) on the buffers fp_integrate_cl_prepare filled (the
 * caller sets the others), and read the fog layer back into `fog`: the
 * whole frame (pix NULL), or the npix pixels pix[] (indices y * width + x)
 * into fog[4*k], list order. */
int fp_integrate_cl_launch(fp_integrate_cl_t *s, cl_kernel k, const fp_view_t *v, const int *pix,
                           size_t npix, float *fog, const char *what);
int fp_integrate_process_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                            const fp_view_t *v, const float *depth, float *fog);
/* As fp_integrate_pixels, on the device. */
/* Whether integrate_fogmap (16 rays a work-item, kernels/fogmap_lanes.h)
 * computes this look's layer: a linear fogmap walked exactly from a
 * perspective camera, wrap zero or repeat. */
int fp_integrate_lanes_ok(const fp_integrate_data_t *d, const fp_view_t *v);
int fp_integrate_pixels_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                           const fp_view_t *v, const float *depth, const int *pix, size_t npix,
                           float *fog);
/* Fog without a fogmap into the device's fog layer (s->fog) on the buffers
 * fp_integrate_cl_prepare filled, not read back, for a stage that adds to
 * it there (filters/scatter_cl.c): the kernel of fp_integrate_pixels_cl
 * with S = (1 - tau) color.  No fogmap, a perspective view without a clip
 * plane. */
int fp_integrate_height_layer_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                                 const fp_view_t *v, const int *pix, size_t npix,
                                 const double color[3]);
/* Fog without a fogmap composited over the plate on the device, in place:
 * rgba (RGBA, the working space) becomes tau * rgb + S per pixel, alpha
 * kept, bit for bit what fp_integrate_pixels_cl and fp_composite_process
 * give, without the fog layer.  Only where fp_integrate_over_ok: the
 * device works in the host's memory, rgba aligned as it wants, no fogmap,
 * a perspective view. */
int fp_integrate_over_ok(const fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                         const fp_view_t *v, const float *rgba);
int fp_integrate_over_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d, const fp_view_t *v,
                         const float *depth, float *rgba);
void fp_integrate_cl_release(fp_integrate_cl_t *s);

#endif
