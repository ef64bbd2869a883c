/* fogpipe: add physically based fog to color + depth OpenEXR frames.
 *
 * The program is the library's public API (fogpipe.h) and nothing else:
 * parse the command line, run it, print what the library reports on
 * stderr, turn the status into the exit status. */
#include "fogpipe.h"

#include <stdio.h>
#include <stdlib.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

static void to_stderr(void *user, int kind, const char *text)
{
    (void)user;
    (void)kind;
    fputs(text, stderr);
    if (kind == FOGPIPE_MSG_PROGRESS)
        fflush(stderr);
}

int main(int argc, char **argv)
{
#ifdef __GLIBC__
    /* A sequence allocates the same frame-sized buffers (tens of MB at
     * 1080p) for every frame.  glibc hands blocks that big to mmap and back
     * to the kernel when freed, and trims its heaps, so every frame faulted
     * in (and the kernel zeroed) ~100 MB of fresh pages again: a fifth of
     * the CPU of a 1080p frame with height fog (perf).  The program keeps them in
     * its heap instead; a library host keeps its own allocator's policy.
     * One heap for every thread: the reader allocates a frame and the
     * writer frees it, and glibc's per-thread arenas (64 MB heaps, unmapped
     * when empty whatever the trim threshold) kept faulting in fresh pages
     * (1080p, 32 frames with height fog: 124k page faults and 490 MB
     * resident with an arena per thread, 72k and 420 MB with one). */
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    mallopt(M_ARENA_MAX, 1);
#endif
    fogpipe_t *fp;
    if (fogpipe_new(&fp) != FOGPIPE_OK) {
        fputs("fogpipe: out of memory\n", stderr);
        return 1;
    }
    fogpipe_set_message_handler(fp, to_stderr, NULL);
    /* The environment's default, below presets and the command line. */
    const char *progress = getenv("FOGPIPE_PROGRESS");
    int rc = FOGPIPE_OK;
    if (progress && *progress)
        rc = fogpipe_set(fp, "progress", progress, "$FOGPIPE_PROGRESS");
    if (rc == FOGPIPE_OK)
        rc = fogpipe_parse_args(fp, argc, argv);
    if (rc == FOGPIPE_OK)
        rc = fogpipe_run(fp, FOGPIPE_RUN_SIGNALS);
    fogpipe_free(fp);
    return rc == FOGPIPE_OK ? 0 : rc == FOGPIPE_EUSAGE ? 2 : rc > FOGPIPE_ESIGNAL ? rc : 1;
}
