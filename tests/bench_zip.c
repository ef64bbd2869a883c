/* make bench: the ZIP codec of the EXR frames, OpenEXR 3.1's own (zlib)
 * against fogpipe's (src/exr/exr_zip.c, libdeflate), on the sample sequence's
 * frames as they come in (what --no-fog writes again) and as height fog
 * leaves them (fogged frames deflate worse: the encoder's data-dependent
 * cost).  CPU time (getrusage user+sys) of one chunk thread, minimum of
 * REPS, per frame: decode (fp_exr_read_memory: inflate, unpack, to float)
 * and encode (fp_exr_encode: to half, pack, deflate), with the bytes per
 * frame; and the exactness of the fast codec: samples that differ between
 * the two decoders on every file, and between what each encoder wrote, read
 * back by the other codec (must be 0: the codec is lossless).
 *
 *   bench_zip IN.exr... -- FOGGED.exr... */
#include "exr_internal.h"
#include "exrio.h"
#include "fp.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#define REPS 5

static double cpu_now(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double) ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 +
           (double) ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
}

/* Decode bytes (copied: the reader takes them). */
static fp_frame_t *decode(const void *bytes, size_t n, const char *path)
{
    void *copy = malloc(n);
    fp_frame_t *f = NULL;
    if (!copy)
        return NULL;
    memcpy(copy, bytes, n);
    if (fp_exr_read_memory(copy, n, path, 1, NULL, &f) != FP_OK)
        return NULL;
    return f;
}

/* Samples of colour and depth that differ (bitwise) between two frames. */
static long differ(fp_frame_t *a, fp_frame_t *b)
{
    const fp_frame_info_t *ia = fp_frame_info(a), *ib = fp_frame_info(b);
    if (ia->width != ib->width || ia->height != ib->height)
        return -1;
    size_t n = (size_t) ia->width * ia->height;
    long d = 0;
    const float *ra = fp_frame_rgba(a), *rb = fp_frame_rgba(b);
    const float *za = fp_frame_depth(a), *zb = fp_frame_depth(b);
    for (size_t i = 0; i < 4 * n; ++i)
        d += memcmp(&ra[i], &rb[i], 4) != 0;
    for (size_t i = 0; za && zb && i < n; ++i)
        d += memcmp(&za[i], &zb[i], 4) != 0;
    return d;
}

typedef struct row_t {
    double dec_ms, enc_ms, bytes, px;
} row_t;

/* One set of files through one codec (own: fogpipe's); the encoded bytes
 * of each file in out[] for the cross-check. */
static int run_set(char **files, int nf, int own, row_t *r, void **out, size_t *out_n)
{
    memset(r, 0, sizeof *r);
    fp_zip_set_enabled(own);
    for (int i = 0; i < nf; ++i) {
        void *bytes = NULL;
        size_t n = 0;
        if (fp_read_whole_file(files[i], &bytes, &n) != FP_OK)
            return -1;
        double best = INFINITY;
        fp_frame_t *f = NULL;
        for (int k = 0; k < REPS; ++k) {
            fp_frame_free(f);
            double t0 = cpu_now();
            f = decode(bytes, n, files[i]);
            best = fmin(best, cpu_now() - t0);
            if (!f)
                return -1;
        }
        r->dec_ms += best * 1e3;
        r->px += (double) fp_frame_info(f)->width * fp_frame_info(f)->height;
        best = INFINITY;
        for (int k = 0; k < REPS; ++k) {
            void *enc = NULL;
            size_t en = 0;
            double t0 = cpu_now();
            if (fp_exr_encode(f, NULL, NULL, files[i], 1, &enc, &en) != FP_OK)
                return -1;
            best = fmin(best, cpu_now() - t0);
            free(out[i]);
            out[i] = enc;
            out_n[i] = en;
        }
        r->enc_ms += best * 1e3;
        r->bytes += (double) out_n[i];
        fp_frame_free(f);
        free(bytes);
    }
    r->dec_ms /= nf;
    r->enc_ms /= nf;
    r->bytes /= nf;
    r->px /= nf;
    return 0;
}

/* Samples that differ: each file decoded by both codecs; each codec's
 * output decoded by the other, against the file. */
