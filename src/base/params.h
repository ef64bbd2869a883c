/* fogpipe: every user-settable parameter, grouped by stage.
 *
 * The single source of truth for names, defaults and ranges is the option
 * table of each stage (FP_OPTIONS in its .c file); this struct only holds
 * the values.  See src/base/options.h. */
#ifndef FP_PARAMS_H
#define FP_PARAMS_H

#define FP_MAX_GIVEN 256

enum { FP_DEPTH_PLANAR = 0, FP_DEPTH_RADIAL = 1, FP_DEPTH_INVERSE = 2 };
enum { FP_UP_Y = 0, FP_UP_Z = 1 };
/* Rotation orders, named by the axes in the order they are applied (the
 * choices of --chan-order, in this order). */
enum { FP_ORDER_XYZ, FP_ORDER_XZY, FP_ORDER_YXZ, FP_ORDER_YZX, FP_ORDER_ZXY, FP_ORDER_ZYX };
enum { FP_FIT_AUTO = 0, FP_FIT_HORIZONTAL = 1, FP_FIT_VERTICAL = 2 };

typedef struct fp_io_params_t {
    char *input;          /* pattern, file, or "-" for stdin */
    char *output;         /* pattern, file, or "-" for stdout */
    char *depth;          /* separate depth sequence pattern */
    char *frames;         /* frame list, "1001-1100", "1-9x2,12" */
    char *color_layer;
    char *depth_channel;
    int use_float;
    char *compression;    /* "input" or a name */
    double dwa_level;     /* DWAA/DWAB level; used only when given (else the input's) */
    char *device;
    int cpu;              /* C reference instead of OpenCL */
    char *preset;
    char *rig;            /* --rig FILE: the rig as JSON (src/scene/rig.h) */
    int frame;            /* --frame N: a single input file's frame number */
    int quiet;
    int verbose;
} fp_io_params_t;

typedef struct fp_camera_params_t {
    double pos[3];
    double target[3];
    double rot[3];        /* degrees, applied Z, then X, then Y (Nuke's ZXY) */
    double vfov;          /* degrees */
    char *chan;           /* Nuke .chan file */
    int chan_order;       /* FP_ORDER_*: the order .chan rotations are applied in */
    int chan_up;          /* FP_UP_*: the up axis of the .chan's coordinates */
    double chan_sensor[2];/* mm; given: the .chan's FOV is Blender's angle_y */
    int chan_fit;         /* FP_FIT_*: Blender's sensor fit, with chan_sensor */
    int up;               /* FP_UP_Y / FP_UP_Z */
    int depth_kind;       /* FP_DEPTH_* */
    double far;           /* depth beyond this is sky */
    double clip_start;    /* fog starts at this planar depth (Cycles' clip start) */
} fp_camera_params_t;

typedef struct fp_fog_params_t {
    double density;       /* extinction per scene unit */
    double height[3];     /* Y0, H, TOP */
    double color[3];      /* fog color (in-scattered ambient radiance) */
    double haze;          /* homogeneous haze, extinction per scene unit */
    double haze_height[3];
    double box[6];        /* X0,Y0,Z0,X1,Y1,Z1, fog frame */
    double offset[3];
    double rotate;        /* degrees about the vertical */
    int sky;              /* 0: fog the sky too, 1: keep it as it is */
} fp_fog_params_t;

enum { FP_BASIS_HAAR = 0, FP_BASIS_LINEAR, FP_BASIS_QUADRATIC, FP_BASIS_CUBIC };
enum { FP_INTEGRATOR_EXACT = 0, FP_INTEGRATOR_MARCH = 1, FP_INTEGRATOR_REFERENCE = 2 };

typedef struct fp_fogmap_params_t {
    char *fogmap;         /* image file */
    char *channel;
    double rect[4];       /* A0,B0,A1,B1: world rectangle the fogmap covers */
    int basis;            /* B-spline degree */
    int wrap;             /* FP_WRAP_* */
    int levels;
    double lod_mu;
    double lod_footprint; /* pixels */
    double lod_bound;     /* largest |dtau| the dropped levels may make (0: exact) */
    double min_transmittance;
    int integrator;
    int steps;
    int jitter;
    int sparse;
    int deconstruct;
    char *preview;        /* directory for --fogmap-preview */
    char *cache;          /* --fogmap-cache DIR|off (filters/fogmap_cache.h); NULL: default */
} fp_fogmap_params_t;

enum { FP_INTERP_HOLD = 0, FP_INTERP_LINEAR, FP_INTERP_SMOOTH };
enum { FP_ADVECT_OFF = 0, FP_ADVECT_SL, FP_ADVECT_MACCORMACK };

