/* A host of libfogpipe, built with nothing but
 *   cc api_demo.c $(pkg-config --cflags --libs fogpipe)
 * (tests/api.sh): fog a frame held in memory (tests/frame_raw.c's .bin)
 * with options given as NAME=VALUE, write the composite as a .bin.
 *
 *   api_demo IN.bin OUT.bin [NAME=VALUE ...] */
#include <fogpipe.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: api_demo IN.bin OUT.bin [NAME=VALUE ...]\n");
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    int32_t wh[2];
    double m[32];
    if (!f || fread(wh, sizeof wh, 1, f) != 1 || fread(m, sizeof(double), 32, f) != 32) {
        fprintf(stderr, "api_demo: %s: cannot read\n", argv[1]);
        return 1;
    }
    size_t n = (size_t)wh[0] * wh[1];
    float *rgba = malloc(n * 4 * sizeof *rgba), *depth = malloc(n * sizeof *depth);
    if (!rgba || !depth || fread(rgba, sizeof *rgba, 4 * n, f) != 4 * n ||
        fread(depth, sizeof *depth, n, f) != n) {
        fprintf(stderr, "api_demo: %s: short\n", argv[1]);
        return 1;
    }
    fclose(f);
    fogpipe_t *fp;
    if (fogpipe_new(&fp) != FOGPIPE_OK)
        return 1;
    int rc = FOGPIPE_OK;
    for (int i = 3; i < argc && rc == FOGPIPE_OK; i++) {
        char *eq = strchr(argv[i], '=');
        if (eq)
            *eq = 0;
        rc = fogpipe_set(fp, argv[i], eq ? eq + 1 : NULL, "api_demo");
    }
    fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
    in.width = wh[0];
    in.height = wh[1];
    in.rgba = rgba;
    in.depth = depth;
    in.world_to_camera = m;
    in.world_to_ndc = m + 16;
    if (rc == FOGPIPE_OK)
        rc = fogpipe_apply(fp, &in, rgba, NULL, NULL);   /* in place */
    if (rc != FOGPIPE_OK) {
        fprintf(stderr, "api_demo: %s\n", fogpipe_error(fp));
        fogpipe_free(fp);
        return rc;
    }
    fogpipe_free(fp);
    FILE *o = fopen(argv[2], "wb");
    int ok = o && fwrite(wh, sizeof wh, 1, o) == 1 && fwrite(m, sizeof(double), 32, o) == 32 &&
             fwrite(rgba, sizeof *rgba, 4 * n, o) == 4 * n;
    if (o && fclose(o) != 0)
        ok = 0;
    free(rgba);
    free(depth);
    return ok ? 0 : 1;
}
