/* Test helper: frames as raw arrays, for the library's tests (tests/api.sh).
 *
 *   frame_raw dump IN.exr OUT.bin         the frame's RGBA, depth and camera
 *   frame_raw compare OUT.bin REF.exr TOL  max |d| of RGBA against REF; exit 1 above TOL
 *
 * .bin (native endianness): int32 width, height; float64 worldToCamera[16],
 * worldToNDC[16]; float32 rgba[w*h*4]; float32 depth[w*h] (a result file
 * has the same layout; its matrices and depth are not read). */
#include "exrio.h"
#include "fp.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int dump(const char *in, const char *out)
{
    fp_frame_t *f = NULL;
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    if (fp_exr_read_file(in, 1, &sel, &f))
        return 1;
    const fp_frame_info_t *info = fp_frame_info(f);
    int32_t wh[2] = { info->width, info->height };
    size_t n = (size_t)wh[0] * wh[1];
    FILE *o = fopen(out, "wb");
    int ok = o && fwrite(wh, sizeof wh, 1, o) == 1 &&
             fwrite(info->world_to_camera, sizeof(double), 16, o) == 16 &&
             fwrite(info->world_to_ndc, sizeof(double), 16, o) == 16 &&
             fwrite(fp_frame_rgba(f), sizeof(float), 4 * n, o) == 4 * n &&
             fwrite(fp_frame_depth(f), sizeof(float), n, o) == n;
    if (o && fclose(o) != 0)
        ok = 0;
    fp_frame_free(f);
    if (!ok)
        fprintf(stderr, "frame_raw: %s: cannot write\n", out);
    return !ok;
}

static int compare(const char *bin, const char *ref, double tol)
{
    FILE *b = fopen(bin, "rb");
    int32_t wh[2];
    double m[32];
    if (!b || fread(wh, sizeof wh, 1, b) != 1 || fread(m, sizeof(double), 32, b) != 32) {
        fprintf(stderr, "frame_raw: %s: cannot read\n", bin);
        return 1;
    }
    fp_frame_t *f = NULL;
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    sel.need_depth = 0;
    if (fp_exr_read_file(ref, 1, &sel, &f))
        return 1;
    const fp_frame_info_t *info = fp_frame_info(f);
    if (info->width != wh[0] || info->height != wh[1]) {
        fprintf(stderr, "frame_raw: %s is %dx%d, %s %dx%d\n", bin, wh[0], wh[1], ref,
                info->width, info->height);
        return 1;
    }
    size_t n = (size_t)wh[0] * wh[1] * 4;
    float *v = malloc(n * sizeof *v);
    if (!v || fread(v, sizeof *v, n, b) != n) {
        fprintf(stderr, "frame_raw: %s: short\n", bin);
        return 1;
    }
    fclose(b);
    const float *r = fp_frame_rgba(f);
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)v[i] - r[i]);
        if (!(d <= worst))
            worst = isnan(d) ? INFINITY : d;
    }
    printf("max |d| %.3g over %zu values (bound %.3g)\n", worst, n, tol);
    free(v);
    fp_frame_free(f);
    return !(worst <= tol);
}

int main(int argc, char **argv)
{
    if (argc == 4 && strcmp(argv[1], "dump") == 0)
        return dump(argv[2], argv[3]);
    if (argc == 5 && strcmp(argv[1], "compare") == 0)
        return compare(argv[2], argv[3], atof(argv[4]));
    fprintf(stderr, "usage: frame_raw dump IN.exr OUT.bin | compare OUT.bin REF.exr TOL\n");
    return 2;
}