/* Animation (filters/animate.c): time t = frame / fps. */
typedef struct fp_animate_params_t {
    double fps;
    double wind[3];       /* horizontal wind (scene units/s) and turning rate (deg/s) */
    int interp;           /* FP_INTERP_*: between the keys of a fogmap sequence */
    double turbulence;    /* amount, times the fogmap's mean */
    double turbulence_speed;
    int seed;
    int advect;           /* FP_ADVECT_* */
    int advect_start;     /* frame at which the advected fogmap is the fogmap */
    char *cache_dir;      /* advection states */
} fp_animate_params_t;

/* Local and extra directional lights: no fixed limit (fp_light_append,
 * filters/scatter.h); FP_MAX_LIGHTS only bounds what one run may hold. */
#define FP_MAX_LIGHTS 65536
enum { FP_LIGHTS_FRAME = 0, FP_LIGHTS_NONE = 1 };
enum { FP_LAMP_SHADOWS_SCREEN = 0, FP_LAMP_SHADOWS_NONE };
enum { FP_SHADOWS_AUTO = 0, FP_SHADOWS_OFF, FP_SHADOWS_WITH_MAP, FP_SHADOWS_WITH_SCREEN,
       FP_SHADOWS_WITH_MAP_SCREEN };
enum { FP_SELF_SHADOW_OFF = 0, FP_SELF_SHADOW_EXACT, FP_SELF_SHADOW_MAP, FP_SELF_SHADOW_AUTO };
enum { FP_LIGHT_QUAD_FAST = 0, FP_LIGHT_QUAD_PANELS };

/* One light (--light, or the frame's rig): kind 0 point, 1 spot, 2 area
 * (axis = the emitting side's normal), 3 directional (an extra sun: axis =
 * the direction toward it, color x intensity its irradiance; no shadow
 * map); position, color, intensity (the scalar multiplier of color: W/sr
 * for point and spot, W/sr along the normal for area), spot axis, inner
 * and outer cone half-angles (degrees, spot_profile 0).  The fields after
 * `outer` are issue 23's (filters/scatter.c gives them their meaning). */
typedef struct fp_light_t {
    int kind;
    double pos[3], color[3], intensity, axis[3], inner, outer;
    int spot_profile;      /* 0: fogpipe's --light spot (inner/outer); 1: Cycles 3.x (blend, cosine) */
    double blend;          /* Cycles spot_blend (spot_profile 1); outer = spot_size/2 */
    double radius;         /* point/spot soft size (Blender shadow_soft_size); 0: a point */
    double u[3], size[2];  /* area: local X axis and extents along u and axis x u */
    int shape;             /* area: 0 rectangle, 1 ellipse */
} fp_light_t;

/* Light in the fog (filters/scatter.c). */
typedef struct fp_light_params_t {
    double sun[3];        /* direction toward the sun (world axes); unset: no sun */
    double sun_color[3];
    double sun_intensity; /* irradiance on a surface facing the sun (Blender's Strength) */
    double albedo;        /* sigma_s / sigma_t */
    char *phase;          /* as given; parsed into the three below */
    int phase_kind;       /* FP_PHASE_* (kernels/phase.h) */
    double phase_g, phase_w;
    char *light;          /* the last --light as given; every one parsed into lights[] */
    fp_light_t *lights;   /* num_lights of them (fp_light_append; freed by fp_options_free) */
    int num_lights, cap_lights;
    int lights_from;      /* FP_LIGHTS_FRAME / FP_LIGHTS_NONE: the rig's lights (src/scene/rig.h) */
    char *shadow_map;     /* pattern of the sun's depth maps */
    int shadow_map_literal; /* shadow_map is one file's name (a frame's rig): no frame
                               number expanded in it */
    int shadows;          /* FP_SHADOWS_* */
    double shadow_bias;   /* scene units, added to each texel's own */
    int shadow_filter;    /* edge ramps, texels each side (0: hard) */
    double screen_shadow[2]; /* distance, thickness */
    int lamp_shadows;     /* FP_LAMP_SHADOWS_*: local lights' screen-space shadows */
    int self_shadow;      /* FP_SELF_SHADOW_* */
    double self_shadow_grid[3];
    int self_shadow_cascades;
    int scatter_steps;
    int light_panels;
    int light_quad;       /* FP_LIGHT_QUAD_* */
    double interleave[2]; /* N x M pattern of per-pixel sample offsets */
    double light_cull;    /* per pixel, the most the lights left out may add (0: none left out) */
    int wants;            /* 1: the look wants the sun's shadow map (a preset's
                             "wants = shadow-map"; filters/shadowcheck.h) */
} fp_light_params_t;

