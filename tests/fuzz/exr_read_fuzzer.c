/* libFuzzer entry point for the EXR frame reader: every input is one frame
 * held in memory, read as fogpipe reads any frame (fp_exr_read_memory:
 * the checks of src/exr/exr_check.c, the C path, the C++ codec path for DWA
 * and B44), and a frame that reads is encoded again as the writer would.
 * Nothing may crash, leak or trip a sanitizer; errors are the normal
 * outcome and their messages are dropped.
 *
 * Built by `make tests/fuzz/exr_read_fuzzer` where configure found a
 * compiler that links -fsanitize=fuzzer (clang); the reader's sources are
 * compiled into it with coverage.  Run it from the test frames (new inputs
 * go to the first directory, so it is a new one):
 *   mkdir corpus && tests/fuzz/exr_read_fuzzer -max_len=1048576 \
 *     -rss_limit_mb=1024 -max_total_time=600 corpus samples/out
 * (-rss_limit_mb: a file under 1 MB must not make the reader take 1 GB). */
#include "exrio.h"
#include "fp.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static void drop(void *user, int kind, const char *text, size_t len)
{
    (void) user;
    (void) kind;
    (void) text;
    (void) len;
}

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void) argc;
    (void) argv;
    fp_msg_set_emitter(drop, NULL);
    fp_exr_set_threads(1); /* the same path every run */
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    void *buf = malloc(size ? size : 1);
    if (!buf)
        return 0;
    if (size)
        memcpy(buf, data, size);
    fp_exr_select_t sel = FP_EXR_SELECT_INITIALIZER;
    sel.need_color = 0;
    sel.need_depth = 0;
    fp_frame_t *f = NULL;
    if (fp_exr_read_memory(buf, size, "<fuzz>", 1, &sel, &f) == FP_OK) {
        fp_exr_write_opts_t opts = FP_EXR_WRITE_OPTS_INITIALIZER;
        void *out = NULL;
        size_t out_size = 0;
        if (fp_exr_encode(f, NULL, &opts, "<fuzz-out>", 1, &out, &out_size) == FP_OK)
            free(out);
        fp_frame_free(f);
    }
    return 0;
}
