/* Helpers shared by the EXR tests (tests/test_exrio.c, test_dwa.c, test_zip.c):
 * half conversion, sample planes of each pixel type, chunk counting, files
 * in the test's directory `tdir`, stderr capture.  Included once per test
 * program; static inline so that a test need not use them all. */
#ifndef FP_EXR_TESTUTIL_H
#define FP_EXR_TESTUTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <fcntl.h>
#include <stdio.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <openexr.h>

#include "exrio.h"
#include "fp.h"

static char tdir[4096];

/* The test program's directory, $FP_TMP/NAME.XXXXXX (/tmp without
 * FP_TMP), and its removal with the stderr capture's file: a cmocka
 * group's set-up and tear-down. */
static inline int tdir_make(const char *name)
{
    const char *base = getenv("FP_TMP");
    if (!base || !*base)
        base = "/tmp";
    mkdir(base, 0777);
    snprintf(tdir, sizeof tdir, "%s/%s.XXXXXX", base, name);
    return mkdtemp(tdir) ? 0 : -1;
}

static inline int tdir_remove(void)
{
    char p[4200];
    snprintf(p, sizeof p, "%s/stderr.txt", tdir);
    unlink(p);
    return rmdir(tdir);
}

/* ------------------------------------------------------------ helpers */

static inline uint16_t f2h(float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000;
    int32_t e = (int32_t) ((x >> 23) & 0xff) - 127 + 15;
    uint32_t man = x & 0x7fffff;
    if (((x >> 23) & 0xff) == 0xff)
        return (uint16_t) (sign | 0x7c00 | (man ? 0x200 : 0));
    if (e >= 31)
        return (uint16_t) (sign | 0x7c00);
    if (e <= 0) {
        if (e < -10)
            return (uint16_t) sign;
        man |= 0x800000;
        int shift = 14 - e;
        uint32_t h = man >> shift, rem = man & ((1u << shift) - 1);
        uint32_t halfway = 1u << (shift - 1);
        if (rem > halfway || (rem == halfway && (h & 1)))
            h++;
        return (uint16_t) (sign | h);
    }
    uint32_t h = sign | ((uint32_t) e << 10) | (man >> 13);
    uint32_t rem = man & 0x1fff;
    if (rem > 0x1000 || (rem == 0x1000 && (h & 1)))
        h++;
    return (uint16_t) h;
}

static inline float h2f(uint16_t h)
{
    uint32_t sign = (uint32_t) (h & 0x8000) << 16, e = (h >> 10) & 0x1f,
             m = h & 0x3ff, bits;
    if (e == 0) {
        float v = ldexpf((float) m, -24);
        return sign ? -v : v;
    }
    if (e == 31)
        bits = sign | 0x7f800000u | (m << 13);
    else
        bits = sign | ((e + 112) << 23) | (m << 13);
    float f;
    memcpy(&f, &bits, 4);
    return f;
}

static inline size_t tsize(int type)
{
    return type == EXR_PIXEL_HALF ? 2 : 4;
}

/* Smooth test content, so lossy codecs stay within tight bounds. */
static inline void *mkplane(int type, int w, int h, int seed)
{
    size_t n = (size_t) w * h;
    uint8_t *p = malloc(n * tsize(type));
    assert_non_null(p);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            size_t i = (size_t) y * w + x;
            float v = 0.05f + 0.9f * (0.5f + 0.5f * sinf(x * 0.11f + seed) *
                                                  cosf(y * 0.07f - seed * 0.3f));
            if (type == EXR_PIXEL_HALF) {
                uint16_t hv = f2h(v);
                memcpy(p + i * 2, &hv, 2);
            } else if (type == EXR_PIXEL_FLOAT) {
                float fv = v * 10.0f + (float) seed + 0.001f * (float) x;
                memcpy(p + i * 4, &fv, 4);
            } else {
                uint32_t u = (uint32_t) (x * 7 + y * 131 + seed * 1000);
                memcpy(p + i * 4, &u, 4);
            }
        }
    return p;
}

static inline float pget(int type, const void *p, size_t i)
{
    const uint8_t *b = p;
    if (type == EXR_PIXEL_HALF) {
        uint16_t h;
        memcpy(&h, b + i * 2, 2);
        return h2f(h);
    }
    if (type == EXR_PIXEL_UINT) {
        uint32_t u;
        memcpy(&u, b + i * 4, 4);
        return (float) u;
    }
    float f;
    memcpy(&f, b + i * 4, 4);
    return f;
}

static inline void quiet_handler(exr_const_context_t c, exr_result_t code, const char *msg)
{
    (void) c;
    (void) code;
    (void) msg;
}

static inline exr_attr_box2i_t box(int x0, int y0, int x1, int y1)
{
    exr_attr_box2i_t b;
    b.min.x = x0;
    b.min.y = y0;
    b.max.x = x1;
    b.max.y = y1;
    return b;
}

static inline int64_t fdiv(int64_t a, int64_t b)
{
    int64_t q = a / b;
    if ((a % b) != 0 && ((a < 0) != (b < 0)))
        q--;
    return q;
}

static inline int64_t scount(int64_t lo, int64_t hi, int s)
{
    return hi <= lo ? 0 : fdiv(hi - 1, s) - fdiv(lo - 1, s);
}

static inline void path_in(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", tdir, name);
}

static inline uint8_t *slurp_file(const char *path, size_t *size)
{
    void *buf = NULL;
    assert_int_equal(fp_read_whole_file(path, &buf, size), FP_OK);
    return buf;
}

static inline void spit_file(const char *path, const void *buf, size_t size)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    if (size)
        assert_int_equal(fwrite(buf, 1, size, fp), size);
    assert_int_equal(fclose(fp), 0);
}

/* --- stderr capture, to check that messages name file and frame */
static int saved_stderr = -1;

static inline void cap_begin(void)
{
    char p[4200];
    path_in(p, sizeof p, "stderr.txt");
    fflush(stderr);
    saved_stderr = dup(2);
    int fd = open(p, O_CREAT | O_TRUNC | O_WRONLY, 0644);
    assert_true(fd >= 0);
    dup2(fd, 2);
    close(fd);
}

static inline const char *cap_end(void)
{
    static char text[8192];
    char p[4200];
    path_in(p, sizeof p, "stderr.txt");
    fflush(stderr);
    dup2(saved_stderr, 2);
    close(saved_stderr);
    FILE *fp = fopen(p, "rb");
    assert_non_null(fp);
    size_t n = fread(text, 1, sizeof text - 1, fp);
    text[n] = '\0';
    fclose(fp);
    unlink(p);
    return text;
}

static inline void assert_contains(const char *hay, const char *needle)
{
    if (!strstr(hay, needle)) {
        print_error("expected \"%s\" in \"%s\"\n", needle, hay);
        fail();
    }
}

#endif
