/* fogpipe: a counter-based random number generator, identical in OpenCL C
 * and C (32-bit unsigned arithmetic only), so that a Monte Carlo run is the
 * same for a given --seed on the CPU reference and on any OpenCL device.
 * A stream is seeded from (seed, pixel, sample) by hashing, then stepped
 * by PCG (O'Neill 2014, RXS-M-XS output). */
#ifndef FP_RNG_H
#define FP_RNG_H

#ifdef __OPENCL_VERSION__
typedef uint fp_u32;
#ifndef FP_FN
#define FP_FN inline
#endif
#else
#include <stdint.h>
typedef uint32_t fp_u32;
#ifndef FP_FN
#define FP_FN static inline
#endif
#endif

/* A 32-bit integer hash (Wellons' lowbias32). */
FP_FN fp_u32 fp_hash32(fp_u32 x)
{
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

typedef struct fp_rng_t {
    fp_u32 state;
} fp_rng_t;

FP_FN fp_rng_t fp_rng_seed(fp_u32 seed, fp_u32 pixel, fp_u32 sample)
{
    fp_rng_t r;
    r.state = fp_hash32(seed ^ fp_hash32(pixel * 0x9e3779b9U ^ fp_hash32(sample + 0x632be5abU)));
    return r;
}

/* The next 32 random bits. */
FP_FN fp_u32 fp_rng_u32(fp_rng_t *r)
{
    fp_u32 s = r->state;
    r->state = s * 747796405U + 2891336453U;
    fp_u32 w = ((s >> ((s >> 28) + 4U)) ^ s) * 277803737U;
    return (w >> 22) ^ w;
}

/* Uniform in [0, 1): 24 random bits, exact in float and double alike. */
#define FP_RNG_NEXT(r) ((fp_real)(fp_rng_u32(r) >> 8) * (fp_real)(1.0 / 16777216.0))

#endif