static long cross_check(char **files, int nf, void **zlib_out, size_t *zlib_n, void **own_out,
                        size_t *own_n)
{
    long d = 0;
    for (int i = 0; i < nf; ++i) {
        void *bytes = NULL;
        size_t n = 0;
        if (fp_read_whole_file(files[i], &bytes, &n) != FP_OK)
            return -1;
        fp_zip_set_enabled(0);
        fp_frame_t *ref = decode(bytes, n, files[i]);
        fp_frame_t *own_by_zlib = decode(own_out[i], own_n[i], files[i]);
        fp_zip_set_enabled(1);
        fp_frame_t *mine = decode(bytes, n, files[i]);
        fp_frame_t *zlib_by_own = decode(zlib_out[i], zlib_n[i], files[i]);
        free(bytes);
        if (!ref || !mine || !own_by_zlib || !zlib_by_own)
            return -1;
        d += differ(ref, mine) + differ(ref, own_by_zlib) + differ(ref, zlib_by_own);
        fp_frame_free(ref);
        fp_frame_free(mine);
        fp_frame_free(own_by_zlib);
        fp_frame_free(zlib_by_own);
    }
    return d;
}

int main(int argc, char **argv)
{
    int sep = 1;
    while (sep < argc && strcmp(argv[sep], "--") != 0)
        sep++;
    int n_in = sep - 1, n_fog = argc - sep - 1;
    if (n_in < 1 || n_fog < 1) {
        fprintf(stderr, "usage: bench_zip IN.exr... -- FOGGED.exr...\n");
        return 2;
    }
    char **sets[2] = { argv + 1, argv + sep + 1 };
    int counts[2] = { n_in, n_fog };
    static const char *const set_names[2] = { "as read (--no-fog)", "height fog" };
    fp_exr_set_threads(1);
    row_t rows[2][2];
    long bad = 0;
    for (int s = 0; s < 2; ++s) {
        void **out[2];
        size_t *out_n[2];
        for (int c = 0; c < 2; ++c) {
            out[c] = calloc((size_t) counts[s], sizeof(void *));
            out_n[c] = calloc((size_t) counts[s], sizeof(size_t));
            if (!out[c] || !out_n[c] ||
                run_set(sets[s], counts[s], c, &rows[s][c], out[c], out_n[c]) != 0) {
                fprintf(stderr, "bench_zip: failed\n");
                return 1;
            }
        }
        long d = cross_check(sets[s], counts[s], out[0], out_n[0], out[1], out_n[1]);
        if (d < 0) {
            fprintf(stderr, "bench_zip: failed\n");
            return 1;
        }
        bad += d;
        for (int c = 0; c < 2; ++c) {
            for (int i = 0; i < counts[s]; ++i)
                free(out[c][i]);
            free(out[c]);
            free(out_n[c]);
        }
    }
    const row_t *r0 = &rows[0][0];
    printf("### EXR ZIP codec: OpenEXR 3.1's zlib against fogpipe's libdeflate\n\n");
    printf("The sample sequence's %d frames (%.0f pixels each), half colour + float depth, ZIP "
           "(16 lines a chunk), one chunk thread, CPU time (getrusage user+sys) per frame, "
           "minimum of %d runs. Decode: inflate, unpack, to float; encode: to half, pack, "
           "deflate at each codec's default level (OpenEXR 3.1's zlib: 6; fogpipe: 4, as "
           "OpenEXR 3.2 and later write with libdeflate).\n\n",
           n_in, r0->px, REPS);
    printf("| frames | codec | decode ms/frame | encode ms/frame | MB/frame |\n"
           "|---|---|---|---|---|\n");
    static const char *const codec_names[2] = { "OpenEXR (zlib)", "fogpipe (libdeflate)" };
    for (int s = 0; s < 2; ++s)
        for (int c = 0; c < 2; ++c)
            printf("| %s | %s | %.1f | %.1f | %.3f |\n", set_names[s], codec_names[c],
                   rows[s][c].dec_ms, rows[s][c].enc_ms, rows[s][c].bytes / 1e6);
    printf("\nThe encoder's cost of the fog (encode of fogged frames minus encode of the frames "
           "as read, per pixel): OpenEXR %.1f ns/px, fogpipe %.1f ns/px. ",
           (rows[1][0].enc_ms - rows[0][0].enc_ms) / r0->px * 1e6,
           (rows[1][1].enc_ms - rows[0][1].enc_ms) / r0->px * 1e6);
    printf("Exactness: %ld samples differ between the two decoders on every file and on what "
           "each encoder wrote (expected 0).\n", bad);
    return bad == 0 ? 0 : 1;
}
