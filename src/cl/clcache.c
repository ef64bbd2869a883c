/* fogpipe: the OpenCL program cache (src/cl/clcache.h): binaries on disk
 * keyed by the SHA-256 of the preprocessed source, the build options and
 * the device and driver versions. */
#include "clcache.h"
#include "fp.h"

#include <errno.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

char *fp_cl_xstrdup(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

char *fp_cl_xasprintf(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0)
        return NULL;
    char *s = malloc((size_t)n + 1);
    if (!s)
        return NULL;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return s;
}

/* Trim in place: some drivers pad names with spaces. */
/* ---------------------------------------------------------------- SHA-256 */

/* FIPS 180-4.  The cache key only needs collision resistance against
 * accidents, but SHA-256 is small enough that there is no reason to argue
 * about a weaker hash. */

static const uint32_t sha256_k[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4,
    0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe,
    0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f,
    0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7,
    0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc,
    0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b,
    0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116,
    0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
    0xc67178f2
};

#define FP_ROR(x, n) (((x) >> (n)) | ((x) << (32 - (n))))

static void sha256_block(fp_sha256_t *s, const unsigned char *p)
{
    uint32_t w[64];
    for (int i = 0; i < 16; i++)
        w[i] = (uint32_t)p[4 * i] << 24 | (uint32_t)p[4 * i + 1] << 16 |
               (uint32_t)p[4 * i + 2] << 8 | (uint32_t)p[4 * i + 3];
    for (int i = 16; i < 64; i++) {
        uint32_t s0 = FP_ROR(w[i - 15], 7) ^ FP_ROR(w[i - 15], 18) ^ (w[i - 15] >> 3);
        uint32_t s1 = FP_ROR(w[i - 2], 17) ^ FP_ROR(w[i - 2], 19) ^ (w[i - 2] >> 10);
        w[i] = w[i - 16] + s0 + w[i - 7] + s1;
    }
    uint32_t a = s->h[0], b = s->h[1], c = s->h[2], d = s->h[3];
    uint32_t e = s->h[4], f = s->h[5], g = s->h[6], h = s->h[7];
    for (int i = 0; i < 64; i++) {
        uint32_t t1 = h + (FP_ROR(e, 6) ^ FP_ROR(e, 11) ^ FP_ROR(e, 25)) + ((e & f) ^ (~e & g)) +
                      sha256_k[i] + w[i];
        uint32_t t2 = (FP_ROR(a, 2) ^ FP_ROR(a, 13) ^ FP_ROR(a, 22)) +
                      ((a & b) ^ (a & c) ^ (b & c));
        h = g;
        g = f;
        f = e;
        e = d + t1;
        d = c;
        c = b;
        b = a;
        a = t1 + t2;
    }
    s->h[0] += a;
    s->h[1] += b;
    s->h[2] += c;
    s->h[3] += d;
    s->h[4] += e;
    s->h[5] += f;
    s->h[6] += g;
    s->h[7] += h;
}

void fp_sha256_init(fp_sha256_t *s)
{
    static const uint32_t iv[8] = { 0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                    0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19 };
    memcpy(s->h, iv, sizeof iv);
    s->len = 0;
    s->nbuf = 0;
}

void fp_sha256_update(fp_sha256_t *s, const void *data, size_t n)
{
    const unsigned char *p = data;
    s->len += n;
    while (n > 0) {
        size_t take = 64 - s->nbuf < n ? 64 - s->nbuf : n;
        memcpy(s->buf + s->nbuf, p, take);
        s->nbuf += take;
        p += take;
        n -= take;
        if (s->nbuf == 64) {
            sha256_block(s, s->buf);
            s->nbuf = 0;
        }
    }
}

