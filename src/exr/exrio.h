/* fogpipe: EXR frames in and out, through OpenEXR's C API (openexr.h).
 *
 * Every frame, from a file or from stdin, is first held whole in memory and
 * decoded from there through a custom read callback (the in-memory pattern
 * of OpenEXR's ImfCheckFile.cpp), so files and streams share one path.
 *
 * Ownership: an fp_frame_t owns its memory image of the input file, the
 * decoded color and depth, and the raw bytes of every channel it does not
 * touch; fp_frame_free releases all of it.  Functions here are reentrant:
 * different frames may be read/written from different threads at once. */
#ifndef FP_EXRIO_H
#define FP_EXRIO_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

typedef struct fp_frame_t fp_frame_t;

/* How to find color and depth.  NULL/0 fields mean "search by the default
 * names": color R,G,B[,A]; else <layer>.Combined.R/G/B[/A] (Blender
 * multilayer), the first such layer; depth Z, depth.Z, <layer>.Depth.Z
 * (the layer of the color first). */
typedef struct fp_exr_select_t {
    const char *color_layer;   /* prefix: channels "<prefix>.R" ...; "" or NULL = search */
    const char *depth_channel; /* full channel name, e.g. "ViewLayer.Depth.Z" */
    int need_color;            /* 0: color is optional (depth-only files) */
    int need_depth;            /* 0: depth is optional (it comes from --depth PATTERN) */
} fp_exr_select_t;
#define FP_EXR_SELECT_INITIALIZER { NULL, NULL, 1, 1 }

/* The rig (src/scene/rig.h) as a frame's header carries it: the text form in any
 * string attribute (Blender's stamp Note) and the typed attributes.  The
 * strings are the frame's (fp_frame_free frees them); NULL when absent. */
typedef struct fp_rig_attrs_t {
    char *text;                /* a string attribute holding "fogpipe-rig ..." */
    char text_attr[256];       /* its name */
    char *rig;                 /* fogpipeRig (the whole text form) */
    char *up;                  /* fogpipeUp */
    char *shadow_map;          /* fogpipeShadowMap */
    char *look;                /* fogpipeLook, else a string attribute holding "fogpipe-look" */
    char look_attr[256];       /* its name */
    int has_version, version;  /* fogpipeRigVersion */
    int has_clip;              /* fogpipeClipStart */
    double clip;
    char bad[320];             /* a fogpipe* attribute of the wrong type, said as an error */
} fp_rig_attrs_t;

typedef struct fp_frame_info_t {
    /* Data window: the pixels we hold, width*height of them. */
    int data_x0, data_y0, width, height;
    /* Display window: the image's frame for camera NDC. */
    int disp_x0, disp_y0, disp_w, disp_h;
    float pixel_aspect;
    int has_world_to_camera, has_world_to_ndc;
    /* Row-major 4x4, OpenEXR's row-vector convention: p' = p * M,
     * element (r,c) at [r*4+c]. */
    double world_to_camera[16];
    double world_to_ndc[16];
    int compression;           /* exr_compression_t of the color part */
    int num_parts;
    int has_alpha;             /* the color had an alpha channel */
    char color_names[4][256];  /* names of R,G,B,A channels found ("" if none) */
    char depth_name[256];      /* name of the depth channel ("" if none) */
    /* The colour part's "chromaticities" attribute: red x,y, green x,y,
     * blue x,y, white x,y (what primaries the RGB values are in). */
    int has_chromaticities;
    float chromaticities[8];
    /* The value of a string attribute holding "fogpipe-camera ..." (what
     * samples/blender/fogpipe_camera.py puts in Blender's stamp Note: the
     * camera as worldToCamera and worldToNDC in text), and that attribute's
     * name; "" if none.  camera.c parses it. */
    char camera_text[1024];
    char camera_text_attr[256];
    /* The focal length in mm from a "Lens" attribute (Blender's stamp, "50.00
     * mm"), 0 if none: checked against a .chan file's field of view. */
    double lens_mm;
    fp_rig_attrs_t rig;
} fp_frame_info_t;

/* Decode an EXR image held in memory.  Takes ownership of `buf` (from
 * malloc), also on failure: it is freed with the frame.  `where_file` and
 * `frame` only label messages.  On failure prints one line naming the file and frame and
 * returns non-zero. */
int fp_exr_read_memory(const void *buf, size_t size, const char *where_file,
                       long frame, const fp_exr_select_t *sel,
                       fp_frame_t **out);

/* Read a whole file into memory and decode it (fp_exr_read_memory). */
int fp_exr_read_file(const char *path, long frame, const fp_exr_select_t *sel,
                     fp_frame_t **out);
/* Its first half: the file's bytes into a malloc'd buffer (message naming
 * the file and frame on failure), for callers that time reading and
 * decoding apart. */
int fp_exr_load_file(const char *path, long frame, void **buf, size_t *size);

