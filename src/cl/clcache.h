/* fogpipe: the OpenCL program cache of the runtime (src/cl/clrt.c): a
 * program binary on disk per key, the SHA-256 of everything that decides
 * the binary (STYLE.md: the fully preprocessed source, the build options,
 * the device and driver versions).  The cache only saves time: every
 * failure warns and falls back to a build. */
#ifndef FP_CLCACHE_H
#define FP_CLCACHE_H

#include <stddef.h>
#include <stdint.h>

#define FP_KEY_LEN 32
/* Bumped when the key's contents or the file layout change. */
#define FP_CACHE_KEY_VERSION "fogpipe-cl-cache-1"

/* FIPS 180-4. */
typedef struct fp_sha256_t {
    uint32_t h[8];
    uint64_t len;
    unsigned char buf[64];
    size_t nbuf;
} fp_sha256_t;

void fp_sha256_init(fp_sha256_t *s);
void fp_sha256_update(fp_sha256_t *s, const void *data, size_t n);
void fp_sha256_final(fp_sha256_t *s, unsigned char out[32]);
/* A field of the key: its length first, so that ("ab", "c") != ("a", "bc"). */
void fp_sha256_field(fp_sha256_t *s, const char *str);

void fp_clcache_key_hex(const unsigned char key[FP_KEY_LEN], char hex[2 * FP_KEY_LEN + 1]);
/* The cache directory (malloc'ed, created if missing), or NULL when the
 * cache is off ($FOGPIPE_CACHE_DIR=off) or cannot be used (a warning). */
char *fp_clcache_dir(void);
/* A cached binary: FP_OK with *bin NULL when absent or invalid. */
int fp_clcache_read(const char *path, const unsigned char key[FP_KEY_LEN],
                    unsigned char **bin, size_t *size);
/* Written through a temporary file and a rename; failures only warn. */
void fp_clcache_write(const char *dir, const char *path, const unsigned char key[FP_KEY_LEN],
                      const char *hex, const unsigned char *bin, size_t size);

/* malloc'd copies (NULL when out of memory), for the runtime's paths and
 * names (src/cl/clrt.c too). */
char *fp_cl_xstrdup(const char *s);
char *fp_cl_xasprintf(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

#endif
