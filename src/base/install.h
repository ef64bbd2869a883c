/* fogpipe: where its installed files are, one way for all of them (the
 * OpenImageIO module, the OpenColorIO config, the presets).
 *
 * The directories are looked in best first, each named once:
 *   - the build tree, when this code runs from it (the program, the tests,
 *     libfogpipe.so there): $(abs_builddir)/.libs for the module,
 *     $(abs_top_srcdir)/samples for the data, never an older install;
 *   - beside the object that holds this code, resolved to an absolute path:
 *     libfogpipe.so as the dynamic loader mapped it (dladdr's link map; a
 *     bare name is never resolved against the working directory), or the
 *     program (/proc/self/exe) when the library is linked into it.  First
 *     the configured layout moved to the prefix found there (bindir or
 *     libdir stripped from that directory: a `make install prefix=P`, a
 *     DESTDIR or a moved tree), then <bin>/../lib/fogpipe,
 *     <lib>/fogpipe, <dir>/../share/fogpipe;
 *   - the configured $(pkglibdir) and $(pkgdatadir), last.
 * The data directories hold ocio/ and presets/, as samples/ does in the
 * source tree.
 *
 * Thread safety: the lists are computed once (pthread_once) and read only. */
#ifndef FP_INSTALL_H
#define FP_INSTALL_H

#include <stddef.h>

#define FP_INSTALL_MAX 8

typedef enum { FP_INSTALL_MODULES, FP_INSTALL_DATA } fp_install_kind_t;

/* The directories for `kind`, best first: sets *dirs to an array of
 * strings that stays valid for the process and returns their count. */
int fp_install_dirs(fp_install_kind_t kind, const char *const **dirs);

/* The first readable regular file `rel` ("ocio/config.ocio",
 * "presets/NAME.preset") in the data directories: 0 and its path, or -1
 * with the places looked in ("a, b, c") in `tried`. */
int fp_install_find(const char *rel, char *path, size_t n, char *tried, size_t tried_n);

#endif