/* Stream framing: read exactly one EXR file from a concatenated stream
 * (stdin) into a malloc'd buffer, using its header, offset table and chunk
 * headers to know where it ends.  Returns FP_OK with *buf and *size set, FP_EOF
 * when the stream is at a clean end before the first byte of a frame, and
 * FP_ERR (message printed: "<stdin>: frame N: truncated ...") otherwise.
 * `index` is the frame's position in the stream, for messages. */
int fp_exr_stream_next(FILE *in, const char *where_file, long index,
                       void **buf, size_t *size);

const fp_frame_info_t *fp_frame_info(const fp_frame_t *f);
/* Color as float RGBA, width*height*4, row-major over the data window,
 * A = 1 when the input had none.  NULL when there was no color. */
float *fp_frame_rgba(fp_frame_t *f);
/* Depth as float, width*height, or NULL when there was none. */
float *fp_frame_depth(fp_frame_t *f);

/* Replace the frame's depth by the depth channel of another frame (the
 * --depth PATTERN sequence).  Fails with a message naming both files when
 * the data windows differ. */
int fp_frame_take_depth(fp_frame_t *f, const char *f_name, fp_frame_t *depth,
                        const char *depth_name, long frame);

/* An extra float channel to add to the output (fog AOVs). */
typedef struct fp_exr_extra_t {
    const char *name;
    const float *data;         /* width*height floats over the data window */
} fp_exr_extra_t;

typedef struct fp_exr_write_opts_t {
    int use_float;             /* write color as FLOAT instead of HALF */
    int compression;           /* exr_compression_t, or -1: the input's */
    const fp_exr_extra_t *extra;
    int num_extra;
    int color_only;            /* 1: drop pass-through channels (AOV-only output) */
    int drop_color;            /* 1: drop the colour channels too (only `extra` is written) */
    /* The colour part's "chromaticities" attribute: 0 passes the input's
     * through, 1 writes `chromaticities` instead (the output colour space's
     * primaries), -1 leaves it out (primaries unknown). */
    int set_chromaticities;
    float chromaticities[8];   /* red x,y, green x,y, blue x,y, white x,y */
    /* DWAA/DWAB compression level (higher: smaller and lossier); < 0: the
     * input's dwaCompressionLevel attribute, else OpenEXR's default 45. */
    float dwa_level;
} fp_exr_write_opts_t;
#define FP_EXR_WRITE_OPTS_INITIALIZER { 0, -1, NULL, 0, 0, 0, 0, { 0 }, -1.0f }

/* Encode the frame to memory: every part, header attribute, data and
 * display window of the input kept; the color channels replaced by `rgba`
 * (width*height*4 floats; written under the input's color channel names,
 * R,G,B,A when the input had no color; A only if the input had alpha or
 * rgba is given for a color-less input); every other channel passed through
 * unchanged; opts->extra channels added to the colour's part (replacing
 * channels of the same name).  Output is scanline.  *out is malloc'd.
 * rgba NULL: the frame's own colour (fp_frame_rgba, possibly edited). */
int fp_exr_encode(const fp_frame_t *f, const float *rgba,
                  const fp_exr_write_opts_t *opts, const char *where_file,
                  long frame, void **out, size_t *out_size);

/* Encode and write atomically: to "<dir>/.<name>.tmp.<pid>" then rename, so
 * the frame appears whole or not at all; the temporary is removed on error. */
int fp_exr_write_file(const fp_frame_t *f, const float *rgba,
                      const fp_exr_write_opts_t *opts, const char *path,
                      long frame);
/* Its second half: write encoded bytes atomically (messages name the
 * frame). */
int fp_exr_write_bytes(const char *path, long frame, const void *buf, size_t size);

/* Read a whole file into a malloc'd buffer (shared helper). */
int fp_read_whole_file(const char *path, void **buf, size_t *size);
/* Write a buffer to `path` atomically (temporary file + rename). */
int fp_write_file_atomic(const char *path, const void *buf, size_t size);

/* Parse a compression name ("none", "rle", "zips", "zip", "piz", "pxr24",
 * "b44", "b44a", "dwaa", "dwab") into exr_compression_t; -1 if unknown.
 * OpenEXR 3.1's C library has no DWA codec: dwaa/dwab go through OpenEXR's
 * C++ library (src/exr/exr_dwa.h), in and out, files and streams alike. */
int fp_exr_compression_from_name(const char *name);
const char *fp_exr_compression_name(int compression);
/* 1 when frames can be written with this compression (exr_compression_t),
 * so that a run can refuse before it computes a frame; 0 if not. */
int fp_exr_compression_writable(int compression);

void fp_frame_free(fp_frame_t *f);

/* Chunks of a frame are decoded and encoded by this many threads at once
 * (the bytes written are the same whatever the count): 0, the default,
 * is one per online core; 1 decodes and encodes on the calling thread.
 * Parts under 65536 pixels always use one.  Process-wide; safe to call
 * from any thread, taken by the next part to be decoded or encoded. */
void fp_exr_set_threads(int n);
/* The count in effect (0 resolved to the number of cores). */
int fp_exr_threads(void);

#endif