typedef struct fp_color_params_t {  /* filters/color.c */
    char *ocio;           /* OpenColorIO config file */
    char *input_space;    /* colour space names, aliases or roles; NULL: default */
    char *working_space;
    char *output_space;
    char *display;        /* for previews; NULL: the config's default */
    char *view;
    int list_spaces;      /* command: describe the config and exit */
} fp_color_params_t;

typedef struct fp_aov_params_t {    /* filters/aov.c */
    int aov;              /* also write fog.RGBA and transmittance.RGB */
    int aov_only;         /* write only those */
} fp_aov_params_t;

typedef struct fp_preview_params_t {  /* filters/preview.c */
    char *preview;        /* PNG/JPEG/TIFF pattern, one per frame */
    char *contact_sheet;  /* one image tiling the run's previews */
    int columns;          /* of the contact sheet; 0: about square */
    int sheet_size;       /* the contact sheet's longer side at most (pixels) */
} fp_preview_params_t;

/* Monte Carlo reference (filters/reference.c; seed from --seed). */
typedef struct fp_reference_params_t {
    int spp;              /* samples per pixel */
    int bounces;          /* scattering events after the first (0: single scattering) */
    int geometry;         /* 1: scattered paths end where the map and the depth hide both */
} fp_reference_params_t;

/* Fog buffers (filters/buffers.c): depth-aware bilateral blur of the fog
 * layer and reduced-resolution fog with joint bilateral upsampling. */
enum { FP_BLUR_OFF = 0, FP_BLUR_BILATERAL = 1 };
enum { FP_EDGES_UPSAMPLE = 0, FP_EDGES_EXACT = 1 };
typedef struct fp_buffers_params_t {
    int blur;             /* FP_BLUR_* */
    int radius;           /* spatial radius, pixels */
    double sigma;         /* spatial sigma, pixels; 0: radius / 2 */
    double range;         /* range sigma, relative difference of guide distance */
    int iterations;
    double falloff;       /* no blur within this distance of the camera, full at twice it */
    int separable;        /* 1: horizontal then vertical passes; 0: full 2D kernel */
    int resolution;       /* fog computed every `resolution` pixels: 1, 2 or 4 */
    int edges;            /* FP_EDGES_*: depth-edge pixels at reduced resolution */
    double edge_threshold;  /* relative distance difference that makes an edge pixel */
} fp_buffers_params_t;

typedef struct fp_deep_params_t {   /* filters/deep.c */
    int deep;             /* write deep scanline EXR */
    double bound;         /* error the split rule may make */
    int max_samples;      /* fog samples per pixel at most */
    double max_alpha;     /* fog samples split until none is more opaque */
} fp_deep_params_t;

typedef struct fp_run_params_t {    /* lib/pipeline.c, lib/frameloop.c */
    int pipeline;         /* 1: read, compute and write on three threads */
    int progress;         /* FP_PROGRESS_* */
    int catch_signals;    /* not an option: the program's SIGINT/SIGTERM handling */
    int skip_existing;    /* leave frames whose output exists alone */
    char *stats;          /* per-frame timings as JSON */
    int no_fog;           /* benchmark: read and write only (the I/O floor) */
    int io_threads;       /* threads per EXR part's chunks; 0: one per core */
    char *max_image_pixels; /* the image budget (src/base/fp_limits.h); NULL: the default */
} fp_run_params_t;

typedef struct fp_cmd_params_t {
    /* The command line as given (not owned), for --stats. */
    int argc;
    char **argv;
    int help;
    int help_markdown;
    int version;
    int list_devices;
    int print_camera;
} fp_cmd_params_t;

/* The fast multiple-scattering path and --fog-color auto (filters/ms.c). */
enum { FP_MS_AUTO = 0, FP_MS_ON = 1, FP_MS_OFF = 2 };
typedef struct fp_ms_params_t {
    int mode;             /* FP_MS_* (--multiple-scattering) */
    double ground_albedo;
    int color_typed;      /* --fog-color R,G,B given (0: auto) */
} fp_ms_params_t;

typedef struct fp_params_t {
    fp_io_params_t io;
    fp_camera_params_t camera;
    fp_fog_params_t fog;
    fp_fogmap_params_t fogmap;
    fp_animate_params_t anim;
    fp_light_params_t light;
    fp_color_params_t color;
    fp_aov_params_t aov;
    fp_preview_params_t preview;
    fp_run_params_t run;
    fp_reference_params_t reference;
    fp_buffers_params_t buffers;
    fp_deep_params_t deep;
    fp_ms_params_t ms;
    fp_cmd_params_t cmd;
    /* Names of the options the user gave (CLI or preset), for "was this
     * set?" questions such as camera overrides. */
    const char *given[FP_MAX_GIVEN];
    int num_given;
} fp_params_t;

#endif
