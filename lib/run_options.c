/* fogpipe: the options of a run that are no stage's: input and output,
 * sequences and farms, the rig (the tables; lib/pipeline.c, lib/frameloop.c
 * and lib/rig_apply.c read the fields).  Apart from the code that reads
 * them so that the table of all tables (lib/options.c) reaches them
 * without reaching the frame loop, which applies looks through it. */
#include "options.h"

#include <stddef.h>

#define IO(f) offsetof(fp_params_t, io.f)
const fp_option_t fp_io_options[] = {
    { "input", 'i', FP_OPT_STRING, IO(input), 0, 0, "-", 0, 0, NULL, "PATTERN",
      "input EXR: a file, a sequence (shot.####.exr, shot.%04d.exr), or - for a stream on stdin",
      NULL, 0 },
    { "output", 'o', FP_OPT_STRING, IO(output), 0, 0, "-", 0, 0, NULL, "PATTERN",
      "output EXR: a file, a sequence pattern, or - for a stream on stdout; a .png, .tif or "
      ".jpg name writes the display-referred frame as --preview does", NULL, 0 },
    { "frames", 'f', FP_OPT_STRING, IO(frames), 0, 0, NULL, 0, 0, NULL, "LIST",
      "frames of a sequence: 1001-1100, 1-100x2, 5, -3, 1,3,7-9 (default: all found on disk; "
      "for a stream, the numbers given to its frames)", NULL, 0 },
    { "frame", 0, FP_OPT_INT, IO(frame), 0, 0, NULL, -1e9, 1e9, NULL, "N",
      "the frame number of a single input file, for animated fog and the rig's per-frame "
      "values (default: the number its name ends with, shot.0002.exr: 2; else 1)", NULL, 0 },
    { "depth", 0, FP_OPT_STRING, IO(depth), 0, 0, NULL, 0, 0, NULL, "PATTERN",
      "take depth from a separate EXR sequence (same frame numbers and data window)", NULL, 0 },
    { "color-layer", 0, FP_OPT_STRING, IO(color_layer), 0, 0, NULL, 0, 0, NULL, "PREFIX",
      "color channels PREFIX.R, PREFIX.G, PREFIX.B[, PREFIX.A] (default: R,G,B,A, "
      "else the first <layer>.Combined)", NULL, 0 },
    { "depth-channel", 0, FP_OPT_STRING, IO(depth_channel), 0, 0, NULL, 0, 0, NULL, "NAME",
      "depth channel name (default: Z, depth.Z, else <layer>.Depth.Z)", NULL, 0 },
    { "float", 0, FP_OPT_FLAG, IO(use_float), 0, 0, NULL, 0, 1, NULL, NULL,
      "write color as 32-bit float (default: half)", NULL, 0 },
    { "compression", 0, FP_OPT_STRING, IO(compression), 0, 0, "input", 0, 0, NULL, "NAME",
      "output compression: input (the input's), none, rle, zips, zip, piz, pxr24, b44, b44a, "
      "dwaa, dwab", NULL, 0 },
    { "dwa-level", 0, FP_OPT_REAL, IO(dwa_level), 0, 0, NULL, 0, 1e4, NULL, "LEVEL",
      "DWAA/DWAB compression level, higher is smaller and lossier (default: the input's "
      "dwaCompressionLevel attribute, else 45, as Nuke and OpenEXR)", NULL, 0 },
    { "device", 'd', FP_OPT_STRING, IO(device), 0, 0, NULL, 0, 0, NULL, "N|NAME",
      "OpenCL device: index from --list-devices or part of its name (default: "
      "$FOGPIPE_DEVICE, else the first GPU, else the first device)", NULL, 0 },
    { "cpu", 0, FP_OPT_FLAG, IO(cpu), 0, 0, NULL, 0, 1, NULL, NULL,
      "compute with the C double-precision reference instead of OpenCL (slow; for checks)",
      NULL, 0 },
    { "preset", 0, FP_OPT_STRING, IO(preset), 0, 0, NULL, 0, 0, NULL, "NAME|FILE",
      "a named look (morning-valley-mist, low-sun-shafts, night-street-lamps) or a FILE of "
      "key = value lines; the command line wins", NULL,
      FP_OPTF_CLI_ONLY },
    { "quiet", 'q', FP_OPT_FLAG, IO(quiet), 0, 0, NULL, 0, 1, NULL, NULL,
      "no warnings or progress on stderr", NULL, 0 },
    { "verbose", 'v', FP_OPT_FLAG, IO(verbose), 0, 0, NULL, 0, 1, NULL, NULL,
      "report device, program cache and per-frame timing on stderr", NULL, 0 },
    FP_OPT_END
};

