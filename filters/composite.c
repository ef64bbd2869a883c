#include "composite.h"

void fp_composite_process(const float *rgba_in, const float *fog, size_t n, float *rgba_out)
{
    for (size_t i = 0; i < n; i++) {
        const float *f = fog + 4 * i;
        for (int c = 0; c < 3; c++)
            rgba_out[4 * i + c] = f[3] * rgba_in[4 * i + c] + f[c];
        rgba_out[4 * i + 3] = rgba_in[4 * i + 3];
    }
}