void fp_sha256_final(fp_sha256_t *s, unsigned char out[32])
{
    uint64_t bits = s->len * 8;
    unsigned char pad = 0x80, zero = 0, len[8];
    fp_sha256_update(s, &pad, 1);
    while (s->nbuf != 56)
        fp_sha256_update(s, &zero, 1);
    for (int i = 0; i < 8; i++)
        len[i] = (unsigned char)(bits >> (56 - 8 * i));
    fp_sha256_update(s, len, 8);
    for (int i = 0; i < 8; i++) {
        out[4 * i] = (unsigned char)(s->h[i] >> 24);
        out[4 * i + 1] = (unsigned char)(s->h[i] >> 16);
        out[4 * i + 2] = (unsigned char)(s->h[i] >> 8);
        out[4 * i + 3] = (unsigned char)s->h[i];
    }
}

/* A field of the key: length first, so that ("ab", "c") != ("a", "bc"). */
void fp_sha256_field(fp_sha256_t *s, const char *str)
{
    uint64_t n = strlen(str);
    unsigned char len[8];
    for (int i = 0; i < 8; i++)
        len[i] = (unsigned char)(n >> (8 * i));
    fp_sha256_update(s, len, 8);
    fp_sha256_update(s, str, (size_t)n);
}

#undef FP_ROR

/* ------------------------------------------------------------ binary cache */

/* Cache file: magic, key, payload size (little endian), SHA-256 of the
 * payload, payload.  The size and payload hash catch a truncated or
 * corrupt file, which is then ignored and rewritten. */
#define FP_CACHE_MAGIC "FPCLBIN1"
#define FP_CACHE_HEADER (8 + FP_KEY_LEN + 8 + 32)

void fp_clcache_key_hex(const unsigned char key[FP_KEY_LEN], char hex[2 * FP_KEY_LEN + 1])
{
    static const char digits[] = "0123456789abcdef";
    for (int i = 0; i < FP_KEY_LEN; i++) {
        hex[2 * i] = digits[key[i] >> 4];
        hex[2 * i + 1] = digits[key[i] & 15];
    }
    hex[2 * FP_KEY_LEN] = '\0';
}

/* The cache directory (malloc'ed, created if missing), or NULL when the
 * cache is off or cannot be used (with a warning: the cache only saves
 * time, so it never fails a run). */
char *fp_clcache_dir(void)
{
    const char *env = getenv("FOGPIPE_CACHE_DIR");
    char *dir = NULL;
    if (env && strcmp(env, "off") == 0)
        return NULL;
    if (env && *env) {
        dir = fp_cl_xstrdup(env);
    } else {
        const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
        /* XDG base directory spec: relative paths are invalid, ignore them. */
        if (xdg && xdg[0] == '/')
            dir = fp_cl_xasprintf("%s/fogpipe", xdg);
        else if (home && *home)
            dir = fp_cl_xasprintf("%s/.cache/fogpipe", home);
        else {
            fp_info("no HOME, XDG_CACHE_HOME or FOGPIPE_CACHE_DIR: OpenCL program cache off");
            return NULL;
        }
    }
    if (!dir) {
        fp_error("out of memory");
        return NULL;
    }
    if (fp_mkdir_p(dir) != 0 && errno != ENOTDIR) {
        fp_warn("%s: cannot create the OpenCL program cache directory (%s); cache off", dir,
                strerror(errno));
        free(dir);
        return NULL;
    }
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        fp_warn("%s: not a directory; OpenCL program cache off", dir);
        free(dir);
        return NULL;
    }
    return dir;
}

