/* fogpipe: where its installed files are (src/base/install.h). */
#define _GNU_SOURCE
#include "config.h"
#include "install.h"

#include <dlfcn.h>
#include <limits.h>
#include <link.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fp.h"

static pthread_once_t once = PTHREAD_ONCE_INIT;
static char store[2][FP_INSTALL_MAX][PATH_MAX];
static const char *lists[2][FP_INSTALL_MAX];
static int counts[2];

/* Adds `dir` to list k unless it is there already (compared resolved when
 * it exists). */
static void add(int k, const char *dir)
{
    char real[PATH_MAX];
    const char *d = realpath(dir, real) ? real : dir;
    if (counts[k] == FP_INSTALL_MAX || strlen(d) >= PATH_MAX)
        return;
    for (int i = 0; i < counts[k]; i++)
        if (strcmp(store[k][i], d) == 0)
            return;
    strcpy(store[k][counts[k]], d);
    lists[k][counts[k]] = store[k][counts[k]];
    counts[k]++;
}

/* The directory of the object that holds this code, absolute; "" if
 * unknown. */
static void object_dir(char *out)
{
    Dl_info info;
    struct link_map *lm = NULL;
    const char *name = "/proc/self/exe";
    /* The main program's link map has an empty name (dladdr's dli_fname
     * is then argv[0], a bare "fogpipe" when run from PATH). */
    if (dladdr1((void *)object_dir, &info, (void **)&lm, RTLD_DL_LINKMAP) && lm && lm->l_name &&
        lm->l_name[0])
        name = lm->l_name;
    out[0] = 0;
    if (!realpath(name, out))
        out[0] = 0;
    char *slash = strrchr(out, '/');
    if (slash == out)
        out[1] = 0; /* the root */
    else if (slash)
        *slash = 0;
}

/* `dir` minus the configured prefix ("/bin" of "/usr/local/bin"); NULL
 * when it is not under the prefix. */
static const char *under_prefix(const char *dir)
{
    size_t n = strlen(FP_PREFIX);
    return strncmp(dir, FP_PREFIX, n) == 0 && dir[n] == '/' ? dir + n : NULL;
}

/* The prefix that `here` (an installed bindir or libdir) was moved to:
 * `here` minus the configured dir's part below the prefix; 0 if neither
 * matches. */
static int moved_prefix(const char *here, char *prefix)
{
    static const char *const dirs[] = { FP_BINDIR, FP_LIBDIR };
    size_t hl = strlen(here);
    for (size_t i = 0; i < FP_ARRAY_LEN(dirs); i++) {
        const char *tail = under_prefix(dirs[i]);
        size_t tl = tail ? strlen(tail) : 0;
        if (tail && hl >= tl && strcmp(here + hl - tl, tail) == 0) {
            memcpy(prefix, here, hl - tl);
            prefix[hl - tl] = 0;
            return 1;
        }
    }
    return 0;
}

static void compute(void)
{
    char self[PATH_MAX], d[PATH_MAX + 64], prefix[PATH_MAX];
    object_dir(self);
    int in_tree = 0;
    static const char *const tree[] = { "", "/.libs", "/tests", "/tests/.libs" };
    for (size_t i = 0; i < FP_ARRAY_LEN(tree); i++) {
        snprintf(d, sizeof d, "%s%s", FP_BUILDDIR, tree[i]);
        in_tree |= self[0] && strcmp(self, d) == 0;
    }
    if (in_tree) {
        add(FP_INSTALL_MODULES, FP_BUILDDIR "/.libs");
        add(FP_INSTALL_DATA, FP_SRCDIR "/samples");
    }
    if (self[0]) {
        const char *lib = under_prefix(FP_PKGLIBDIR), *data = under_prefix(FP_PKGDATADIR);
        if (moved_prefix(self, prefix)) {
            if (lib) {
                snprintf(d, sizeof d, "%s%s", prefix, lib);
                add(FP_INSTALL_MODULES, d);
            }
            if (data) {
                snprintf(d, sizeof d, "%s%s", prefix, data);
                add(FP_INSTALL_DATA, d);
            }
        }
        static const char *const mods[] = { "/../lib/fogpipe", "/fogpipe" };
        for (size_t i = 0; i < FP_ARRAY_LEN(mods); i++) {
            snprintf(d, sizeof d, "%s%s", self, mods[i]);
            struct stat st;
            /* <bindir>/fogpipe is the program, not a directory. */
            if (stat(d, &st) != 0 || S_ISDIR(st.st_mode))
                add(FP_INSTALL_MODULES, d);
        }
        snprintf(d, sizeof d, "%s/../share/fogpipe", self);
        add(FP_INSTALL_DATA, d);
    }
    add(FP_INSTALL_MODULES, FP_PKGLIBDIR);
    add(FP_INSTALL_DATA, FP_PKGDATADIR);
}

int fp_install_dirs(fp_install_kind_t kind, const char *const **dirs)
{
    pthread_once(&once, compute);
    *dirs = lists[kind];
    return counts[kind];
}

int fp_install_find(const char *rel, char *path, size_t n, char *tried, size_t tried_n)
{
    const char *const *dirs;
    int count = fp_install_dirs(FP_INSTALL_DATA, &dirs);
    size_t used = 0;
    if (tried_n)
        tried[0] = 0;
    for (int i = 0; i < count; i++) {
        char p[PATH_MAX + 256];
        struct stat st;
        snprintf(p, sizeof p, "%s/%s", dirs[i], rel);
        if (stat(p, &st) == 0 && S_ISREG(st.st_mode) && access(p, R_OK) == 0 &&
            strlen(p) < n) {
            memcpy(path, p, strlen(p) + 1);
            return 0;
        }
        if (used < tried_n) {
            int w = snprintf(tried + used, tried_n - used, "%s%s", used ? ", " : "", dirs[i]);
            used += w > 0 ? (size_t)w : 0;
        }
    }
    return -1;
}
