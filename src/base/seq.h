/* fogpipe: file sequences and frame lists.
 *
 * Patterns: printf-style %d / %0Nd, or a run of '#' or '@' with one digit
 * per character (as in Nuke and Blender: "####" is 4 digits, zero padded).
 * Negative frames are written as printf writes them ("%04d" of -5 is
 * "-005"). */
#ifndef FP_SEQ_H
#define FP_SEQ_H

#include <stddef.h>

/* 1 if the pattern has a frame placeholder, 0 if it names one file,
 * -1 if it has more than one placeholder or a malformed %-spec. */
int fp_seq_has_placeholder(const char *pattern);

/* Expand a pattern for one frame.  A pattern without a placeholder is
 * copied.  Returns FP_OK, or FP_EUSAGE (message) when `out` is too small or
 * the pattern is malformed. */
int fp_seq_format(const char *pattern, long frame, char *out, size_t outsz);

typedef struct fp_frame_list_t {
    long *frames;
    size_t count;
} fp_frame_list_t;

/* Parse "1001-1100", "1-100x2", "5", "-3", "-10--1", "1,3,7-9": comma
 * lists of single frames and ranges A-B[xSTEP] (A <= B, STEP >= 1).
 * Duplicates are kept in the given order.  FP_EUSAGE with a message naming
 * the spec on a malformed one. */
int fp_frames_parse(const char *spec, fp_frame_list_t *out);

/* Find the frames of a pattern on disk (sorted ascending): used when
 * --frames is not given.  FP_ERR (message) when none exists. */
int fp_frames_scan(const char *pattern, fp_frame_list_t *out);

void fp_frames_free(fp_frame_list_t *l);

/* The frame number a single file's name carries, as a sequence's file
 * names do: the digits just before its extension ("shot.0002.exr": 2,
 * "render_0017.exr": 17, "shot0017.exr": 17; after a letter at least 4
 * digits: "p3.exr" and "huge_b44.exr" carry none).  1 with *frame set, 0
 * when the name ends in no such number before its extension. */
int fp_seq_frame_of_name(const char *path, long *frame);

#endif