#define RUN(f) offsetof(fp_params_t, run.f)
const fp_option_t fp_run_options[] = {
    { "skip-existing", 0, FP_OPT_FLAG, RUN(skip_existing), 0, 0, NULL, 0, 1, NULL, NULL,
      "leave frames whose output file exists alone (not even read): resumes an interrupted "
      "run", NULL, 0 },
    { "stats", 0, FP_OPT_STRING, RUN(stats), 0, 0, NULL, 0, 0, NULL, "FILE",
      "write per-frame timings (read, decode, fog, composite, encode, write) and totals as "
      "JSON to FILE at the end", NULL, 0 },
    { "progress", 0, FP_OPT_ENUM, RUN(progress), 0, 0, "auto", 0, 0, "auto|bar|lines|off",
      "auto|bar|lines|off",
      "progress on stderr: an updating line (bar), one line per frame for farm logs "
      "(lines: \"fogpipe: progress: 3 of 100 frames (3%), frame 1003 in 2.1 s, 3:24 left\"), "
      "or none; auto: bar on a terminal, else lines ($FOGPIPE_PROGRESS sets the default)",
      NULL, 0 },
    { "pipeline", 0, FP_OPT_ENUM, RUN(pipeline), 0, 0, "on", 0, 0, "off|on", "off|on",
      "decode the next frame and encode the previous one on their own threads while the "
      "device computes (off: one frame at a time on one thread, for debugging)", NULL, 0 },
    { "io-threads", 0, FP_OPT_INT, RUN(io_threads), 0, 0, "0", 0, 64, NULL, "N",
      "threads that decode and encode the chunks of one EXR frame at once (0: one per "
      "core; --pipeline off: one); the bytes written are the same", NULL, 0 },
    { "max-image-pixels", 0, FP_OPT_STRING, RUN(max_image_pixels), 0, 0, NULL, 0, 0, NULL,
      "N", "refuse images (EXR frames, fogmaps) of more than N pixels, from their header "
      "before anything is decoded (256M, the default, is 16384x16384; K, M, G: powers of "
      "1024); the longest axis allowed and the bytes of a line scale with it", NULL, 0 },
    { "no-fog", 0, FP_OPT_FLAG, RUN(no_fog), 0, 0, NULL, 0, 1, NULL, NULL,
      "benchmark: skip the fog, only read, decode, encode and write (the I/O floor)", NULL,
      FP_OPTF_HIDDEN },
    FP_OPT_END
};

#define LI(f) offsetof(fp_params_t, light.f)
const fp_option_t fp_rig_options[] = {
    { "rig", 0, FP_OPT_STRING, IO(rig), 0, 0, NULL, 0, 0, NULL, "FILE",
      "the rig as a JSON file (fogpipe rig schema 1: up, clip_start, shadow_map with # runs, "
      "lights, per-frame \"frames\"), over what the frames carry", NULL, 0 },
    { "lights", 0, FP_OPT_ENUM, LI(lights_from), 0, 0, "frame", 0, 0, "frame|none",
      "frame|none",
      "the suns, lights and shadow map the frames (or --rig) carry: used (frame) or ignored "
      "(none); --sun, --light and --shadow-map override them either way", NULL, 0 },
    FP_OPT_END
};
