/* fogpipe: bounded reading of text inputs (preset files, .chan camera
 * files) and the checks made before an image input is handed to a reader
 * that reads until it is satisfied (a fogmap through OpenImageIO).
 *
 * An endless or huge input (/dev/zero, a video given by mistake) fails
 * quickly with a one-line message naming the file and the limit, instead
 * of reading forever. */
#ifndef FP_TEXTFILE_H
#define FP_TEXTFILE_H

#include <stdint.h>
#include <stdio.h>

/* A text input is at most 16 MiB, a line at most 64 KiB, and holds no NUL
 * byte. */
#define FP_TEXT_MAX_BYTES ((int64_t)16 << 20)
#define FP_TEXT_MAX_LINE  ((size_t)64 << 10)

typedef struct fp_text_t {
    FILE *f;
    const char *path;   /* not owned: the caller's, for messages */
    const char *what;   /* "preset", "camera file" */
    char *line;         /* the current line, without its newline */
    size_t cap;
    int64_t bytes;      /* read so far */
    int lineno;
    int err_usage;      /* errors are usage errors (FP_EUSAGE), not FP_ERR */
    int rc;             /* the status of the error fp_text_next printed */
} fp_text_t;

/* Open `path` (regular file, pipe or device alike) as a `what`: FP_OK, or
 * an error "PATH: cannot open WHAT (reason)" with `err_usage` choosing
 * fp_usage_error over fp_error. */
int fp_text_open(fp_text_t *t, const char *path, const char *what, int err_usage);

/* The next line (without "\n" or "\r\n") into *line, valid until the next
 * call: 1 a line, 0 the end of the file, -1 an error printed, its status in
 * t->rc ("PATH:LINE: a line longer than 64 KiB (expected a WHAT, a text
 * file)", "PATH: more than 16 MiB ...", a NUL byte, a read error). */
int fp_text_next(fp_text_t *t, char **line);

void fp_text_close(fp_text_t *t);

/* The whole of a text input (a JSON rig file, whose one line may be long)
 * into a malloc'd, NUL-terminated *out of *len bytes: at most 16 MiB and
 * no NUL byte, else the message fp_text_next would give. */
int fp_text_read_all(const char *path, const char *what, int err_usage, char **out,
                     size_t *len);

/* An image file about to be read by a reader that cannot be bounded from
 * outside (OpenImageIO): FP_OK when `path` is a regular file no larger
 * than the image budget allows (fp_image_limits: its pixels times four
 * float channels, plus 16 MiB of headers); otherwise an error naming the
 * file, `what` ("fogmap") and what was expected.  Devices and pipes are
 * refused: /dev/zero never ends. */
int fp_image_file_check(const char *path, const char *what);
/* That bound in bytes, also what an image read whole from a device or a
 * pipe may grow to. */
int64_t fp_image_file_max_bytes(void);

#endif
