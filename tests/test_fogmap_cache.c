/* The fogmap's decomposition cache (filters/fogmap_cache.h) through
 * fp_fogmap_setup on the C reference: the tables a run loads are the bits
 * the decomposition made (a new serial apart); a byte changed anywhere in
 * the file, or the file cut anywhere, is noticed, the map decomposed again
 * with the same tables, and the file written again whole; --fogmap-cache
 * off writes nothing; a map below FP_FOGMAP_CACHE_MIN is not cached; on a
 * device in the host's memory the device's buffers are the tables.  Run
 * once under AddressSanitizer when the file format changes. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fogmap.h"
#include "fogmap_cache.h"
#include "fp.h"
#include "integrate.h"
#include "options.h"
#include "testutil.h"

#define N 256

static char dir[256];
static int warnings;   /* "ignoring the cached fogmap tables" warnings */

static void count(void *user, int kind, const char *text, size_t len)
{
    (void)user;
    (void)len;
    warnings += kind == FP_MSG_WARNING && strstr(text, "ignoring the cached fogmap tables");
}

static float *noise_map(int n, unsigned seed)
{
    float *img = malloc((size_t)n * n * sizeof(float));
    uint32_t s = seed * 2654435761u + 1;
    for (int i = 0; i < n * n; i++) {
        s = s * 1664525u + 1013904223u;
        img[i] = (float)(s >> 8) / 16777216.0f;
    }
    return img;
}

static void params(fp_params_t *p, const char *cache)
{
    memset(p, 0, sizeof *p);
    fp_options_defaults(p);
    assert_int_equal(fp_options_apply(p, "fog-rect", "-60,-20,60,160", "test"), FP_OK);
    assert_int_equal(fp_options_apply(p, "density", "0.1", "test"), FP_OK);
    assert_int_equal(fp_options_apply(p, "levels", "5", "test"), FP_OK);
    assert_int_equal(fp_options_apply(p, "fogmap-cache", cache, "test"), FP_OK);
}

/* The one cache file in dir (its path into `path`), or 0 files. */
static int cache_file(char *path, size_t n)
{
    DIR *d = opendir(dir);
    int count = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        if (e->d_name[0] == '.')
            continue;
        count++;
        snprintf(path, n, "%s/%s", dir, e->d_name);
    }
    if (d)
        closedir(d);
    return count;
}

static void same_tables(const fp_fog_tables_t *a, const fp_fog_tables_t *b)
{
    assert_int_equal(a->nlevels, b->nlevels);
    assert_int_equal(a->ncoef, b->ncoef);
    assert_int_equal(a->nocc, b->nocc);
    assert_memory_equal(a->lvi, b->lvi, sizeof a->lvi);
    assert_memory_equal(a->lvf, b->lvf, sizeof a->lvf);
    assert_memory_equal(a->coef, b->coef, a->ncoef * sizeof(float));
    assert_memory_equal(a->occ, b->occ, a->nocc);
    assert_true(a->serial != b->serial);
}

/* Set up from img with --fogmap-cache `cache`. */
static void setup(const float *img, int n, const char *cache, fp_fogmap_stage_t *s,
                  fp_integrate_data_t *d)
{
    fp_params_t p;
    params(&p, cache);
    memset(d, 0, sizeof *d);
    assert_int_equal(fp_integrate_commit(&p, d), FP_OK);
    assert_int_equal(fp_fogmap_setup(&p, NULL, img, n, n, s, d), FP_OK);
    fp_options_free(&p);
}

static long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

static void test_cache(void **state)
{
    (void)state;
    float *img = noise_map(N, 1);
    fp_fogmap_stage_t ref, s;
    fp_integrate_data_t d;
    char path[600];
    setup(img, N, "off", &ref, &d);
    assert_int_equal(cache_file(path, sizeof path), 0);
    setup(img, N, dir, &s, &d);   /* decomposed, written */
    same_tables(&ref.tables, &s.tables);
    fp_fogmap_release(&s);
    assert_int_equal(cache_file(path, sizeof path), 1);
    long size = file_size(path);
    assert_true(size > (long)(ref.tables.ncoef * sizeof(float)));
    setup(img, N, dir, &s, &d);   /* loaded */
    same_tables(&ref.tables, &s.tables);
    assert_int_equal(s.map.num_levels, ref.map.num_levels);
    assert_int_equal(s.map.pad_x0, ref.map.pad_x0);
    fp_fogmap_release(&s);

    /* A byte changed in the magic, the key, the size, the checksum, the
     * fixed part, the coefficients, the last byte (the occupancy). */
    long at[] = { 0, 20, 44, 60, 100, size / 2, size - 1 };
    for (size_t i = 0; i < sizeof at / sizeof at[0]; i++) {
        FILE *f = fopen(path, "r+b");
        assert_non_null(f);
        fseek(f, at[i], SEEK_SET);
        int c = fgetc(f);
        fseek(f, at[i], SEEK_SET);
        fputc(c ^ 0x5a, f);
        fclose(f);
        warnings = 0;
        setup(img, N, dir, &s, &d);
        assert_int_equal(warnings, 1);
        same_tables(&ref.tables, &s.tables);
        fp_fogmap_release(&s);
        assert_int_equal(file_size(path), size);   /* written again whole */
    }
    /* Cut short anywhere, or longer. */
    long cut[] = { 0, 7, 50, 80, 1000, size - 1 };
    for (size_t i = 0; i < sizeof cut / sizeof cut[0] + 1; i++) {
        if (i < sizeof cut / sizeof cut[0]) {
            assert_int_equal(truncate(path, cut[i]), 0);
        } else {
            FILE *f = fopen(path, "ab");
            fputs("extra", f);
            fclose(f);
        }
        warnings = 0;
        setup(img, N, dir, &s, &d);
        assert_int_equal(warnings, 1);
        same_tables(&ref.tables, &s.tables);
        fp_fogmap_release(&s);
        assert_int_equal(file_size(path), size);
    }
    /* Another map: another file, its own tables. */
    float *img2 = noise_map(N, 2);
    setup(img2, N, dir, &s, &d);
    assert_true(memcmp(s.tables.coef, ref.tables.coef, ref.tables.ncoef * sizeof(float)) != 0);
    fp_fogmap_release(&s);
    char other[600];
    assert_int_equal(cache_file(other, sizeof other), 2);
    while (cache_file(other, sizeof other) > 0)
        unlink(other);
    /* A small map is not cached. */
    float *small = noise_map(64, 3);
    setup(small, 64, dir, &s, &d);
    fp_fogmap_release(&s);
    assert_int_equal(cache_file(path, sizeof path), 0);
    fp_fogmap_release(&ref);
    free(img);
    free(img2);
    free(small);
}

