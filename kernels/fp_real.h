/* fogpipe kernels: the precision of code written once and compiled twice,
 * as OpenCL C in single precision and as C in double precision (the C
 * reference): fp_real and the address-space and function qualifiers. */
#ifndef FP_REAL_H
#define FP_REAL_H

#ifdef __OPENCL_VERSION__
typedef float fp_real;
#define FP_CONSTANT __constant
#define FP_TABLE __constant
#define FP_GLOBAL __global
#ifndef FP_FN
#define FP_FN inline
#endif
#define FP_INF INFINITY
#else
#include <math.h>
typedef double fp_real;
#define FP_CONSTANT const
#define FP_TABLE static const
#define FP_GLOBAL
#ifndef FP_FN
#define FP_FN static inline
#endif
#define FP_INF INFINITY
#endif

#endif
