/* Shared helpers of the C tests: a repeatable random source and a
 * synthetic wide camera whose rays cover every direction class. */
#ifndef FP_TESTUTIL_H
#define FP_TESTUTIL_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "camera.h"
#include "options_all.h"

/* cmocka 1.1 (Debian 12) has no assert_double_equal. */
#ifndef assert_double_equal
#define assert_double_equal(a, b, eps)                                                  \
    do {                                                                                \
        double a_ = (a), b_ = (b), e_ = (eps);                                          \
        if (!(fabs(a_ - b_) <= e_) && !(a_ == b_))                                      \
            fail_msg("%s = %.17g, expected %.17g (tolerance %g)", #a, a_, b_, e_);       \
    } while (0)
#endif

static uint64_t fp_test_rng = 88172645463325252ull;

static inline double urand(void)
{
    fp_test_rng ^= fp_test_rng << 13;
    fp_test_rng ^= fp_test_rng >> 7;
    fp_test_rng ^= fp_test_rng << 17;
    return (double)(fp_test_rng >> 11) / 9007199254740992.0;
}

/* A 150-degree camera at height cam_y pitched by pitch_deg, for frames of
 * random rays (grazing and level ones included near the horizon). */
static inline int make_view(fp_view_t *v, int w, int h, double cam_y, double pitch_deg)
{
    fp_params_t p;
    fp_options_defaults(&p);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = w;
    info.height = info.disp_h = h;
    info.pixel_aspect = 1;
    char rot[64];
    snprintf(rot, sizeof rot, "%g,25,0", pitch_deg);
    int rc = fp_options_apply(&p, "camera-pos", "3,0,-7", "test") ||
             fp_options_apply(&p, "camera-rot", rot, "test") ||
             fp_options_apply(&p, "vfov", "150", "test");
    p.camera.pos[1] = cam_y;
    fp_camera_t c;
    if (rc == 0)
        rc = fp_camera_resolve(&p, &info, "synthetic", 1, &c) || fp_view_setup(&c, &p, &info, v);
    fp_options_free(&p);
    return rc;
}

/* A pixel list for the fog stages' list launches: every 3rd pixel of an
 * n-pixel frame, last first (out of order on purpose); pix has room for
 * n / 3 + 1.  Returns its length. */
static inline size_t test_pixel_list(size_t n, int *pix)
{
    size_t m = 0;
    for (size_t k = 0; 3 * k < n; k++)
        pix[m++] = (int)(n - 1 - 3 * k);
    return m;
}

/* Largest |difference| between the list results got[4*k] and the frame's
 * full[4 * pix[k]] (NaN counts as infinite). */
static inline double test_list_diff(const float *full, const int *pix, size_t m, const float *got)
{
    double worst = 0;
    for (size_t k = 0; k < m; k++)
        for (int c = 0; c < 4; c++) {
            double e = fabs((double)got[4 * k + c] - full[4 * (size_t)pix[k] + c]);
            worst = isnan(e) ? INFINITY : fmax(worst, e);
        }
    return worst;
}

#endif
