/* fp-scene: the sample scene generator of fogpipe.
 *
 * An analytic ray tracer (ground plane, boxes, a wall with gaps, spheres,
 * a low sun with hard shadows) that writes an animated color + depth EXR
 * sequence with the standard worldToCamera / worldToNDC attributes, and
 * per frame the sun's orthographic depth map (its own worldToNDC), and a
 * 64x64 greyscale fogmap (fogmap.exr, channel Y: patches of fog with clear
 * gaps, for --fogmap), with OpenEXR's C API.  Deterministic: the same bytes
 * every run.
 *
 *   fp-scene -o DIR [--width W] [--height H] [--frames A-B]
 *            [--layout plain|blender] [--shadow-size N] [--sky-depth V]
 *
 * Conventions (OpenEXR's): world right-handed, +Y up, meters; matrices
 * row-vector (p' = p M); camera space +x right, +y up, +z the viewing
 * direction; NDC (0,0) top-left, (1,1) bottom-right of the display window.
 * Depth Z is planar (camera-space z); sky is +inf unless --sky-depth. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

typedef struct { double x, y, z; } vec3;

static vec3 v3(double x, double y, double z) { return (vec3){ x, y, z }; }
static vec3 add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static vec3 sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static vec3 mul(vec3 a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static double dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static vec3 cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static vec3 norm(vec3 a) { return mul(a, 1 / sqrt(dot(a, a))); }

/* ------------------------------------------------------------ scene */

typedef struct { vec3 lo, hi, color; } box_t;
typedef struct { vec3 c; double r; vec3 color; } sphere_t;

