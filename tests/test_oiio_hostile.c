/* The OpenImageIO bridge against hostile images and disks: a header that
 * claims a giant image is refused from the header, before any pixel is
 * allocated (peak memory stays near that of a no-op run), against the
 * host's image budget (src/base/fp_limits.h).  The files are made here byte by
 * byte (PNG, TIFF), so that nothing else needs to write a broken image.
 * Files go to a directory under $FP_TMP (or /tmp) that is removed at the
 * end. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fp.h"
#include "fp_limits.h"
#include "oiio_bridge.h"

static char dir[4096];

static const char *tpath(const char *name)
{
    static char buf[8][4200];
    static int next;
    char *p = buf[next++ % 8];
    snprintf(p, sizeof buf[0], "%s/%s", dir, name);
    return p;
}

static void write_bytes(const char *path, const void *bytes, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(bytes, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* The messages `call` printed, kept (src/base/fp.h), as one string. */
static char said[8192];
#define SAYS(call)                                                                       \
    do {                                                                                 \
        fp_msgbuf_t sink_ = { 0 };                                                       \
        fp_msgbuf_t *old_ = fp_msg_capture(&sink_);                                      \
        (void)(call);                                                                    \
        fp_msg_capture(old_);                                                            \
        size_t n_ = sink_.len < sizeof said - 1 ? sink_.len : sizeof said - 1;           \
        memcpy(said, sink_.text ? sink_.text : "", n_);                                  \
        said[n_] = 0;                                                                    \
        fp_msg_free(&sink_);                                                             \
    } while (0)

static void assert_said(const char *part)
{
    if (!strstr(said, part))
        fail_msg("expected a message with \"%s\", got \"%s\"", part, said);
}

/* One line, naming the file. */
static void assert_one_line_naming(const char *path)
{
    size_t n = strlen(said);
    if (n == 0 || said[n - 1] != '\n' || strchr(said, '\n') != said + n - 1)
        fail_msg("expected one line, got \"%s\"", said);
    assert_said(path);
}

static long peak_rss_kb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss;
}

/* ---------------------------------------------------------------- PNG by hand */

static uint32_t crc32_png(const unsigned char *p, size_t n, uint32_t crc)
{
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++)
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1)));
    }
    return ~crc;
}

static size_t put32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)(v >> 24);
    p[1] = (unsigned char)(v >> 16);
    p[2] = (unsigned char)(v >> 8);
    p[3] = (unsigned char)v;
    return 4;
}

static size_t chunk(unsigned char *out, const char *type, const unsigned char *data, uint32_t n)
{
    size_t k = put32(out, n);
    memcpy(out + k, type, 4);
    if (n)
        memcpy(out + k + 4, data, n);
    k += 4 + n;
    k += put32(out + k, crc32_png(out + 4, 4 + n, 0));
    return k;
}

/* An 8-bit gray PNG that says it is w x h, with a few bytes of IDAT: a
 * header like any other, nothing behind it. */
