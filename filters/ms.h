/* fogpipe stage "ms": the fast multiple-scattering path (issue 28).
 *
 * Per frame, the diffusely scattered light of the sun in the fog, taken
 * as a plane-parallel medium (the fog's height profile, infinitely wide),
 * is solved for once (fp_ms_solve) and stored as a table of J_ms(height)
 * in the light parameters (kernels/ms_core.h); every view ray then adds
 * its in-scatter exactly as the single-scattered light's (fp_ms_ray, in
 * the C reference and the OpenCL kernel alike).  The stage also resolves
 * --fog-color auto (the ambient term derived from the sun and the fog).
 * See doc/notes/multiple-scattering.md for what it is measured against. */
#ifndef FP_MS_H
#define FP_MS_H

#include "options.h"
#include "params.h"

extern const fp_option_t fp_ms_options[];

/* The plane-parallel problem: the fog's extinction profile from `fp`
 * (FP_F_*, fog space: the main fog between its box's floor and top, the
 * haze; the box's sides bound it), albedo, the phase function's mean
 * cosine g (similarity), the unit direction toward the sun (fog space,
 * above the horizon) and the ground's albedo.  Writes
 * J_ms per unit sun irradiance on FP_MS_NODES heights from *yb, *dy
 * apart (the mean radiance of the light scattered at least once), and
 * *jmean, its mean over the column weighted by optical depth.  Returns 0,
 * or -1 when there is no fog to solve for (then J = 0). */
int fp_ms_solve(const double *fp, double albedo, double g, const double sun[3],
                double ground_albedo, double *J, double *yb, double *dy, double *jmean);

/* Per frame: the table and the ambient term in the light parameters `lt`
 * (FP_LT_*) from the run's parameters and the frame's fog parameters
 * `fp` (FP_F_*), with the sun's shadow map `smap` as the scatter stage
 * holds it (NULL: none). */
int fp_ms_frame(const fp_params_t *p, double *lt, const double *fp, const float *smap);

/* The phase function's mean cosine (kinds of kernels/phase.h). */
double fp_ms_mean_cosine(int kind, double g, double w);

#endif