static const box_t boxes[] = {
    /* the wall at z = 40, 6 m high, with four 2 m gaps for light shafts */
    { { -40, 0, 40 }, { -17, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { -15, 0, 40 }, { -7, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { -5, 0, 40 }, { 3, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { 5, 0, 40 }, { 13, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { 15, 0, 40 }, { 40, 6, 41 }, { 0.55, 0.5, 0.45 } },
    /* near boxes */
    { { -8, 0, 20 }, { -5, 3, 23 }, { 0.7, 0.25, 0.2 } },
    { { 6, 0, 15 }, { 9, 5, 18 }, { 0.2, 0.4, 0.7 } },
    /* tall far boxes: the fog's depth gradient */
    { { -20, 0, 80 }, { -12, 25, 88 }, { 0.6, 0.6, 0.62 } },
    { { 10, 0, 110 }, { 20, 40, 120 }, { 0.5, 0.55, 0.6 } },
    { { -45, 0, 140 }, { -28, 18, 150 }, { 0.62, 0.58, 0.5 } },
    { { 30, 0, 60 }, { 36, 12, 66 }, { 0.45, 0.5, 0.4 } },
};
static const sphere_t spheres[] = {
    { { 0, 1, 12 }, 1, { 0.8, 0.8, 0.75 } },
    { { -3, 0.7, 8 }, 0.7, { 0.9, 0.6, 0.1 } },
    { { 4, 2, 30 }, 2, { 0.3, 0.7, 0.35 } },
};

#define SKY_T 1e30

typedef struct { double t; vec3 n, color; } hit_t;

static int hit_box(const box_t *b, vec3 o, vec3 d, double tmax, hit_t *h)
{
    double t0 = 0, t1 = tmax;
    int axis = -1;
    double sign = 0;
    const double lo[3] = { b->lo.x, b->lo.y, b->lo.z }, hi[3] = { b->hi.x, b->hi.y, b->hi.z };
    const double oo[3] = { o.x, o.y, o.z }, dd[3] = { d.x, d.y, d.z };
    for (int a = 0; a < 3; a++) {
        if (dd[a] == 0) {
            if (oo[a] < lo[a] || oo[a] > hi[a])
                return 0;
            continue;
        }
        double u = (lo[a] - oo[a]) / dd[a], v = (hi[a] - oo[a]) / dd[a];
        if (u > v) {
            double t = u;
            u = v;
            v = t;
        }
        if (u > t0) {
            t0 = u;
            axis = a;
            sign = dd[a] > 0 ? -1 : 1;
        }
        t1 = fmin(t1, v);
        if (t0 > t1)
            return 0;
    }
    if (axis < 0 || t0 <= 1e-6)
        return 0;
    h->t = t0;
    h->n = v3(axis == 0 ? sign : 0, axis == 1 ? sign : 0, axis == 2 ? sign : 0);
    h->color = b->color;
    return 1;
}

static int hit_sphere(const sphere_t *s, vec3 o, vec3 d, double tmax, hit_t *h)
{
    vec3 oc = sub(o, s->c);
    double b = dot(oc, d), c = dot(oc, oc) - s->r * s->r, disc = b * b - c;
    if (disc < 0)
        return 0;
    double t = -b - sqrt(disc);
    if (t <= 1e-6 || t >= tmax)
        return 0;
    h->t = t;
    h->n = norm(sub(add(o, mul(d, t)), s->c));
    h->color = s->color;
    return 1;
}

/* Nearest hit along a unit direction; t = SKY_T when nothing. */
static hit_t trace(vec3 o, vec3 d)
{
    hit_t best = { SKY_T, { 0, 0, 0 }, { 0, 0, 0 } }, h;
    if (d.y < 0) {
        double t = -o.y / d.y;
        if (t > 1e-6) {
            vec3 p = add(o, mul(d, t));
            int checker = ((int)floor(p.x / 2) + (int)floor(p.z / 2)) & 1;
            best.t = t;
            best.n = v3(0, 1, 0);
            best.color = checker ? v3(0.42, 0.4, 0.36) : v3(0.3, 0.32, 0.28);
        }
    }
    for (size_t i = 0; i < sizeof boxes / sizeof *boxes; i++)
        if (hit_box(&boxes[i], o, d, best.t, &h))
            best = h;
    for (size_t i = 0; i < sizeof spheres / sizeof *spheres; i++)
        if (hit_sphere(&spheres[i], o, d, best.t, &h))
            best = h;
    return best;
}

static vec3 sun_dir(void) { return norm(v3(-0.4, 0.35, 0.6)); }

static vec3 shade(vec3 o, vec3 d, hit_t h)
{
    if (h.t >= SKY_T) {
        /* Sky: brighter toward the horizon. */
        double k = fmax(0, d.y);
        return add(mul(v3(0.85, 0.9, 1.0), 1 - k), mul(v3(0.25, 0.4, 0.8), k));
    }
    vec3 p = add(o, mul(d, h.t)), l = sun_dir();
    double ndl = fmax(0, dot(h.n, l));
    if (ndl > 0 && trace(add(p, mul(h.n, 1e-4)), l).t < SKY_T)
        ndl = 0;
    vec3 sun = mul(v3(1.0, 0.9, 0.75), 3.0 * ndl);
    vec3 amb = mul(v3(0.35, 0.42, 0.55), 0.5 + 0.5 * h.n.y);
    vec3 light = add(sun, amb);
    return v3(h.color.x * light.x, h.color.y * light.y, h.color.z * light.z);
}

/* ------------------------------------------------------------ cameras */

typedef struct {
    vec3 c, r, u, f;      /* position, right, up, forward */
    double w2c[16], w2n[16];
} camera_t;

static void mat_mul(const double a[16], const double b[16], double out[16])
{
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += a[i * 4 + k] * b[k * 4 + j];
            out[i * 4 + j] = s;
        }
}

/* worldToCamera: rows (R.x U.x F.x 0), (R.y U.y F.y 0), (R.z U.z F.z 0),
 * (-C.R, -C.U, -C.F, 1), so [p,1] M = (dot(p-C,R), dot(p-C,U), dot(p-C,F), 1). */
static void look_at(camera_t *cam, vec3 c, vec3 target)
{
    cam->c = c;
    cam->f = norm(sub(target, c));
    cam->r = norm(cross(cam->f, v3(0, 1, 0)));
    cam->u = cross(cam->r, cam->f);
    double m[16] = { cam->r.x, cam->u.x, cam->f.x, 0, cam->r.y, cam->u.y, cam->f.y, 0,
                     cam->r.z, cam->u.z, cam->f.z, 0, -dot(c, cam->r), -dot(c, cam->u),
                     -dot(c, cam->f), 1 };
    memcpy(cam->w2c, m, sizeof m);
}

/* Perspective: nx = 0.5 + sx x/z, ny = 0.5 - sy y/z (w = z). */
static void perspective(camera_t *cam, double vfov_deg, double aspect)
{
    double sy = 1 / (2 * tan(vfov_deg * M_PI / 360)), sx = sy / aspect;
    double p[16] = { sx, 0, 0, 0, 0, -sy, 0, 0, 0.5, 0.5, 1, 1, 0, 0, 0, 0 };
    mat_mul(cam->w2c, p, cam->w2n);
}

/* Orthographic: nx = 0.5 + x/ww, ny = 0.5 - y/hw (w = 1). */
static void orthographic(camera_t *cam, double ww, double hw)
{
    double p[16] = { 1 / ww, 0, 0, 0, 0, -1 / hw, 0, 0, 0, 0, 1, 0, 0.5, 0.5, 0, 1 };
    mat_mul(cam->w2c, p, cam->w2n);
}

/* The camera path: a dolly forward with a slow pan. */
static void frame_camera(camera_t *cam, long frame, int w, int h)
{
    double k = (double)(frame - 1);
    look_at(cam, v3(-2 + 0.4 * k, 1.8, -12 + 1.2 * k), v3(2 - 0.6 * k, 2.5, 60));
    perspective(cam, 45, (double)w / h);
}

static void sun_camera(camera_t *cam)
{
    vec3 l = sun_dir();
    look_at(cam, mul(l, 300), v3(0, 0, 60));
    orthographic(cam, 260, 260);
}

/* ------------------------------------------------------------ EXR output */

typedef struct {
    const char *name;
    exr_pixel_type_t type;
    const float *data;
} out_chan_t;

static int write_exr(const char *path, int w, int h, const out_chan_t *ch, int nch,
                     const camera_t *cam /* NULL: no camera attributes */, const char *desc)
{
    char tmp[4200];
    const char *slash = strrchr(path, '/');
    int dirlen = slash ? (int)(slash - path + 1) : 0;
    snprintf(tmp, sizeof tmp, "%.*s.%s.tmp.%ld", dirlen, path, path + dirlen, (long)getpid());
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int idx = 0, inited = 0, ok = 0;
    int32_t lpc = 1;
    exr_result_t rv = exr_start_write(&ctx, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_add_part(ctx, "", EXR_STORAGE_SCANLINE, &idx);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(ctx, idx, w, h, EXR_COMPRESSION_ZIP);
    for (int c = 0; c < nch && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(ctx, idx, ch[c].name, ch[c].type, EXR_PERCEPTUALLY_LINEAR, 1, 1);
    exr_attr_m44f_t m1, m2;
    for (int i = 0; i < 16 && cam; i++) {
        m1.m[i] = (float)cam->w2c[i];
        m2.m[i] = (float)cam->w2n[i];
    }
    if (rv == EXR_ERR_SUCCESS && cam)
        rv = exr_attr_set_m44f(ctx, idx, "worldToCamera", &m1);
    if (rv == EXR_ERR_SUCCESS && cam)
        rv = exr_attr_set_m44f(ctx, idx, "worldToNDC", &m2);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_attr_set_string(ctx, idx, "fogpipe/scene", desc);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_write_header(ctx);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_get_scanlines_per_chunk(ctx, idx, &lpc);
    for (int y = 0; y < h && rv == EXR_ERR_SUCCESS; y += lpc) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(ctx, idx, y, &ci);
        if (rv == EXR_ERR_SUCCESS)
            rv = inited ? exr_encoding_update(ctx, idx, &ci, &enc)
                        : exr_encoding_initialize(ctx, idx, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS)
            break;
        for (int c = 0; c < enc.channel_count; c++) {
            exr_coding_channel_info_t *cc = &enc.channels[c];
            for (int k = 0; k < nch; k++)
                if (strcmp(cc->channel_name, ch[k].name) == 0)
                    cc->encode_from_ptr = (const uint8_t *)(ch[k].data + (size_t)y * w);
            cc->user_pixel_stride = 4;
            cc->user_line_stride = 4 * w;
            cc->user_bytes_per_element = 4;
            cc->user_data_type = EXR_PIXEL_FLOAT;
        }
        if (!inited) {
            rv = exr_encoding_choose_default_routines(ctx, idx, &enc);
            inited = 1;
        }
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_encoding_run(ctx, idx, &enc);
    }
    if (inited)
        exr_encoding_destroy(ctx, &enc);
    ok = rv == EXR_ERR_SUCCESS;
    if (ctx && exr_finish(&ctx) != EXR_ERR_SUCCESS)
        ok = 0;
    if (ok && rename(tmp, path) != 0)
        ok = 0;
    if (!ok) {
        fprintf(stderr, "fp-scene: %s: cannot write (%s)\n", path,
                rv != EXR_ERR_SUCCESS ? exr_get_default_error_message(rv) : strerror(errno));
        unlink(tmp);
        return 1;
    }
    return 0;
}

/* ------------------------------------------------------------ fogmap */

/* Patches of fog: a sum of smooth bumps, zero between them (so the sparse
 * walk has empty blocks to skip), values up to about 1.5. */
static float *make_fogmap(int size)
{
    float *img = calloc((size_t)size * size, sizeof *img);
    unsigned s = 2024;
    for (int b = 0; b < 18 && img; b++) {
        double v[3];
        for (int k = 0; k < 3; k++) {
            s = s * 1103515245u + 12345u;
            v[k] = ((s >> 8) % 10000) / 10000.0;
        }
        double r = 0.06 + 0.14 * v[2];
        for (int j = 0; j < size; j++)
            for (int i = 0; i < size; i++) {
                double dx = (i + 0.5) / size - v[0], dy = (j + 0.5) / size - v[1];
                double q = 1 - (dx * dx + dy * dy) / (r * r);
                if (q > 0)
                    img[(size_t)j * size + i] += (float)(q * q);
            }
    }
    return img;
}

/* ------------------------------------------------------------ main */

/* mkdir -p */
static int mkdir_p(const char *dir)
{
    char path[4096];
    snprintf(path, sizeof path, "%s", dir);
    for (char *p = path + 1;; p++) {
        char c = *p;
        if (c == '/' || c == 0) {
            *p = 0;
            if (mkdir(path, 0777) != 0 && errno != EEXIST) {
                fprintf(stderr, "fp-scene: %s: cannot create directory (%s)\n", path,
                        strerror(errno));
                return 1;
            }
            *p = c;
        }
        if (c == 0)
            return 0;
    }
}

static int usage(const char *msg)
{
    fprintf(stderr, "fp-scene: %s (usage: fp-scene -o DIR [--width W] [--height H] "
                    "[--frames A-B] [--layout plain|blender] [--shadow-size N] "
                    "[--sky-depth V])\n", msg);
    return 2;
}

int main(int argc, char **argv)
{
    const char *dir = NULL;
    int w = 320, h = 180, shadow = 512, blender = 0;
    long f0 = 1, f1 = 8;
    float sky = INFINITY;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--help")) {
            printf("fp-scene -o DIR [--width W] [--height H] [--frames A-B] "
                   "[--layout plain|blender] [--shadow-size N] [--sky-depth V]\n");
            return 0;
        }
        if (!v)
            return usage("missing value or unknown option");
        i++;
        char *end;
        if (!strcmp(a, "-o")) {
            dir = v;
        } else if (!strcmp(a, "--width")) {
            w = (int)strtol(v, &end, 10);
            if (*end || w < 1 || w > 16384)
                return usage("--width: expected 1..16384");
        } else if (!strcmp(a, "--height")) {
            h = (int)strtol(v, &end, 10);
            if (*end || h < 1 || h > 16384)
                return usage("--height: expected 1..16384");
        } else if (!strcmp(a, "--frames")) {
            if (sscanf(v, "%ld-%ld", &f0, &f1) != 2 || f1 < f0)
                return usage("--frames: expected A-B");
        } else if (!strcmp(a, "--layout")) {
            if (strcmp(v, "plain") && strcmp(v, "blender"))
                return usage("--layout: expected plain or blender");
            blender = !strcmp(v, "blender");
        } else if (!strcmp(a, "--shadow-size")) {
            shadow = (int)strtol(v, &end, 10);
            if (*end || shadow < 0 || shadow > 16384)
                return usage("--shadow-size: expected 0..16384");
        } else if (!strcmp(a, "--sky-depth")) {
            sky = strtof(v, &end);
            if (*end)
                return usage("--sky-depth: expected a number or inf");
        } else {
            return usage("unknown option");
        }
    }
    if (!dir)
        return usage("-o DIR is required");
    if (mkdir_p(dir))
        return 1;
    size_t n = (size_t)w * h;
    float *rgba[4], *z = malloc(n * sizeof(float));
    for (int c = 0; c < 4; c++)
        rgba[c] = malloc(n * sizeof(float));
    int rc = 0;
    for (long frame = f0; frame <= f1 && !rc; frame++) {
        camera_t cam;
        frame_camera(&cam, frame, w, h);
        double sy = 1 / (2 * tan(45 * M_PI / 360)), sx = sy * h / w;
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++) {
                /* The ray through the pixel center's NDC point. */
                double nx = (i + 0.5) / w, ny = (j + 0.5) / h;
                double cx = (nx - 0.5) / sx, cy = (0.5 - ny) / sy;
                vec3 dcam = add(add(mul(cam.r, cx), mul(cam.u, cy)), cam.f);
                vec3 d = norm(dcam);
                hit_t hit = trace(cam.c, d);
                vec3 col = shade(cam.c, d, hit);
                size_t k = (size_t)j * w + i;
                rgba[0][k] = (float)col.x;
                rgba[1][k] = (float)col.y;
                rgba[2][k] = (float)col.z;
                rgba[3][k] = 1;
                /* Planar depth: the hit's camera-space z. */
                z[k] = hit.t >= SKY_T ? sky : (float)(hit.t * dot(d, cam.f));
            }
        char path[4300], desc[128];
        snprintf(path, sizeof path, "%s/scene.%04ld.exr", dir, frame);
        snprintf(desc, sizeof desc, "fogpipe sample scene, frame %ld", frame);
        out_chan_t plain[] = { { "R", EXR_PIXEL_HALF, rgba[0] }, { "G", EXR_PIXEL_HALF, rgba[1] },
                               { "B", EXR_PIXEL_HALF, rgba[2] }, { "A", EXR_PIXEL_HALF, rgba[3] },
                               { "Z", EXR_PIXEL_FLOAT, z } };
        out_chan_t layer[] = { { "ViewLayer.Combined.R", EXR_PIXEL_HALF, rgba[0] },
                               { "ViewLayer.Combined.G", EXR_PIXEL_HALF, rgba[1] },
                               { "ViewLayer.Combined.B", EXR_PIXEL_HALF, rgba[2] },
                               { "ViewLayer.Combined.A", EXR_PIXEL_HALF, rgba[3] },
                               { "ViewLayer.Depth.Z", EXR_PIXEL_FLOAT, z } };
        rc = write_exr(path, w, h, blender ? layer : plain, 5, &cam, desc);
        if (rc || shadow == 0)
            continue;
        /* The sun's orthographic depth map. */
        camera_t sc;
        sun_camera(&sc);
        float *sz = malloc((size_t)shadow * shadow * sizeof(float));
        for (int j = 0; j < shadow; j++)
            for (int i = 0; i < shadow; i++) {
                double x = ((i + 0.5) / shadow - 0.5) * 260, y = (0.5 - (j + 0.5) / shadow) * 260;
                vec3 o = add(add(sc.c, mul(sc.r, x)), mul(sc.u, y));
                hit_t hit = trace(o, sc.f);
                sz[(size_t)j * shadow + i] = hit.t >= SKY_T ? INFINITY : (float)hit.t;
            }
        snprintf(path, sizeof path, "%s/shadow.%04ld.exr", dir, frame);
        snprintf(desc, sizeof desc, "fogpipe sample scene, sun depth map, frame %ld", frame);
        out_chan_t sch[] = { { "Z", EXR_PIXEL_FLOAT, sz } };
        rc = write_exr(path, shadow, shadow, sch, 1, &sc, desc);
        free(sz);
    }
    if (!rc) {
        char path[4300];
        snprintf(path, sizeof path, "%s/fogmap.exr", dir);
        float *fm = make_fogmap(64);
        out_chan_t fch[] = { { "Y", EXR_PIXEL_FLOAT, fm } };
        rc = fm ? write_exr(path, 64, 64, fch, 1, NULL, "fogpipe sample fogmap") : 1;
        free(fm);
    }
    for (int c = 0; c < 4; c++)
        free(rgba[c]);
    free(z);
    return rc;
}