static size_t giant_png(unsigned char *out, uint32_t w, uint32_t h)
{
    static const unsigned char sig[8] = { 0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n' };
    unsigned char ihdr[13] = { 0 };
    put32(ihdr, w);
    put32(ihdr + 4, h);
    ihdr[8] = 8; /* bits */
    ihdr[9] = 0; /* gray */
    /* A zlib stream of a few zero bytes. */
    static const unsigned char idat[] = { 0x78, 0x9c, 0x63, 0x60, 0x00, 0x00, 0x00, 0x02, 0x00, 0x01 };
    size_t k = 8;
    memcpy(out, sig, 8);
    k += chunk(out + k, "IHDR", ihdr, 13);
    k += chunk(out + k, "IDAT", idat, sizeof idat);
    k += chunk(out + k, "IEND", NULL, 0);
    return k;
}

/* ---------------------------------------------------------------- TIFF by hand */

static size_t put16le(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    return 2;
}

static size_t put32le(unsigned char *p, uint32_t v)
{
    put16le(p, v);
    put16le(p + 2, v >> 16);
    return 4;
}

/* An uncompressed 8-bit gray TIFF, w x h in one strip, its directory first
 * and `kept` bytes of its w * h bytes of pixels after it (the rest cut).
 * Returns the file's size; `out` holds 8 + 2 + 9 * 12 + 4 + kept bytes. */
static size_t gray_tiff(unsigned char *out, uint32_t w, uint32_t h, uint32_t kept)
{
    const uint32_t tags[9][3] = { /* tag, type (3 short, 4 long), value */
                                  { 256, 4, w },  { 257, 4, h },     { 258, 3, 8 },
                                  { 259, 3, 1 },  { 262, 3, 1 },     { 273, 4, 0 },
                                  { 277, 3, 1 },  { 278, 4, h },     { 279, 4, w * h } };
    const uint32_t data = 8 + 2 + 9 * 12 + 4;
    size_t k = 0;
    memcpy(out, "II*\0", 4);
    k = 4;
    k += put32le(out + k, 8);
    k += put16le(out + k, 9);
    for (int i = 0; i < 9; i++) {
        uint32_t v = tags[i][0] == 273 ? data : tags[i][2];
        k += put16le(out + k, tags[i][0]);
        k += put16le(out + k, tags[i][1]);
        k += put32le(out + k, 1);
        if (tags[i][1] == 3) {
            k += put16le(out + k, v);
            k += put16le(out + k, 0);
        } else {
            k += put32le(out + k, v);
        }
    }
    k += put32le(out + k, 0);
    for (uint32_t i = 0; i < kept; i++)
        out[k++] = (unsigned char)(i * 7);
    return k;
}

/* ---------------------------------------------------------------- tests */

/* Headers of 30000 x 30000 (4.5 GB asked for before) and 100000 x 100000
 * pixels (40 GB) are refused by the budget from the header alone: the
 * message says so, the outputs stay untouched, and the peak memory grows by
 * less than 64 MiB. */
static void test_giant_headers_refused(void **state)
{
    (void)state;
    /* The module loaded first, so that its own size is not counted. */
    float small[4] = { 0.5f, 0.5f, 0.5f, 0.5f };
    assert_int_equal(fp_oiio_write_preview(tpath("small.png"), small, 2, 2, 1, 8, 0), FP_OK);
    float *px = NULL;
    int w = -7, h = -7;
    assert_int_equal(fp_oiio_read_channel(tpath("small.png"), NULL, &px, &w, &h), FP_OK);
    free(px);

    static unsigned char buf[1 << 12];
    write_bytes(tpath("giant30k.png"), buf, giant_png(buf, 30000, 30000));
    write_bytes(tpath("giant100k.png"), buf, giant_png(buf, 100000, 100000));
    write_bytes(tpath("giant30k.tif"), buf, gray_tiff(buf, 30000, 30000, 64));
    const char *names[] = { "giant30k.png", "giant100k.png", "giant30k.tif" };
    long before = peak_rss_kb();
    for (size_t i = 0; i < FP_ARRAY_LEN(names); i++) {
        float *got = (float *)&got;
        w = h = -7;
        int rc = 0;
        SAYS(rc = fp_oiio_read_channel(tpath(names[i]), NULL, &got, &w, &h));
        assert_int_equal(rc, FP_ERR);
        assert_one_line_naming(tpath(names[i]));
        assert_said("exceeds the image budget");
        assert_true(got == (float *)&got);
        assert_int_equal(w, -7);
    }
    long grew = peak_rss_kb() - before;
    if (grew > 64 * 1024)
        fail_msg("peak memory grew by %ld KiB reading giant headers", grew);
}

/* The budget is the host's, as it is when the image is read: lowered, a
 * 64 x 64 image is refused; back to the defaults, it reads. */
static void test_budget_is_the_hosts(void **state)
{
    (void)state;
    float img[64 * 64];
    for (int i = 0; i < 64 * 64; i++)
        img[i] = (float)(i % 64) / 63.0f;
    assert_int_equal(fp_oiio_write_preview(tpath("64.png"), img, 64, 64, 1, 8, 0), FP_OK);
    fp_image_limits_t l;
    fp_image_limits_default(&l);
    l.max_pixels = 4000;
    fp_image_limits_set(&l);
    float *got = NULL;
    int w, h, rc = 0;
    SAYS(rc = fp_oiio_read_channel(tpath("64.png"), NULL, &got, &w, &h));
    assert_int_equal(rc, FP_ERR);
    assert_said("64x64 exceeds the image budget of 4000 pixels");
    fp_image_limits_default(&l);
    l.max_channels = 2;
    fp_image_limits_set(&l);
    float rgb[3 * 4] = { 0 };
    assert_int_equal(fp_oiio_write_preview(tpath("rgb.png"), rgb, 2, 2, 3, 8, 0), FP_OK);
    SAYS(rc = fp_oiio_read_channel(tpath("rgb.png"), "G", &got, &w, &h));
    assert_int_equal(rc, FP_ERR);
    assert_said("3 channels");
    fp_image_limits_default(&l);
    fp_image_limits_set(&l);
    assert_int_equal(fp_oiio_read_channel(tpath("64.png"), NULL, &got, &w, &h), FP_OK);
    assert_int_equal(w, 64);
    free(got);
}

/* The first `n` bytes of `from` as `to`. */
static void cut_copy(const char *from, const char *to, long n)
{
    FILE *f = fopen(from, "rb");
    assert_non_null(f);
    static unsigned char buf[1 << 20];
    size_t got = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_true(n > 0 && (size_t)n < got);
    write_bytes(to, buf, (size_t)n);
}

static long file_size(const char *path)
{
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    return (long)st.st_size;
}

/* Truncated and damaged images, each a one-line error naming the file
 * (before, a TIFF cut in its strip and a JPEG cut in its scan returned
 * pixels, garbage, with an error nobody read; a cut PNG printed libpng's own
 * line besides).  The whole files read. */
static void test_truncated_images_refused(void **state)
{
    (void)state;
    static unsigned char buf[1 << 14];
    write_bytes(tpath("whole.tif"), buf, gray_tiff(buf, 64, 64, 64 * 64));
    write_bytes(tpath("cut.tif"), buf, gray_tiff(buf, 64, 64, 64 * 32));
    float img[64 * 64];
    uint32_t x = 12345;
    for (int i = 0; i < 64 * 64; i++) {
        x = x * 1103515245u + 12345u;
        img[i] = (float)(x >> 8) / 16777216.0f;
    }
    assert_int_equal(fp_oiio_write_preview(tpath("whole.jpg"), img, 64, 64, 1, 8, 0), FP_OK);
    assert_int_equal(fp_oiio_write_preview(tpath("whole.png"), img, 64, 64, 1, 8, 0), FP_OK);
    cut_copy(tpath("whole.jpg"), tpath("cut.jpg"), file_size(tpath("whole.jpg")) / 2);
    cut_copy(tpath("whole.png"), tpath("cut.png"), file_size(tpath("whole.png")) / 2);
    cut_copy(tpath("whole.png"), tpath("cut-iend.png"), file_size(tpath("whole.png")) - 6);
    /* One bit flipped inside the pixel data: the CRC says so. */
    FILE *f = fopen(tpath("whole.png"), "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    buf[n / 2] ^= 0x10;
    write_bytes(tpath("flipped.png"), buf, n);

    float *got = NULL;
    int w, h;
    const char *whole[] = { "whole.tif", "whole.jpg", "whole.png" };
    for (size_t i = 0; i < FP_ARRAY_LEN(whole); i++) {
        assert_int_equal(fp_oiio_read_channel(tpath(whole[i]), NULL, &got, &w, &h), FP_OK);
        assert_int_equal(w, 64);
        free(got);
    }
    const char *bad[] = { "cut.tif", "cut.jpg", "cut.png", "cut-iend.png", "flipped.png" };
    const char *why[] = { "truncated or corrupt", "truncated or corrupt", "truncated PNG",
                          "truncated PNG", "fails its CRC" };
    for (size_t i = 0; i < FP_ARRAY_LEN(bad); i++) {
        got = (float *)&got;
        int rc = 0;
        SAYS(rc = fp_oiio_read_channel(tpath(bad[i]), NULL, &got, &w, &h));
        assert_int_equal(rc, FP_ERR);
        assert_one_line_naming(tpath(bad[i]));
        assert_said(why[i]);
        assert_true(got == (float *)&got);
    }
}

/* Entries of the test directory whose name contains ".tmp.". */
static int temporaries(void)
{
    int n = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)))
        n += strstr(e->d_name, ".tmp.") != NULL;
    if (d)
        closedir(d);
    return n;
}

