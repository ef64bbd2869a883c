/* libfogpipe: physically based fog for rendered images, as a library.
 *
 * The fog of the fogpipe command line (which is a small program on top of
 * this header), for hosts that hold images in memory: a compositor plug-in,
 * a Blender or Python script, a render farm's own tools.
 *
 *   fogpipe_t *fp;
 *   if (fogpipe_new(&fp) != FOGPIPE_OK) ...            (out of memory)
 *   fogpipe_set(fp, "preset", "low-sun-shafts", NULL);
 *   fogpipe_set(fp, "density", "0.05", NULL);
 *   fogpipe_frame_t in = FOGPIPE_FRAME_INITIALIZER;
 *   in.width = w; in.height = h; in.rgba = rgba; in.depth = z;
 *   in.world_to_camera = w2c; in.world_to_ndc = w2ndc;
 *   if (fogpipe_apply(fp, &in, out, NULL, NULL) != FOGPIPE_OK)
 *       fprintf(stderr, "%s\n", fogpipe_error(fp));
 *   fogpipe_free(fp);
 *
 * Build with `pkg-config --cflags --libs fogpipe`.
 *
 * Options.  Every option of the command line (`fogpipe --help`, the
 * README's option reference) is set by its long name, without or with the
 * leading "--", and its value written as on the command line ("0,4" for a
 * pair, "1"/"0" or "true"/"false" for a flag).  The same table parses,
 * range-checks and documents both.  "preset" reads a named look or a file
 * of options at once; options set later win over it.
 *
 * Errors.  Every fallible call returns FOGPIPE_OK (0) or an error code and
 * keeps a one-line message in the context (fogpipe_error), naming the file
 * or frame and what was expected.  The library never exits and never
 * prints: its warnings, verbose output and progress go to the handler set
 * by fogpipe_set_message_handler, and are dropped without one.
 * (fogpipe_run's listings — --help, --list-devices, --print-camera — and
 * an output stream of "-" are written to stdout: the caller asked for
 * them.)
 *
 * Ownership.  The context owns what it makes; arrays passed in stay the
 * caller's and are not kept after the call returns.  Strings returned are
 * the context's, valid until its next call.
 *
 * Threads.  A context is used by one thread at a time; contexts on
 * different threads run at once.  Everything a call changes is its
 * context's: its OpenCL device and programs, where its messages go, its
 * verbosity, its image budget, the warnings it has given once, and the
 * threads the call starts run in it (doc/design.md).  Calls on one context
 * from several threads wait for each other; fogpipe_free while another
 * thread is in a call on the same context waits for that call to return.
 * Only the program's signal handling (fogpipe_run with FOGPIPE_RUN_SIGNALS)
 * is the process's, as signals are.  The library
 * keeps the list of live contexts: a call on a freed context (or one that
 * was waiting for the lock while another thread freed it) is refused with
 * FOGPIPE_EUSAGE without touching it, a second fogpipe_free does nothing,
 * and fogpipe_error says "not a live context".  A host must still not free
 * a context that another thread may call next: a later fogpipe_new may be
 * given the same address.
 *
 * Callbacks.  A message handler runs inside the call, under its context's
 * lock, one message at a time: on the calling thread, or during
 * fogpipe_run on one of the frame loop's threads.  From a handler,
 * fogpipe_error, fogpipe_version and fogpipe_set_message_handler work;
 * fogpipe_free marks
 * the context (any context) to be freed when the call in progress returns
 * (that call still finishes); every other call (fogpipe_new, _set,
 * _parse_args, _apply, _run), on any context, is refused with
 * FOGPIPE_ERROR and the message "...: called from a message handler",
 * never a deadlock.  A handler must not wait for another thread's call
 * on the same context (that thread waits for the lock this call holds).
 *
 * ABI.  Symbols carry the version node FOGPIPE_0 (libfogpipe.so.0); only
 * the fogpipe_* names below are exported.  Structures given by pointer
 * start from their _INITIALIZER so that fields added at their end keep
 * old callers working. */
#ifndef FOGPIPE_H
#define FOGPIPE_H