/* Read a cached binary; FP_OK with *bin == NULL when absent or invalid. */
int fp_clcache_read(const char *path, const unsigned char key[FP_KEY_LEN],
                      unsigned char **bin, size_t *size)
{
    FILE *f = NULL;
    unsigned char *data = NULL;
    unsigned char hdr[FP_CACHE_HEADER], sum[32];
    const char *why = NULL;

    *bin = NULL;
    *size = 0;
    if (!(f = fopen(path, "rb"))) {
        if (errno != ENOENT)
            fp_warn("%s: cannot read cached OpenCL program (%s); rebuilding", path,
                    strerror(errno));
        goto out;
    }
    if (fread(hdr, 1, sizeof hdr, f) != sizeof hdr) {
        why = "truncated header";
        goto out;
    }
    if (memcmp(hdr, FP_CACHE_MAGIC, 8) != 0) {
        why = "bad magic";
        goto out;
    }
    if (memcmp(hdr + 8, key, FP_KEY_LEN) != 0) {
        why = "key mismatch";
        goto out;
    }
    uint64_t n = 0;
    for (int i = 0; i < 8; i++)
        n |= (uint64_t)hdr[8 + FP_KEY_LEN + i] << (8 * i);
    /* A program binary beyond 1 GiB is a corrupt size field, not a program. */
    if (n == 0 || n > ((uint64_t)1 << 30)) {
        why = "bad size";
        goto out;
    }
    if (!(data = malloc((size_t)n))) {
        why = "out of memory";
        goto out;
    }
    if (fread(data, 1, (size_t)n, f) != (size_t)n) {
        why = "truncated";
        goto out;
    }
    if (fgetc(f) != EOF) {
        why = "trailing bytes";
        goto out;
    }
    fp_sha256_t s;
    fp_sha256_init(&s);
    fp_sha256_update(&s, data, (size_t)n);
    fp_sha256_final(&s, sum);
    if (memcmp(sum, hdr + 8 + FP_KEY_LEN + 8, 32) != 0) {
        why = "checksum mismatch";
        goto out;
    }
    *bin = data;
    *size = (size_t)n;
    data = NULL;
out:
    if (why)
        fp_warn("%s: ignoring corrupt cached OpenCL program (%s); rebuilding", path, why);
    free(data);
    if (f)
        fclose(f);
    return FP_OK;
}

/* Write through a temporary file and rename, so that a concurrent reader
 * sees the old file, no file, or the whole new one.  Failures only warn. */
void fp_clcache_write(const char *dir, const char *path, const unsigned char key[FP_KEY_LEN],
                        const char *hex, const unsigned char *bin, size_t size)
{
    char *tmp = NULL;
    int fd = -1;
    FILE *f = NULL;
    unsigned char hdr[FP_CACHE_HEADER];
    const char *why = NULL;

    memcpy(hdr, FP_CACHE_MAGIC, 8);
    memcpy(hdr + 8, key, FP_KEY_LEN);
    for (int i = 0; i < 8; i++)
        hdr[8 + FP_KEY_LEN + i] = (unsigned char)((uint64_t)size >> (8 * i));
    fp_sha256_t s;
    fp_sha256_init(&s);
    fp_sha256_update(&s, bin, size);
    fp_sha256_final(&s, hdr + 8 + FP_KEY_LEN + 8);

    if (!(tmp = fp_cl_xasprintf("%s/.%s.tmp-XXXXXX", dir, hex))) {
        why = "out of memory";
        goto out;
    }
    if ((fd = mkstemp(tmp)) < 0) {
        why = strerror(errno);
        free(tmp);
        tmp = NULL;
        goto out;
    }
    /* mkstemp makes 0600; the cache may be shared by a farm's users. */
    (void)fchmod(fd, 0644);
    if (!(f = fdopen(fd, "wb"))) {
        why = strerror(errno);
        goto out;
    }
    fd = -1;
    if (fwrite(hdr, 1, sizeof hdr, f) != sizeof hdr || fwrite(bin, 1, size, f) != size ||
        fflush(f) != 0 || fsync(fileno(f)) != 0) {
        why = strerror(errno);
        goto out;
    }
    int e = fclose(f);
    f = NULL;
    if (e != 0) {
        why = strerror(errno);
        goto out;
    }
    if (rename(tmp, path) != 0) {
        why = strerror(errno);
        goto out;
    }
    free(tmp);
    tmp = NULL;
out:
    if (f)
        fclose(f);
    if (fd >= 0)
        close(fd);
    if (tmp) {
        unlink(tmp);
        free(tmp);
    }
    if (why)
        fp_warn("%s: cannot write the OpenCL program cache (%s)", path, why);
}
