/* fogpipe: the fog integrals along one view ray, gathered: every file that
 * integrates the fog includes this one.  Split by job, each compiled twice
 * (OpenCL C in single precision, C in double precision):
 *   fog_params.h    the parameter layout, quadrature, the per-level integral
 *   fogmap_walk.h   the one walk per ray over a fogmap's levels, its LOD
 *   fog_ray.h       the ray through the fog box, optical depth, the cursor
 *   fog_simd.h      the homogeneous fog on FP_SIMD rays at once */
#ifndef FP_FOG_CORE_H
#define FP_FOG_CORE_H

#include "fog_params.h"
#include "fogmap_walk.h"
#include "fog_ray.h"
#include "fog_simd.h"

#endif
