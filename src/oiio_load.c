/* fogpipe: the OpenImageIO bridge's functions (src/oiio_bridge.h), loading
 * the module fogpipe_oiio.so the first time one is called.
 *
 * Where the module is looked for, the first that loads and is of this
 * build (FP_OIIO_ABI and PACKAGE_VERSION) wins:
 *   - the build tree's .libs, when this code runs from the build tree (the
 *     program, the tests and libfogpipe.so there: never an older installed
 *     module);
 *   - beside the object holding this code, as installed: <dir>/fogpipe/
 *     (libfogpipe.so in $(libdir)) and <dir>/../lib/fogpipe/ (the program
 *     in $(bindir)), so that a DESTDIR or moved install finds its own;
 *   - $(pkglibdir), as configured. */
#define _GNU_SOURCE
#include "config.h"

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fp.h"
#include "fp_limits.h"
#include "oiio_bridge.h"

#define MODULE_NAME "fogpipe_oiio.so"

static pthread_once_t once = PTHREAD_ONCE_INIT;
static const fp_oiio_module_t *mod;
static char tried[8192]; /* the places looked in */
static char why[8192];   /* why a module that is there did not load */

static void append(char *buf, size_t size, const char *text)
{
    size_t used = strlen(buf);
    snprintf(buf + used, size - used, "%s%s", used ? ", " : "", text);
}

/* Load dir/MODULE_NAME if it is there and of this build; 1 if loaded. */
static int try_dir(const char *dir)
{
    char path[PATH_MAX + 64], real[PATH_MAX];
    snprintf(path, sizeof path, "%s/%s", dir, MODULE_NAME);
    /* A place that is there but not a directory (<bindir>/fogpipe, the
     * program) is none; each one is named once, however reached. */
    struct stat st;
    if (stat(dir, &st) == 0 && !S_ISDIR(st.st_mode))
        return 0;
    const char *name = realpath(dir, real) ? real : dir;
    if (!strstr(tried, name))
        append(tried, sizeof tried, name);
    if (access(path, F_OK) != 0)
        return 0;
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *e = dlerror();
        append(why, sizeof why, e ? e : path);
        return 0;
    }
    fp_oiio_entry_fn entry;
    /* POSIX's way from a data pointer to a function pointer (dlsym(3)). */
    *(void **)&entry = dlsym(h, FP_OIIO_ENTRY);
    const fp_oiio_module_t *m = entry ? entry(fp_error, fp_warn, fp_image_limits_check) : NULL;
    if (!m || m->abi != FP_OIIO_ABI || strcmp(m->version, PACKAGE_VERSION) != 0) {
        char line[PATH_MAX + 200];
        snprintf(line, sizeof line, "%s is not this fogpipe's (%s, expected %s)", path,
                 m ? m->version : "no " FP_OIIO_ENTRY, PACKAGE_VERSION);
        append(why, sizeof why, line);
        dlclose(h);
        return 0;
    }
    mod = m;
    return 1;
}

static void load(void)
{
    Dl_info info;
    char self[PATH_MAX] = "";
    if (dladdr((void *)load, &info) && info.dli_fname && realpath(info.dli_fname, self)) {
        char *slash = strrchr(self, '/');
        if (slash)
            *slash = 0;
    }
    /* The build tree's program, tests and library (not an install made
     * into a directory inside it). */
    int in_tree = 0;
    static const char *const tree[] = { "", "/.libs", "/tests", "/tests/.libs" };
    for (size_t i = 0; i < FP_ARRAY_LEN(tree); i++) {
        char d[PATH_MAX + 32];
        snprintf(d, sizeof d, "%s%s", FP_BUILDDIR, tree[i]);
        in_tree |= self[0] && strcmp(self, d) == 0;
    }
    char dir[PATH_MAX + 32];
    if (in_tree && try_dir(FP_BUILDDIR "/.libs"))
        return;
    if (self[0]) {
        snprintf(dir, sizeof dir, "%s/fogpipe", self);
        if (try_dir(dir))
            return;
        snprintf(dir, sizeof dir, "%s/../lib/fogpipe", self);
        if (try_dir(dir))
            return;
    }
    try_dir(FP_MODULE_DIR);
}

static int need(const char *path, const char *what)
{
    pthread_once(&once, load);
    if (mod)
        return FP_OK;
    return fp_error("%s: %s needs fogpipe's OpenImageIO module %s, which %s%s (looked in %s)",
                    path && *path ? path : "(no file name)", what, MODULE_NAME,
                    why[0] ? "did not load: " : "is not installed", why, tried);
}

int fp_oiio_read_channel(const char *path, const char *channel, float **data, int *width,
                         int *height)
{
    int rc = need(path, "reading the image");
    return rc ? rc : mod->read_channel(path, channel, data, width, height);
}

int fp_oiio_write_preview(const char *path, const float *pixels, int width, int height,
                          int nchannels, int bits, int dither)
{
    int rc = need(path, "writing the image");
    return rc ? rc : mod->write_preview(path, pixels, width, height, nchannels, bits, dither);
}

int fp_oiio_tile_sheet(const char *const *paths, int count, int columns, int max_size,
                       const char *out_path)
{
    int rc = need(out_path, "making the contact sheet");
    return rc ? rc : mod->tile_sheet(paths, count, columns, max_size, out_path);
}
