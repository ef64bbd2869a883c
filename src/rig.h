/* fogpipe: the rig, what the host knows about the light and the camera's
 * frame besides the camera matrices: up axis, clip start, suns, point,
 * spot and area lights, the sun's shadow map, and the artist's fog look
 * (issue 23: the fogpipe rig schema, version 1).
 *
 * Three carriers: the text form in any string attribute of the frame
 * (Blender's stamp Note, beside "fogpipe-camera 1 ..."):
 *   fogpipe-rig 1 [up y|z] [clip START] [shadow PATH] [lights N] LIGHT...
 *     sun   DX DY DZ  R G B  ANGLE
 *     point X Y Z  R G B  RADIUS
 *     spot  X Y Z  R G B  RADIUS  AX AY AZ  SIZE BLEND
 *     area  X Y Z  R G B  NX NY NZ  UX UY UZ  SU SV  SHAPE
 * the typed attributes fogpipeRigVersion (int 1), fogpipeUp, fogpipeClipStart,
 * fogpipeShadowMap, fogpipeRig (the whole text form) and fogpipeLook, and a
 * JSON rig file (--rig FILE) with per-frame overrides.  Precedence: a
 * command-line flag > the rig file > typed attributes > the text.
 *
 * All of it is per frame: the frame loop reads each frame's rig on the
 * thread that computes it (fp_rig_frame, fp_rig_apply), so animated lights
 * change with the frame.  The up axis and the look are the run's, from the
 * rig file or else the first frame (fp_rig_prescan). */
#ifndef FP_RIG_H
#define FP_RIG_H

#include <stdint.h>
#include <stdio.h>

#include "exrio.h"
#include "params.h"

#define FP_RIG_MAX_LIGHTS 4096

enum { FP_RIG_SUN = 0, FP_RIG_POINT, FP_RIG_SPOT, FP_RIG_AREA };

typedef struct fp_rig_light_t {
    int type;          /* FP_RIG_* */
    double pos[3];     /* point, spot, area */
    double dir[3];     /* sun: toward it (unit); spot: where it points; area: its normal */
    double rgb[3];     /* sun: irradiance; point, spot: W/sr; area: W/sr along the normal */
    double angle;      /* sun: angular diameter, degrees */
    double radius;     /* point, spot: Blender's shadow_soft_size */
    double size;       /* spot: full cone angle, degrees */
    double blend;      /* spot: spot_blend, 0..1 */
    double u[3];       /* area: its local X axis (unit) */
    double extent[2];  /* area: size along u and along dir x u */
    int shape;         /* area: 0 rectangle, 1 ellipse */
} fp_rig_light_t;

typedef struct fp_rig_t {
    int has_up, up;            /* FP_UP_* */
    int has_clip;
    double clip;
    char *shadow;              /* the sun's shadow map (a file name); NULL: none */
    int has_lights;            /* lights given (possibly none: "lights 0") */
    int nlights;
    fp_rig_light_t *lights;
    char *look;                /* "fogpipe-look 1 name=value ..." or NULL */
    char look_from[300];       /* where the look came from, for messages */
    int any;                   /* something was given */
    char *cut;                 /* the lights' text was cut off with no fogpipeRig: the
                                  error, raised only if the lights are used (fp_rig_apply) */
} fp_rig_t;

void fp_rig_free(fp_rig_t *r);
/* Fields of `over` replace those of `dst` (deep copies). */
int fp_rig_merge(fp_rig_t *dst, const fp_rig_t *over);

/* The text form from `text` (the first "fogpipe-rig" in it, up to the end
 * or the next "fogpipe-..." token).  `what` names it in messages ("file:
 * frame N: attribute 'Note'").  *declared gets N of "lights N" (-1: not
 * said), *complete whether that many lights followed. */
int fp_rig_parse_text(const char *text, const char *what, fp_rig_t *out, int *declared,
                      int *complete);

/* The rig a frame's header carries (text, then typed attributes over it);
 * out->any 0 when none. */
int fp_rig_from_frame(const fp_frame_info_t *info, const char *where_file, long frame,
                      fp_rig_t *out);

/* A JSON rig file (--rig FILE), whole. */
typedef struct fp_rig_file_t fp_rig_file_t;
int fp_rig_file_load(const char *path, fp_rig_file_t **out);
void fp_rig_file_free(fp_rig_file_t *f);
/* The file's rig for `frame`: its keys with "frames" {"N": {...}} over
 * them; "shadow_map"'s # runs expanded with the frame number. */
int fp_rig_file_frame(const fp_rig_file_t *f, long frame, fp_rig_t *out);

/* This frame's rig: the frame's own under the rig file's (either may be
 * absent: file NULL, info NULL). */
int fp_rig_frame(const fp_rig_file_t *file, const fp_frame_info_t *info,
                 const char *where_file, long frame, fp_rig_t *out);

/* The run's up axis and look, before anything is committed: from the rig
 * file, else the first frame's rig (`first`, may be NULL: a stream).  Sets
 * p->camera.up when --up is not given, applies the look under the command
 * line and --preset (fp_options_apply_look). */
int fp_rig_prescan(fp_params_t *p, const fp_rig_file_t *file, const fp_rig_t *first,
                   const char *first_name, long first_frame);

/* --rig FILE loaded into *file (NULL without), then fp_rig_prescan with
 * the first input frame's rig (a file input's header read once more; its
 * errors, if any, are the frame loop's to report).  *has_rig: the file or
 * that frame carries a rig. */
int fp_rig_run_setup(fp_params_t *p, fp_rig_file_t **file, int *has_rig);
/* A single input file's frame number: --frame, else the number its name
 * ends with (fp_seq_frame_of_name), else 1. */
long fp_rig_single_frame(const fp_params_t *p);

/* The frame's parameters: *q = *base with the rig applied under the flags
 * (schema precedence): clip start, the brightest sun as --sun/--sun-color/
 * --sun-intensity, further suns as directional lights, local lights
 * (fp_light_append), the shadow map (relative to the frame file's
 * directory).  q's strings are base's or the rig's: q lives no longer than
 * either, and is released with fp_rig_params_release, never
 * fp_options_free. */
int fp_rig_apply(const fp_params_t *base, const fp_rig_t *rig, const char *where_file,
                 long frame, fp_params_t *q);
void fp_rig_params_release(fp_params_t *q);

/* A key of what the light stage is committed from (sun, lights, shadow
 * map, up): equal keys, the same commit. */
uint64_t fp_rig_light_key(const fp_params_t *q);

/* The warnings of the light stage's commits, one per change of the rig
 * (an animated lamp): each said once a run.  fp_rig_seen returns 1 when
 * the text was seen before, else records it (up to FP_RIG_SEEN_MAX). */
#define FP_RIG_SEEN_MAX 32
typedef struct fp_rig_seen_t {
    uint64_t h[FP_RIG_SEEN_MAX];
    int n;
} fp_rig_seen_t;
int fp_rig_seen(fp_rig_seen_t *s, const char *text, int len);

/* --print-camera: the rig understood for the frame, after the flags. */
void fp_rig_print(FILE *out, const fp_rig_t *rig, const fp_params_t *q);

#endif
