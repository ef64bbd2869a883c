/* fogpipe stage "integrate": extinction integrated exactly along each view
 * ray, and the fog layer (in-scattered light S, transmittance tau) that the
 * composite stage applies.  CPU reference in double (fp_integrate_process),
 * OpenCL (fp_integrate_process_cl, kernels/integrate.cl). */
#ifndef FP_INTEGRATE_H
#define FP_INTEGRATE_H

#include "camera.h"
#include "clrt.h"
#include "params.h"

/* Derived once per run from the parameters (darktable's "commit"). */
typedef struct fp_integrate_data_t {
    double sigma;         /* extinction per scene unit at full density */
    double y0, H, top;    /* height profile: h = 1 below y0, exp(-(y-y0)/H) to top */
    double fog_color[3];
} fp_integrate_data_t;

int fp_integrate_commit(const fp_params_t *p, fp_integrate_data_t *d);

/* Optical depth along the ray oy + t dy (dy: the unit direction's y),
 * t in [0, len], len may be INFINITY.  Closed form, double precision. */
double fp_integrate_optical_depth(const fp_integrate_data_t *d, double oy, double dy,
                                  double len);

/* CPU reference for a whole frame: fog[4*i] = (S.r, S.g, S.b, tau).
 * *suspicious counts NaN/negative depth samples (treated as sky). */
int fp_integrate_process(const fp_integrate_data_t *d, const fp_view_t *v,
                         const float *depth, float *fog, long *suspicious);

/* OpenCL state kept across frames (program, kernel, buffers). */
typedef struct fp_integrate_cl_t {
    fp_cl_t *cl;
    cl_kernel kernel;
    cl_mem depth, fog, view;
    size_t capacity;      /* pixels the buffers hold */
} fp_integrate_cl_t;

int fp_integrate_cl_init(fp_cl_t *cl, fp_integrate_cl_t *s);
int fp_integrate_process_cl(fp_integrate_cl_t *s, const fp_integrate_data_t *d,
                            const fp_view_t *v, const float *depth, float *fog);
void fp_integrate_cl_release(fp_integrate_cl_t *s);

#endif
