/* exr_mangle: hostile EXR files made from good ones, and the cost of
 * reading them, for tests/exr_limits.sh (single-part scanline files, as
 * fogpipe writes them; attr-int also multipart ones).
 *
 *   exr_mangle window IN OUT X0 Y0 X1 Y1   the dataWindow claims another size
 *   exr_mangle chunk IN OUT K DELTA         chunk K's size field changed by
 *                                           DELTA (the last chunk: DELTA > 0
 *                                           appends that many bytes)
 *   exr_mangle attr-type IN OUT NAME TYPE   attribute NAME's type renamed
 *                                           (TYPE as long as the old one)
 *   exr_mangle empty-attr IN OUT NAME TYPE  attribute NAME of type TYPE and
 *                                           no bytes added to the header
 *   exr_mangle attr-cut IN OUT NAME K       attribute NAME's value less its
 *                                           last K bytes (its size and the
 *                                           offsets follow)
 *   exr_mangle attr-int IN OUT PART NAME I V  the I-th 32-bit word of
 *                                           attribute NAME of part PART set
 *                                           to V (multipart files too)
 *   exr_mangle measure FILE                 read FILE with fp_exr_read_file
 *                                           in a child process; prints
 *                                           "rc=R rss_kb=K base_kb=B ms=M":
 *                                           its peak resident memory, that
 *                                           of a child that reads nothing,
 *                                           and its time (the message
 *                                           goes to stderr)
 *
 * The child of `measure` runs under a 3 GiB address-space limit (not
 * under AddressSanitizer, which reserves terabytes), so that a reader
 * that would allocate what a hostile header claims fails instead of
 * taking the machine. */
#include "exrio.h"
#include "fp.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif

static uint8_t *slurp(const char *path, size_t *n, size_t extra)
{
    void *b = NULL;
    if (fp_read_whole_file(path, &b, n) != FP_OK)
        exit(2);
    uint8_t *g = realloc(b, *n + extra + 1);
    if (!g)
        exit(2);
    memset(g + *n, 0, extra + 1);
    return g;
}

static void spit(const char *path, const uint8_t *b, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp || fwrite(b, 1, n, fp) != n || fclose(fp) != 0) {
        fprintf(stderr, "exr_mangle: cannot write %s\n", path);
        exit(2);
    }
}

static uint32_t u32(const uint8_t *p)
{
    return (uint32_t) p[0] | (uint32_t) p[1] << 8 | (uint32_t) p[2] << 16 |
           (uint32_t) p[3] << 24;
}

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t) (v >> (8 * i));
}

/* Walk the headers (one, or a multipart file's list): the value of
 * attribute `name` of part `part` (its type at *type_at, its size field at
 * *size_at), and where the headers end (*end: the offset tables). */
static size_t find_attr_in(const uint8_t *b, size_t n, int part, const char *name,
                           size_t *type_at, size_t *size_at, size_t *end)
{
    size_t pos = 8, found = 0;
    int multipart = (u32(b + 4) & 0x1000) != 0;
    for (int p = 0; pos < n; ++p) {
        if (multipart && b[pos] == 0)
            break; /* the empty header that ends the list */
        while (pos < n && b[pos]) {
            const char *nm = (const char *) b + pos;
            pos += strlen(nm) + 1;
            size_t ty = pos;
            pos += strlen((const char *) b + pos) + 1;
            uint32_t sz = u32(b + pos);
            if (p == part && name && strcmp(nm, name) == 0) {
                found = pos + 4;
                if (type_at)
                    *type_at = ty;
                if (size_at)
                    *size_at = pos;
            }
            pos += 4 + sz;
        }
        pos++;
        if (!multipart)
            break;
    }
    if (end)
        *end = multipart ? pos + 1 : pos;
    return found;
}

static size_t find_attr(const uint8_t *b, size_t n, const char *name, size_t *type_at,
                        size_t *end)
{
    return find_attr_in(b, n, 0, name, type_at, NULL, end);
}

static int measure(const char *path)
{
    struct timespec t0, t1;
    struct rusage ru;
    int st;
    pid_t pid = fork();
    if (pid == 0)
        _exit(0);
    if (pid < 0 || wait4(pid, &st, 0, &ru) < 0)
        return 2;
    long base = ru.ru_maxrss;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    pid = fork();
    if (pid == 0) {
#ifndef UNDER_ASAN
        struct rlimit rl = { (rlim_t) 3 << 30, (rlim_t) 3 << 30 };
        setrlimit(RLIMIT_AS, &rl);
#endif
        fp_frame_t *f = NULL;
        fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
        sel.need_depth = 0;
        int rc = fp_exr_read_file(path, 1, &sel, &f);
        fp_frame_free(f);
        _exit(rc == FP_OK ? 0 : 1);
    }
    if (pid < 0 || wait4(pid, &st, 0, &ru) < 0)
        return 2;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double ms = (double) (t1.tv_sec - t0.tv_sec) * 1e3 + (double) (t1.tv_nsec - t0.tv_nsec) / 1e6;
    printf("rc=%d rss_kb=%ld base_kb=%ld ms=%.0f\n",
           WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st), ru.ru_maxrss, base, ms);
    return 0;
}

