/* fogpipe: the frame loop.  Runs a run's frames through three stages --
 * read (a file, or the next frame of the stdin stream, and decode it),
 * process (camera, fog on the device, composite) and write (encode, then an
 * atomic file write or the frame whole on stdout) -- either pipelined on
 * three threads or one frame at a time on the calling thread.
 *
 * Pipelined: a reader thread runs `next`, the calling thread `process`
 * (it owns the OpenCL device), a writer thread `write`; a queue of one
 * frame between stages, so that the reader decodes frame N+1 and the writer
 * encodes frame N-1 while the device computes frame N, and at most four
 * frames are in memory.
 *
 * Order: frames leave the loop in the order they entered it whatever thread
 * handled them, so the stdout stream, the messages (each frame's messages
 * are kept with it, fp_msg_capture, and printed when it is finished), the
 * progress line and the stats file are in input order.  Errors: the first
 * failed frame (in order) stops the loop; every frame before it is
 * finished, no frame after it is written, its one-line message is the only
 * one printed.  The outputs are the same bytes either way.
 *
 * Signals: while fp_loop_signals_start() is in force SIGINT and SIGTERM
 * (unless ignored on entry, as in background jobs of a non-interactive
 * shell) ask the loop to stop: the write in flight is finished, the frames
 * in flight are dropped, a line names the last complete frame, the stats
 * are written and fp_loop_run returns FP_ESIGNAL + the signal number.  A
 * second signal stops the process at once (_exit), after the file write in
 * flight (fp_loop_commit_begin/end), without the stats; so does the first
 * when the only thread (--pipeline off) is waiting for stdin.  Either way no
 * partial or temporary output file is left. */
#ifndef FP_FRAMELOOP_H
#define FP_FRAMELOOP_H

#include "fp.h"

/* Per-frame timers, milliseconds. */
enum {
    FP_T_READ,       /* file or stream bytes into memory */
    FP_T_DECODE,     /* EXR decoding (and a --depth file's) */
    FP_T_FOGMAP,     /* fogmap decomposition for this frame (0: none needed) */
    FP_T_FOG,        /* camera, view and the fog layer (device or C reference) */
    FP_T_COMPOSITE,  /* tau * color + S */
    FP_T_ENCODE,     /* EXR encoding */
    FP_T_WRITE,      /* atomic file write, or stdout */
    FP_T_COUNT
};
extern const char *const fp_loop_timer_names[FP_T_COUNT];

#define FP_LOOP_PATH 4096

typedef struct fp_loop_job_t {
    long seq;                   /* position in the run, from 0 (set by the loop) */
    long frame;                 /* frame number (set by `next`) */
    char in[FP_LOOP_PATH];      /* input name, for messages and stats */
    char out[FP_LOOP_PATH];     /* output path, "<stdout>", or "" */
    int skipped;                /* set by `next`: nothing to do (--skip-existing) */
    double ms[FP_T_COUNT];      /* stage times, set by the stages */
    double decompose_ms;        /* the fogmap decomposition, part of ms[FP_T_FOGMAP] */
    void *data;                 /* the caller's per-frame state (freed by `release`) */
    /* Loop internals. */
    int status;                 /* FP_OK, or the error that stopped this frame */
    fp_msgbuf_t msgs;
} fp_loop_job_t;

/* The stages.  Each returns FP_OK or an error status (message printed:
 * it is kept with the frame).  `next` and `write` run on their own threads
 * when pipelined: they may only read state they share with `process`. */
typedef struct fp_loop_ops_t {
    void *ctx;
    /* Fill `job` (job->seq set) with the next frame, read and decoded, or
     * marked skipped.  FP_EOF: no more frames (nothing to release). */
    int (*next)(void *ctx, fp_loop_job_t *job);
    /* Compute the frame (not called for a skipped or failed frame). */
    int (*process)(void *ctx, fp_loop_job_t *job);
    /* Encode and write the frame (same). */
    int (*write)(void *ctx, fp_loop_job_t *job);
    /* Free job->data (may be NULL); any thread. */
    void (*release)(void *ctx, fp_loop_job_t *job);
} fp_loop_ops_t;

/* Progress on stderr: an updating line on a terminal (BAR), or one line
 * per finished frame for farm logs (LINES):
 *   fogpipe: progress: 3 of 100 frames (3%), frame 1003 in 2.1 s, 3:24 left
 * ("N frames" and no percentage or time left when the count is unknown, a
 * stream); AUTO picks BAR on a terminal, else LINES. */
enum { FP_PROGRESS_AUTO = 0, FP_PROGRESS_BAR, FP_PROGRESS_LINES, FP_PROGRESS_OFF };

typedef struct fp_loop_opts_t {
    int pipelined;
    int progress;               /* FP_PROGRESS_BAR, _LINES or _OFF (the caller resolved auto) */
    long total;                 /* frames expected; 0: unknown (a stream) */
    const char *stats_path;     /* --stats FILE, or NULL */
    const char *input, *output; /* patterns, for the stats */
    const char *device;         /* "C reference" or the OpenCL device, for the stats */
    int argc;                   /* the command line, for the stats (argv may be NULL) */
    char *const *argv;
    double setup_ms;            /* device, programs, fogmap before the first frame */
    double fogmap_setup_ms;     /* the fogmap's first decomposition, part of setup_ms */
} fp_loop_opts_t;

/* Run every frame.  Returns FP_OK, the first failed frame's status, or
 * FP_ESIGNAL + signal number. */
int fp_loop_run(const fp_loop_ops_t *ops, const fp_loop_opts_t *opts);

/* Catch SIGINT and SIGTERM for the loop (see above).  Call before any
 * thread is made (the OpenCL driver's included), so that every thread
 * inherits the blocked mask; fp_loop_signals_stop restores the previous
 * state. */
int fp_loop_signals_start(void);
void fp_loop_signals_stop(void);
/* The signal asked for, or 0. */
int fp_loop_interrupted(void);

/* Around a read that may block for as long as its producer wants (stdin):
 * on a signal the loop may cancel the reader thread there. */
void fp_loop_blocking_begin(void);
void fp_loop_blocking_end(void);

/* Around the write of an output file or of a frame to stdout: a second
 * signal waits for it.  `done`: the frame now written whole (NULL: none). */
void fp_loop_commit_begin(void);
void fp_loop_commit_end(const fp_loop_job_t *done);

/* Monotonic clock, milliseconds. */
double fp_now_ms(void);

#endif