#ifdef __cplusplus
extern "C" {
#endif

/* Return codes. */
enum {
    FOGPIPE_OK = 0,
    FOGPIPE_ERROR = 1,     /* bad input, I/O, device, a call in the wrong state */
    FOGPIPE_EUSAGE = 2,    /* unknown option, value out of range, bad argument */
    FOGPIPE_ESIGNAL = 128  /* fogpipe_run stopped by SIGINT/SIGTERM: 128 + the signal */
};

typedef struct fogpipe fogpipe_t;

/* A context with every option at its default.  *out is NULL on failure. */
int fogpipe_new(fogpipe_t **out);
/* Frees the context and everything it made (NULL, and a context already
 * freed, are ignored; see Threads and Callbacks above). */
void fogpipe_free(fogpipe_t *ctx);

/* The message of the last failed call on `ctx` ("" if none): one line. */
const char *fogpipe_error(const fogpipe_t *ctx);

/* The library's version, e.g. "0.1.0". */
const char *fogpipe_version(void);

/* Set one option: `name` as on the command line ("density",
 * "--fog-color"), `value` as written there (NULL for a flag means on).
 * `origin` labels a bad value's message (NULL: "fogpipe_set"). */
int fogpipe_set(fogpipe_t *ctx, const char *name, const char *value, const char *origin);

/* Parse a command line (argv[0] is the program; presets first, the
 * command line wins), as the fogpipe program does.  argc strings, none
 * NULL; the context keeps its own copy (for --stats), so the caller may
 * free argv when the call returns. */
int fogpipe_parse_args(fogpipe_t *ctx, int argc, char **argv);

/* Messages: `kind` is one of FOGPIPE_MSG_*; `text` holds whole lines,
 * each ending in "\n" ("fogpipe: warning: ..."), except progress on a
 * terminal, which redraws one line with "\r". */
enum {
    FOGPIPE_MSG_ERROR = 0,
    FOGPIPE_MSG_WARNING,
    FOGPIPE_MSG_INFO,     /* -v / verbose */
    FOGPIPE_MSG_LINES,    /* a frame's kept lines, errors, warnings and info in order */
    FOGPIPE_MSG_PROGRESS
};
typedef void (*fogpipe_message_fn)(void *user, int kind, const char *text);
/* NULL drops them (the default).  The handler runs under the library's
 * lock: it must not call the library except as Callbacks above says. */
void fogpipe_set_message_handler(fogpipe_t *ctx, fogpipe_message_fn fn, void *user);

/* One frame in memory.  Row 0 is the top row; pixels are scene-linear
 * float32 in the input color space (--input-space). */
typedef struct fogpipe_frame_t {
    int width, height;
    const float *rgba;             /* width*height*4 */
    const float *depth;            /* width*height: planar camera z (see --depth-kind) */
    /* OpenEXR's camera attributes (row-major 4x4, row vectors: p' = p M),
     * or NULL to take the camera from the options (--camera-pos ...). */
    const double *world_to_camera; /* 16 */
    const double *world_to_ndc;    /* 16 */
    long frame;                    /* the frame number: animation time = frame / --fps */
    const char *name;              /* for messages; NULL: "<memory>" */
} fogpipe_frame_t;
#define FOGPIPE_FRAME_INITIALIZER { 0, 0, (const float *)0, (const float *)0, \
                                    (const double *)0, (const double *)0, 1, (const char *)0 }

/* Fog `in` with the context's options and write the composite (RGBA,
 * width*height*4 floats, in the output color space) to `out_rgba`, which
 * may be in->rgba itself.  When not NULL, `out_fog_rgba` (w*h*4) gets the
 * fog layer of --aov (in-scattered light premultiplied, alpha 1 - tau) and
 * `out_transmittance` (w*h*3) the transmittance.  The device, programs and
 * fogmap are set up by the first call and kept while no option changes. */
int fogpipe_apply(fogpipe_t *ctx, const fogpipe_frame_t *in, float *out_rgba,
                  float *out_fog_rgba, float *out_transmittance);

/* The fog of `in` as deep samples: what --deep writes (README "Deep
 * compositing"), whatever that option says.  Pixel i holds counts[i]
 * samples from offsets[i]: premultiplied RGBA (the output color space),
 * Z and ZBack (the depth's convention), sorted and not overlapping; the
 * fog's volumetric samples, then the surface as a point sample at its
 * depth.  *out is the caller's: free it with fogpipe_deep_free. */
typedef struct fogpipe_deep_t {
    int width, height;
    const unsigned int *counts;          /* width*height */
    const unsigned long long *offsets;   /* width*height + 1 */
    unsigned long long total;            /* samples */
    const float *rgba;                   /* total*4 */
    const float *z, *zback;              /* total */
} fogpipe_deep_t;
int fogpipe_apply_deep(fogpipe_t *ctx, const fogpipe_frame_t *in, fogpipe_deep_t **out);
void fogpipe_deep_free(fogpipe_deep_t *d);

/* Files and streams: run the options' -i/-o (and --frames, ...) as the
 * command line does, or the command asked for (--help, --version,
 * --list-devices, --list-spaces) onto stdout.  FOGPIPE_RUN_SIGNALS
 * catches SIGINT and SIGTERM to stop cleanly (the program's behaviour: a
 * second signal ends the process); a host leaves it out. */
enum { FOGPIPE_RUN_SIGNALS = 1 };
int fogpipe_run(fogpipe_t *ctx, int flags);

#ifdef __cplusplus
}
#endif

#endif