/* A full disk, as a file size limit (RLIMIT_FSIZE, SIGXFSZ ignored: a
 * write past it fails with EFBIG as one past the end of a disk fails with
 * ENOSPC): previews and contact sheets of every format fail with one line
 * naming the file, leave nothing under the final name nor a temporary, and
 * an older file of that name stays whole (before, the preview reported
 * success and a cut PNG was renamed into place). */
static void test_full_disk(void **state)
{
    (void)state;
    enum { W = 256, H = 256 };
    static float noise[W * H * 3];
    uint32_t x = 777;
    for (int i = 0; i < W * H * 3; i++) {
        x = x * 1103515245u + 12345u;
        noise[i] = (float)(x >> 8) / 16777216.0f;
    }
    float small[4] = { 0.25f, 0.5f, 0.75f, 1.0f };
    assert_int_equal(fp_oiio_write_preview(tpath("old.png"), small, 2, 2, 1, 8, 0), FP_OK);
    assert_int_equal(fp_oiio_write_preview(tpath("cell1.png"), noise, W, H, 3, 8, 1), FP_OK);
    assert_int_equal(fp_oiio_write_preview(tpath("cell2.png"), noise, W, H, 3, 8, 1), FP_OK);
    assert_true(file_size(tpath("cell1.png")) > 64 * 1024);

    struct rlimit old, lim;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
    void (*oldsig)(int) = signal(SIGXFSZ, SIG_IGN);
    lim = old;
    lim.rlim_cur = 16 * 1024;
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
    const char *names[] = { "full.png", "full.tif", "full.jpg", "old.png" };
    int rcs[4], sheet_rc = 0;
    static char msgs[5][sizeof said];
    for (int i = 0; i < 4; i++) {
        SAYS(rcs[i] = fp_oiio_write_preview(tpath(names[i]), noise, W, H, 3, 8, 1));
        memcpy(msgs[i], said, sizeof said);
    }
    const char *cells[] = { tpath("cell1.png"), tpath("cell2.png") };
    SAYS(sheet_rc = fp_oiio_tile_sheet(cells, 2, 2, 4096, tpath("sheet.png")));
    memcpy(msgs[4], said, sizeof said);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &old), 0);
    signal(SIGXFSZ, oldsig);

    for (int i = 0; i < 5; i++) {
        const char *name = i < 4 ? names[i] : "sheet.png";
        if ((i < 4 ? rcs[i] : sheet_rc) != FP_ERR)
            fail_msg("%s: written past the file size limit", name);
        memcpy(said, msgs[i], sizeof said);
        assert_one_line_naming(tpath(name));
        /* strerror(EFBIG), or libtiff's own words for it. */
        if (!strstr(said, "File too large") && !strstr(said, "Write error"))
            fail_msg("%s: expected the write error, got \"%s\"", name, said);
        if (i != 3 && access(tpath(name), F_OK) == 0)
            fail_msg("%s: a cut file was left under the final name", name);
    }
    assert_int_equal(temporaries(), 0);
    float *got;
    int w, h;
    assert_int_equal(fp_oiio_read_channel(tpath("old.png"), NULL, &got, &w, &h), FP_OK);
    assert_int_equal(w, 2);
    free(got);
}