/* The tables on a device that works in the host's memory (PoCL's CPU
 * device): page-aligned, and the device's buffers are the tables
 * themselves (CL_MEM_USE_HOST_PTR), not a copy of their own (issue 26: a
 * 4096 map's 200 MB held twice); a fog layer from them as the C reference
 * gives it.  Skipped without such a device. */
static void test_tables_in_place(void **state)
{
    (void)state;
    fp_cl_t *cl = NULL;
    if (fp_cl_open(NULL, &cl) != FP_OK)
        skip();
    cl_bool unified = CL_FALSE;
    clGetDeviceInfo(fp_cl_device(cl), CL_DEVICE_HOST_UNIFIED_MEMORY, sizeof unified, &unified,
                    NULL);
    if (!unified) {
        fp_cl_close(cl);
        skip();
    }
    float *img = noise_map(64, 7);
    fp_fogmap_stage_t s;
    fp_integrate_data_t d;
    setup(img, 64, "off", &s, &d);
    assert_int_equal((uintptr_t)s.tables.coef % 4096, 0);
    assert_int_equal((uintptr_t)s.tables.occ % 4096, 0);
    fp_integrate_cl_t icl;
    assert_int_equal(fp_integrate_cl_init(cl, &icl), FP_OK);
    fp_view_t v;
    assert_int_equal(make_view(&v, 16, 12, 4, -10), FP_OK);
    float depth[16 * 12], ref[16 * 12 * 4], got[16 * 12 * 4];
    for (int i = 0; i < 16 * 12; i++)
        depth[i] = (float)(5 + i % 37);
    assert_int_equal(fp_integrate_process_cl(&icl, &d, &v, depth, got), FP_OK);
    void *host = NULL;
    cl_mem_flags flags = 0;
    assert_int_equal(clGetMemObjectInfo(icl.coef, CL_MEM_HOST_PTR, sizeof host, &host, NULL),
                     CL_SUCCESS);
    assert_int_equal(clGetMemObjectInfo(icl.coef, CL_MEM_FLAGS, sizeof flags, &flags, NULL),
                     CL_SUCCESS);
    if (!(flags & CL_MEM_USE_HOST_PTR) || host != (void *)s.tables.coef)
        fail_msg("the device's coefficients are not the tables' (flags %#lx, host %p, tables "
                 "%p)", (unsigned long)flags, host, (void *)s.tables.coef);
    assert_int_equal(clGetMemObjectInfo(icl.occ, CL_MEM_HOST_PTR, sizeof host, &host, NULL),
                     CL_SUCCESS);
    assert_ptr_equal(host, s.tables.occ);
    assert_int_equal(fp_integrate_process(&d, &v, depth, ref, NULL), FP_OK);
    for (int i = 0; i < 16 * 12 * 4; i++)
        if (!(fabs(got[i] - ref[i]) <= 1e-5))
            fail_msg("fog layer value %d: OpenCL %.7g, C %.7g (tolerance 1e-5)", i, got[i],
                     ref[i]);
    /* The device first, then the tables (lib/pipeline.c's order). */
    fp_integrate_cl_release(&icl);
    fp_cl_close(cl);
    fp_fogmap_release(&s);
    free(img);
}

int main(void)
{
    fp_msg_set_emitter(count, NULL);
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/fp_fogmap_cache.XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(dir))
        return 1;
    const struct CMUnitTest tests[] = { cmocka_unit_test(test_cache),
                                        cmocka_unit_test(test_tables_in_place) };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    rmdir(dir);
    return rc;
}
