/* fogpipe: the fogmap's decomposition cached across runs (issue 26).
 *
 * The set-up of a big still fogmap (the wavelet decomposition, the walk's
 * sum surfaces, the cell bounds of --lod-bound, the tensor grid) grows
 * with the square of its side: 3.7 s for a 4096x4096 map.  The tables it
 * makes depend only on the map's pixels and a few options, so they are
 * kept in a file named by a hash of those (the map's content, not its
 * name or date), and a later run with the same map loads them instead.
 *
 * Where: --fogmap-cache DIR, else DIR/fogmaps under the cache directory of
 * the OpenCL programs (FOGPIPE_CACHE_DIR, $XDG_CACHE_HOME/fogpipe or
 * ~/.cache/fogpipe).  --fogmap-cache off or FOGPIPE_CACHE_DIR=off turn it
 * off.  Only maps of at least FP_FOGMAP_CACHE_MIN pixels are cached (a
 * smaller one decomposes faster than its file is read), never an animated
 * fogmap nor a run of --fogmap-preview (they need the levels themselves).
 *
 * The key holds the decomposition's device (the C reference, or the
 * OpenCL device's name: the two round differently), so a run that loads
 * the tables gives the same bits as one that makes them.  A file that
 * does not read back whole and unchanged (a checksum of its contents) is
 * ignored with a warning and written again; the cache only saves time,
 * so it never fails a run.  Files are written atomically (a temporary
 * file renamed), so runs sharing the directory (a farm) never read half
 * a file.  Nothing is evicted: a 4096x4096 map's file is 255 MB, and
 * removing the directory reclaims the space (the next run writes again). */
#ifndef FP_FOGMAP_CACHE_H
#define FP_FOGMAP_CACHE_H

#include "clrt.h"
#include "integrate.h"
#include "params.h"
#include "wavelet.h"

#define FP_FOGMAP_CACHE_MIN (256 * 256)

typedef struct fp_fogmap_cache_t {
    char *path;     /* the cache file for this map and these options; NULL: no cache */
    unsigned char key[32];
} fp_fogmap_cache_t;

/* Find the cache file for `img` (w x h) under `p`'s options and the
 * decomposition device (`cl`, NULL for the C reference).  c->path stays
 * NULL when the cache is off, the map is small, animated or previewed, or
 * the directory cannot be made (a warning then). */
int fp_fogmap_cache_open(const fp_params_t *p, fp_cl_t *cl, const float *img, int w, int h,
                         fp_fogmap_cache_t *c);

/* Load the tables and the decomposition's figures (m: its scalars and
 * synthesis filters, no levels) from the cache file: 1 when loaded, 0 when
 * absent or unusable (t and m then left empty).  The caller sets what
 * depends on more than the key (the tables' serial, the cells' size in
 * fog units). */
int fp_fogmap_cache_load(const fp_fogmap_cache_t *c, fp_fogmap_t *m, fp_fog_tables_t *t);

/* Write the tables made from a decomposition (m) into the cache file
 * (a warning when that fails). */
void fp_fogmap_cache_store(const fp_fogmap_cache_t *c, const fp_fogmap_t *m,
                           const fp_fog_tables_t *t);

void fp_fogmap_cache_close(fp_fogmap_cache_t *c);

#endif