/* The module file is checked before dlopen trusts it: the build's own
 * passes; every cut of it (a cut module crashed the process with SIGBUS
 * inside dlopen), a file of text, and ELF headers of another class, byte
 * order, type or machine are each refused with a reason naming the file. */
static void test_module_check(void **state)
{
    (void)state;
    const char *build = getenv("FP_BUILDDIR");
    char mod[4200];
    snprintf(mod, sizeof mod, "%s/.libs/fogpipe_oiio.so", build && *build ? build : ".");
    char why[8192] = "";
    if (fp_oiio_module_check(mod, why, sizeof why) != 0)
        fail_msg("the build's module refused: %s", why);
    FILE *f = fopen(mod, "rb");
    assert_non_null(f);
    static unsigned char buf[8 << 20];
    size_t size = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_true(size > 4096 && size < sizeof buf);
    const char *cut = tpath("cut.so");
    size_t cuts[64 + 6];
    int nc = 0;
    for (int k = 1; k < 64; k++)
        cuts[nc++] = size * k / 64;
    cuts[nc++] = 10;
    cuts[nc++] = 63;
    cuts[nc++] = 64;
    cuts[nc++] = 200;
    cuts[nc++] = size - 1;
    for (int k = 0; k < nc; k++) {
        write_bytes(cut, buf, cuts[k]);
        why[0] = 0;
        if (fp_oiio_module_check(cut, why, sizeof why) == 0)
            fail_msg("a module cut to %zu of %zu bytes passed", cuts[k], size);
        if (!strstr(why, cut) || !strstr(why, cuts[k] < 64 ? "too short" : "cut"))
            fail_msg("cut to %zu bytes: \"%s\"", cuts[k], why);
    }
    const char *text = tpath("text.so");
    write_bytes(text, "not a module at all, just some text\n", 36);
    assert_int_equal(fp_oiio_module_check(text, why, sizeof why), -1);
    assert_non_null(strstr(why, "too short"));
    memset(buf + 64, 'x', 4096);
    write_bytes(text, buf + 64, 4096);
    assert_int_equal(fp_oiio_module_check(text, why, sizeof why), -1);
    assert_non_null(strstr(why, "not an ELF file"));
    /* One byte of the header changed at a time: class, byte order, type
     * (an executable), machine. */
    static const struct { size_t at; unsigned char to; const char *says; } edits[] = {
        { 4, 1, "-bit ELF file" }, { 5, 2, "byte order" }, { 16, 2, "not a shared object" },
        { 18, 0x28, "another machine" },
    };
    for (size_t i = 0; i < FP_ARRAY_LEN(edits); i++) {
        unsigned char old = buf[edits[i].at];
        buf[edits[i].at] = edits[i].to;
        write_bytes(tpath("edited.so"), buf, size);
        buf[edits[i].at] = old;
        assert_int_equal(fp_oiio_module_check(tpath("edited.so"), why, sizeof why), -1);
        if (!strstr(why, edits[i].says))
            fail_msg("header byte %zu set to %d: \"%s\"", edits[i].at, edits[i].to, why);
    }
    assert_int_equal(fp_oiio_module_check(tpath("nothere.so"), why, sizeof why), -1);
    assert_int_equal(fp_oiio_module_check(dir, why, sizeof why), -1);
}

static int setup_group(void **state)
{
    (void)state;
    const char *base = getenv("FP_TMP");
    if (!base || !*base)
        base = "/tmp";
    if (mkdir(base, 0777) != 0 && errno != EEXIST)
        return -1;
    snprintf(dir, sizeof dir, "%s/test_oiio_hostile.XXXXXX", base);
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown_group(void **state)
{
    (void)state;
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_giant_headers_refused),
        cmocka_unit_test(test_budget_is_the_hosts),
        cmocka_unit_test(test_truncated_images_refused),
        cmocka_unit_test(test_full_disk),
        cmocka_unit_test(test_module_check),
    };
    return cmocka_run_group_tests(tests, setup_group, teardown_group);
}