int main(int argc, char **argv)
{
    size_t n = 0, end = 0;
    if (argc == 3 && strcmp(argv[1], "measure") == 0)
        return measure(argv[2]);
    if (argc == 8 && strcmp(argv[1], "window") == 0) {
        uint8_t *b = slurp(argv[2], &n, 0);
        size_t v = find_attr(b, n, "dataWindow", NULL, NULL);
        if (!v)
            return 2;
        for (int i = 0; i < 4; ++i)
            put32(b + v + 4 * i, (uint32_t) strtol(argv[4 + i], NULL, 10));
        spit(argv[3], b, n);
        free(b);
        return 0;
    }
    if (argc == 6 && strcmp(argv[1], "chunk") == 0) {
        long k = strtol(argv[4], NULL, 10), delta = strtol(argv[5], NULL, 10);
        uint8_t *b = slurp(argv[2], &n, delta > 0 ? (size_t) delta : 0);
        find_attr(b, n, NULL, NULL, &end);
        uint64_t off = (uint64_t) u32(b + end + 8 * k) | (uint64_t) u32(b + end + 8 * k + 4) << 32;
        if (off + 8 > n)
            return 2;
        uint32_t sz = u32(b + off + 4);
        put32(b + off + 4, (uint32_t) ((long) sz + delta));
        int last = off + 8 + sz == n;
        spit(argv[3], b, last && delta > 0 ? n + (size_t) delta : n);
        free(b);
        return 0;
    }
    if (argc == 6 && strcmp(argv[1], "attr-type") == 0) {
        uint8_t *b = slurp(argv[2], &n, 0);
        size_t ty = 0;
        if (!find_attr(b, n, argv[4], &ty, NULL) ||
            strlen((const char *) b + ty) != strlen(argv[5]))
            return 2;
        memcpy(b + ty, argv[5], strlen(argv[5]));
        spit(argv[3], b, n);
        free(b);
        return 0;
    }
    if (argc == 6 && strcmp(argv[1], "empty-attr") == 0) {
        size_t nl = strlen(argv[4]) + 1, tl = strlen(argv[5]) + 1, add = nl + tl + 4;
        uint8_t *b = slurp(argv[2], &n, add);
        find_attr(b, n, NULL, NULL, &end);
        /* the offsets move by what is inserted before the header's end */
        uint64_t first = (uint64_t) u32(b + end) | (uint64_t) u32(b + end + 4) << 32;
        for (size_t t = end; t + 8 <= first && t + 8 <= n; t += 8) {
            uint64_t off = ((uint64_t) u32(b + t) | (uint64_t) u32(b + t + 4) << 32) + add;
            put32(b + t, (uint32_t) off);
            put32(b + t + 4, (uint32_t) (off >> 32));
        }
        memmove(b + end - 1 + add, b + end - 1, n - (end - 1));
        memcpy(b + end - 1, argv[4], nl);
        memcpy(b + end - 1 + nl, argv[5], tl);
        put32(b + end - 1 + nl + tl, 0);
        spit(argv[3], b, n + add);
        free(b);
        return 0;
    }
    if (argc == 6 && strcmp(argv[1], "attr-cut") == 0) {
        size_t k = (size_t) strtoul(argv[5], NULL, 10), size_at = 0;
        uint8_t *b = slurp(argv[2], &n, 0);
        size_t v = find_attr_in(b, n, 0, argv[4], NULL, &size_at, &end);
        if (!v || u32(b + size_at) < k)
            return 2;
        size_t cut_at = v + u32(b + size_at) - k;
        put32(b + size_at, u32(b + size_at) - (uint32_t) k);
        /* the offsets (single part: up to the first chunk) move back by k */
        uint64_t first = (uint64_t) u32(b + end) | (uint64_t) u32(b + end + 4) << 32;
        for (size_t t = end; t + 8 <= first && t + 8 <= n; t += 8) {
            uint64_t off = ((uint64_t) u32(b + t) | (uint64_t) u32(b + t + 4) << 32) - k;
            put32(b + t, (uint32_t) off);
            put32(b + t + 4, (uint32_t) (off >> 32));
        }
        memmove(b + cut_at, b + cut_at + k, n - cut_at - k);
        spit(argv[3], b, n - k);
        free(b);
        return 0;
    }
    if (argc == 8 && strcmp(argv[1], "attr-int") == 0) {
        uint8_t *b = slurp(argv[2], &n, 0);
        size_t size_at = 0;
        size_t v = find_attr_in(b, n, atoi(argv[4]), argv[5], NULL, &size_at, NULL);
        long i = strtol(argv[6], NULL, 10);
        if (!v || i < 0 || (uint64_t) (i + 1) * 4 > u32(b + size_at))
            return 2;
        put32(b + v + 4 * (size_t) i, (uint32_t) strtol(argv[7], NULL, 10));
        spit(argv[3], b, n);
        free(b);
        return 0;
    }
    fprintf(stderr, "usage: exr_mangle window|chunk|attr-type|empty-attr|attr-cut|attr-int|measure "
                    "... (see its source)\n");
    return 2;
}
