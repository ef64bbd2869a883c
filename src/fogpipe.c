/* fogpipe: add physically based fog to color + depth OpenEXR frames. */
#include "clrt.h"
#include "color.h"
#include "fp.h"
#include "options.h"
#include "pipeline.h"

#include "config.h"

#include <stdlib.h>

int main(int argc, char **argv)
{
    fp_params_t p;
    int rc = fp_options_defaults(&p);
    /* The environment's default, below presets and the command line. */
    const char *progress = getenv("FOGPIPE_PROGRESS");
    if (rc == FP_OK && progress && *progress)
        rc = fp_options_apply(&p, "progress", progress, "$FOGPIPE_PROGRESS");
    if (rc == FP_OK)
        rc = fp_options_parse(argc, argv, &p);
    p.cmd.argc = argc;
    p.cmd.argv = argv;
    if (rc) {
        fp_options_free(&p);
        return rc == FP_EUSAGE ? 2 : 1;
    }
    fp_quiet = p.io.quiet;
    fp_verbose = p.io.verbose;
    if (p.io.preset)
        fp_info("preset: %s", p.io.preset);
    if (p.cmd.help || p.cmd.help_markdown) {
        fp_options_print_help(stdout, p.cmd.help_markdown);
        rc = FP_OK;
    } else if (p.cmd.version) {
        printf("%s %s\n", PACKAGE_NAME, PACKAGE_VERSION);
        rc = FP_OK;
    } else if (p.cmd.list_devices) {
        rc = fp_cl_list_devices(stdout);
    } else if (p.color.list_spaces) {
        rc = fp_color_list(&p, stdout);
    } else {
        rc = fp_pipeline_run(&p);
    }
    fp_options_free(&p);
    if (fflush(stdout) != 0 && rc == FP_OK)
        rc = fp_error("<stdout>: write failed");
    return rc == FP_OK ? 0 : rc == FP_EUSAGE ? 2 : rc > FP_ESIGNAL ? rc : 1;
}
