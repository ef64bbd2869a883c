/* fogpipe: common definitions shared by every module.
 *
 * Conventions (STYLE.md): every fallible function returns an int status,
 * FP_OK (0) on success; outputs come last; one exit path frees what the
 * function made.  Messages are one line on stderr, prefixed "fogpipe: ",
 * naming the file, the frame and what was expected. */
#ifndef FP_H
#define FP_H

#include <stddef.h>
#include <stdio.h>
#include <stdarg.h>

#include "fp_ctx.h"

enum {
    FP_OK = 0,
    FP_ERR = 1,       /* runtime error: bad input file, I/O, device */
    FP_EUSAGE = 2,    /* usage error: unknown option, value out of range */
    FP_EOF = 3,       /* clean end of a stream (not an error for callers that expect it) */
    FP_ESIGNAL = 128  /* stopped by a signal: FP_ESIGNAL + the signal number is the exit
                         status (130 for SIGINT, 143 for SIGTERM) */
};

#define FP_ARRAY_LEN(a) (sizeof(a) / sizeof((a)[0]))

/* Print "fogpipe: <message>\n" on stderr.  Returns FP_ERR so that callers
 * can write `return fp_error(...)`. */
int fp_error(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Same, returning FP_EUSAGE. */
int fp_usage_error(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* "fogpipe: warning: <message>" unless the context is quiet. */
void fp_warn(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Verbose/informational message, printed only when the context is verbose. */
void fp_info(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* The current context's verbosity (src/base/fp_ctx.h), as lvalues. */
#define fp_quiet (fp_ctx()->quiet)
#define fp_verbose (fp_ctx()->verbose)

/* Where messages go: stderr, unless the current context has an emitter
 * (the library's API sets its own so that it never prints).  `kind` says what the
 * text is; FP_MSG_KEPT is a buffer of whole lines kept by a frame
 * (errors, warnings and info mixed), FP_MSG_PROGRESS the progress output
 * (for a terminal it holds "\r" and escape codes). */
enum { FP_MSG_ERROR = 0, FP_MSG_WARNING, FP_MSG_INFO, FP_MSG_KEPT, FP_MSG_PROGRESS };
/* The current context's emitter (NULL: stderr). */
void fp_msg_set_emitter(fp_emit_fn fn, void *user);
void fp_emit(int kind, const char *text, size_t len);

/* Kept messages.  While a thread has a sink (fp_msg_capture), its messages
 * (errors, warnings, info) are appended to the sink, whole lines, instead
 * of printed; fp_msg_flush prints them later.  The frame loop keeps each
 * frame's messages with the frame, so they come out in frame order whichever
 * thread read, computed or wrote it. */
typedef struct fp_msgbuf_t {
    char *text;
    size_t len, cap;
} fp_msgbuf_t;
/* Set the calling thread's sink (NULL: print again); returns the previous. */
fp_msgbuf_t *fp_msg_capture(fp_msgbuf_t *sink);
/* Print the kept lines on stderr and empty the buffer. */
void fp_msg_flush(fp_msgbuf_t *b);
void fp_msg_free(fp_msgbuf_t *b);

/* mkdir -p: `dir` and its missing parents (0777 less the umask).  0 when
 * it is a directory afterwards, -1 with errno set otherwise. */
int fp_mkdir_p(const char *dir);

/* The directory that will hold the file `path` (an output frame, a
 * preview), made when missing, as Nuke's and Blender's Write nodes do: one
 * error line naming the file, the frame and the directory otherwise. */
int fp_make_parent_dir(const char *path, long frame);

/* A frame's label for messages: "shot.0012.exr" or "<stdin> frame 3". */
typedef struct fp_where_t {
    const char *file;   /* file name or "<stdin>" */
    long frame;         /* frame number, or stream index */
} fp_where_t;

#endif
