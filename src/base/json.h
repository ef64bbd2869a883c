/* fogpipe: a small strict JSON reader (RFC 8259) for rig files (src/scene/rig.h).
 *
 * Strict: no comments, no trailing commas, no duplicate keys, numbers as
 * JSON writes them and finite, strings valid UTF-8 escapes (\uXXXX, with
 * surrogate pairs), no control characters in strings.  Bounded: at most 64
 * levels deep and 1M values, on top of the 16 MiB of a text input
 * (src/base/textfile.h).  Errors are one line naming the file, the line and
 * what was expected. */
#ifndef FP_JSON_H
#define FP_JSON_H

#include <stddef.h>

typedef enum {
    FP_JSON_NULL = 0,
    FP_JSON_BOOL,
    FP_JSON_NUMBER,
    FP_JSON_STRING,
    FP_JSON_ARRAY,
    FP_JSON_OBJECT
} fp_json_type_t;

typedef struct fp_json_t {
    fp_json_type_t type;
    int line;                  /* where the value starts, for messages */
    int boolean;
    double number;
    char *string;              /* FP_JSON_STRING (NUL-terminated; no NUL inside) */
    int n;                     /* FP_JSON_ARRAY, FP_JSON_OBJECT: children */
    struct fp_json_t *items;
    char **keys;               /* FP_JSON_OBJECT: the children's keys */
} fp_json_t;

/* Parse `text` (len bytes) as one JSON value; `path` labels messages.
 * FP_EUSAGE with a message on malformed input. */
int fp_json_parse(const char *text, size_t len, const char *path, fp_json_t *out);
/* Read and parse a file (bounded, src/base/textfile.h). */
int fp_json_load(const char *path, const char *what, fp_json_t *out);
/* The value of `key` in an object, NULL when absent (or not an object). */
const fp_json_t *fp_json_get(const fp_json_t *obj, const char *key);
const char *fp_json_type_name(fp_json_type_t t);
void fp_json_free(fp_json_t *v);

#endif
