/* fogpipe-scene: the sample scene generator of fogpipe (installed with it:
 * a test scene and sun shadow map to try fogpipe on).
 *
 * An analytic ray tracer (ground plane with a checker, boxes, a wall with
 * gaps, spheres, a low sun with hard ray-traced shadows and sky ambient)
 * that writes, with OpenEXR's C API only:
 *   DIR/scene.%04d.exr   color R,G,B,A (HALF, A = 1) and planar depth Z
 *                        (FLOAT), worldToCamera / worldToNDC (m44f) and a
 *                        "fogpipe/scene" string describing the frame;
 *   DIR/shadow.%04d.exr  the sun's orthographic depth map, Z (FLOAT), with
 *                        its own worldToCamera / worldToNDC (w = 1); the
 *                        same map every frame (the sun does not move), one
 *                        per frame because the format allows animation;
 *   DIR/fogmap.exr       a 64x64 greyscale fogmap (channel Y: patches of
 *                        fog with clear gaps) for fogpipe's --fogmap.
 * One sample per pixel center, so Z is exactly the depth of the center ray.
 * Deterministic: the same bytes every run.  --check verifies that every
 * pixel's hit point projects back into its own pixel through the matrices
 * as written (floats), with the depth written, and that the sun map
 * shadows what the traced shadow rays shadow.
 *
 * Conventions (OpenEXR's, and fogpipe's): world right-handed, +Y up,
 * meters; matrices act on row vectors (p' = p M) and are stored row-major;
 * camera space +x right, +y up, +z the viewing direction; NDC (0,0) the
 * top-left and (1,1) the bottom-right corner of the display window, taken
 * after the homogeneous divide by the 4th component.  Depth Z is planar
 * (camera-space z of the hit, not the distance along the ray); sky pixels
 * get --sky-depth (default +inf).  Sun map texels that see nothing get
 * +inf; points outside the map are outside every caster's reach (lit). */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

#define FP_PI 3.14159265358979323846
#define FP_COUNT(a) (sizeof(a) / sizeof *(a))
#define FP_DIR_MAX 4000     /* longest -o accepted, so every path fits */
#define FP_PATH_MAX 4200
#define FP_VFOV_DEG 45.0    /* the sample camera's vertical field of view */

/* --check tolerances: a hit point reprojected through the float matrices
 * written to the file lands within FP_CHECK_PX pixels of its pixel center
 * and gives the written depth to FP_CHECK_DEPTH (relative to the depth plus
 * the camera's distance from the origin: the scale float rounding works
 * at).  The points the sun map shadows and those the traced shadow rays
 * shadow overlap by at least FP_CHECK_SUN (intersection over union), judged
 * when the map's texels are at most FP_CHECK_TEXEL meters: half the
 * thinnest caster or gap (the wall's slits, 0.5 m), so none falls between
 * texels. */
#define FP_CHECK_PX 0.05
#define FP_CHECK_DEPTH 1e-6
#define FP_CHECK_SUN 0.95
#define FP_CHECK_TEXEL 0.25

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
static vec3 vmin(vec3 a, vec3 b) { return v3(fmin(a.x, b.x), fmin(a.y, b.y), fmin(a.z, b.z)); }
static vec3 vmax(vec3 a, vec3 b) { return v3(fmax(a.x, b.x), fmax(a.y, b.y), fmax(a.z, b.z)); }

/* ------------------------------------------------------------ scene */

typedef struct { vec3 lo, hi, color; } box_t;
typedef struct { vec3 c; double r; vec3 color; } sphere_t;

static const box_t boxes[] = {
    /* the wall at z = 40, 6 m high, with four 2 m gaps for light shafts
     * and, in its middle stretch, three narrow 0.5 m slits */
    { { -40, 0, 40 }, { -17, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { -15, 0, 40 }, { -7, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { -5, 0, 40 }, { -3.5, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { -3, 0, 40 }, { -1.5, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { -1, 0, 40 }, { 0.5, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { 1, 0, 40 }, { 3, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { 5, 0, 40 }, { 13, 6, 41 }, { 0.55, 0.5, 0.45 } },
    { { 15, 0, 40 }, { 40, 6, 41 }, { 0.55, 0.5, 0.45 } },
    /* thin pillars before the wall (0.6 m square, 5 m high): their
     * shadows cut the shafts */
    { { -11.3, 0, 34 }, { -10.7, 5, 34.6 }, { 0.5, 0.48, 0.46 } },
    { { -6.3, 0, 34 }, { -5.7, 5, 34.6 }, { 0.5, 0.48, 0.46 } },
    { { 2.7, 0, 34 }, { 3.3, 5, 34.6 }, { 0.5, 0.48, 0.46 } },
    { { 11.7, 0, 34 }, { 12.3, 5, 34.6 }, { 0.5, 0.48, 0.46 } },
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

/* The ground the camera path looks at from nearby; the sun map covers it
 * together with every box and sphere. */
static const vec3 ground_lo = { -20, 0, -20 }, ground_hi = { 20, 0, 0 };

#define SKY_T 1e30

typedef struct { double t; vec3 n, color; } hit_t;

/* Slab test; a ray starting inside the box does not hit it. */
static inline int hit_box(const box_t *b, vec3 o, vec3 d, double tmax, hit_t *h)
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
        if (v < t1)
            t1 = v;
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

static inline int hit_sphere(const sphere_t *s, vec3 o, vec3 d, double tmax, hit_t *h)
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
            /* 2 m checker: motion and fog stay readable near and far (in
             * doubles: grazing rays reach far past any int) */
            int checker = fabs(fmod(floor(p.x / 2) + floor(p.z / 2), 2)) == 1;
            best.t = t;
            best.n = v3(0, 1, 0);
            best.color = checker ? v3(0.42, 0.4, 0.36) : v3(0.3, 0.32, 0.28);
        }
    }
    for (size_t i = 0; i < FP_COUNT(boxes); i++)
        if (hit_box(&boxes[i], o, d, best.t, &h))
            best = h;
    for (size_t i = 0; i < FP_COUNT(spheres); i++)
        if (hit_sphere(&spheres[i], o, d, best.t, &h))
            best = h;
    return best;
}

/* Any hit at all along d (the shadow ray): the same answer as
 * trace(o, d).t < SKY_T, without looking for the nearest. */
static int occluded(vec3 o, vec3 d)
{
    hit_t h;
    if (d.y < 0 && -o.y / d.y > 1e-6)
        return 1;
    for (size_t i = 0; i < FP_COUNT(boxes); i++)
        if (hit_box(&boxes[i], o, d, SKY_T, &h))
            return 1;
    for (size_t i = 0; i < FP_COUNT(spheres); i++)
        if (hit_sphere(&spheres[i], o, d, SKY_T, &h))
            return 1;
    return 0;
}

/* Direction toward the sun: low (about 26 degrees up), ahead of the camera
 * and to its right, so the wall's gaps throw shafts toward the viewer. */
static vec3 sun_dir(void) { return norm(v3(-0.4, 0.35, 0.6)); }

typedef enum { FP_SUN_AWAY, FP_SUN_LIT, FP_SUN_SHADOWED } fp_sun_t;

/* Lambert with the sun (warm, strength 3) and hard shadows, plus a sky
 * ambient that fades toward downward normals; linear scene-referred.  *sun
 * tells whether the point faces the sun and, if so, whether it sees it. */
static vec3 shade(vec3 o, vec3 d, hit_t h, fp_sun_t *sun)
{
    *sun = FP_SUN_AWAY;
    if (h.t >= SKY_T) {
        /* Sky: brighter toward the horizon. */
        double k = fmax(0, d.y);
        return add(mul(v3(0.85, 0.9, 1.0), 1 - k), mul(v3(0.25, 0.4, 0.8), k));
    }
    vec3 p = add(o, mul(d, h.t)), l = sun_dir();
    double ndl = fmax(0, dot(h.n, l));
    if (ndl > 0) {
        *sun = FP_SUN_LIT;
        if (occluded(add(p, mul(h.n, 1e-4)), l)) {
            *sun = FP_SUN_SHADOWED;
            ndl = 0;
        }
    }
    vec3 light = mul(v3(1.0, 0.9, 0.75), 3.0 * ndl);
    vec3 amb = mul(v3(0.35, 0.42, 0.55), 0.5 + 0.5 * h.n.y);
    light = add(light, amb);
    return v3(h.color.x * light.x, h.color.y * light.y, h.color.z * light.z);
}

/* ------------------------------------------------------------ cameras */

typedef struct {
    vec3 c, r, u, f;      /* position, right, up, forward (world) */
    int ortho;
    double sx, sy;        /* perspective: NDC per unit of x/z, y/z */
    double ww, hw;        /* orthographic: world width and height covered */
    double w2c[16], w2n[16];
} fp_cam_t;

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
 * (-C.R, -C.U, -C.F, 1), so [p,1] M = (dot(p-C,R), dot(p-C,U), dot(p-C,F), 1);
 * R = normalize(F x worldUp), U = R x F. */
static void orient(fp_cam_t *cam, vec3 c, vec3 f)
{
    cam->c = c;
    cam->f = f;
    cam->r = norm(cross(f, v3(0, 1, 0)));
    cam->u = cross(cam->r, f);
    double m[16] = { cam->r.x, cam->u.x, cam->f.x, 0, cam->r.y, cam->u.y, cam->f.y, 0,
                     cam->r.z, cam->u.z, cam->f.z, 0, -dot(c, cam->r), -dot(c, cam->u),
                     -dot(c, cam->f), 1 };
    memcpy(cam->w2c, m, sizeof m);
}

static void look_at(fp_cam_t *cam, vec3 c, vec3 target) { orient(cam, c, norm(sub(target, c))); }

/* Perspective, square pixels: nx = 0.5 + sx x/z, ny = 0.5 - sy y/z with
 * sy = 1 / (2 tan(V/2)), sx = sy / aspect; P's rows (sx,0,0,0), (0,-sy,0,0),
 * (0.5,0.5,1,1), (0,0,0,0), so w = z. */
static void perspective(fp_cam_t *cam, double vfov_deg, int w, int h)
{
    cam->ortho = 0;
    cam->sy = 1 / (2 * tan(vfov_deg * FP_PI / 360));
    cam->sx = cam->sy * h / w;
    double p[16] = { cam->sx, 0, 0, 0, 0, -cam->sy, 0, 0, 0.5, 0.5, 1, 1, 0, 0, 0, 0 };
    mat_mul(cam->w2c, p, cam->w2n);
}

/* Orthographic: nx = 0.5 + x/ww, ny = 0.5 - y/hw; P's rows (1/ww,0,0,0),
 * (0,-1/hw,0,0), (0,0,1,0), (0.5,0.5,0,1), so w = 1 and the third is z. */
static void orthographic(fp_cam_t *cam, double ww, double hw)
{
    cam->ortho = 1;
    cam->ww = ww;
    cam->hw = hw;
    double p[16] = { 1 / ww, 0, 0, 0, 0, -1 / hw, 0, 0, 0, 0, 1, 0, 0.5, 0.5, 0, 1 };
    mat_mul(cam->w2c, p, cam->w2n);
}

/* The ray through NDC (nx, ny): what the matrices above map back there. */
static void camera_ray(const fp_cam_t *cam, double nx, double ny, vec3 *o, vec3 *d)
{
    if (cam->ortho) {
        double x = (nx - 0.5) * cam->ww, y = (0.5 - ny) * cam->hw;
        *o = add(add(cam->c, mul(cam->r, x)), mul(cam->u, y));
        *d = cam->f;
    } else {
        double cx = (nx - 0.5) / cam->sx, cy = (0.5 - ny) / cam->sy;
        *o = cam->c;
        *d = norm(add(add(mul(cam->r, cx), mul(cam->u, cy)), cam->f));
    }
}

/* The camera path, laid out for frames 1..8 (it goes on linearly outside):
 * eye height 1.8 m, a dolly forward 1.2 m per frame from z = -12 while the
 * aim pans right to left across the wall at z = 40 and the far boxes. */
static void frame_path(long frame, vec3 *eye, vec3 *target)
{
    double k = (double)(frame - 1);
    *eye = v3(-2 + 0.4 * k, 1.8, -12 + 1.2 * k);
    *target = v3(2 - 0.6 * k, 2.5, 60);
}

static void frame_camera(fp_cam_t *cam, long frame, int w, int h)
{
    vec3 eye, target;
    frame_path(frame, &eye, &target);
    look_at(cam, eye, target);
    perspective(cam, FP_VFOV_DEG, w, h);
}

/* The sun's camera looks along -sunDir at the middle of the scene bounds
 * (boxes, spheres, the ground near the camera path), square, sized to the
 * bounds' projection, and far enough back that every z is at least 1. */
static void sun_camera(fp_cam_t *cam)
{
    vec3 lo = ground_lo, hi = ground_hi;
    for (size_t i = 0; i < FP_COUNT(boxes); i++) {
        lo = vmin(lo, boxes[i].lo);
        hi = vmax(hi, boxes[i].hi);
    }
    for (size_t i = 0; i < FP_COUNT(spheres); i++) {
        vec3 r = v3(spheres[i].r, spheres[i].r, spheres[i].r);
        lo = vmin(lo, sub(spheres[i].c, r));
        hi = vmax(hi, add(spheres[i].c, r));
    }
    vec3 mid = mul(add(lo, hi), 0.5);
    orient(cam, mid, mul(sun_dir(), -1));
    double ex = 0, ey = 0, ez = 0;
    for (int k = 0; k < 8; k++) {
        vec3 q = sub(v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z), mid);
        ex = fmax(ex, fabs(dot(q, cam->r)));
        ey = fmax(ey, fabs(dot(q, cam->u)));
        ez = fmax(ez, fabs(dot(q, cam->f)));
    }
    double side = 2 * fmax(ex, ey) + 2; /* 1 m margin each side */
    /* Back far enough that the bounds are at z >= 1, and so is the ground
     * plane wherever the map sees it (nearest at one of the corners). */
    vec3 c = sub(mid, mul(cam->f, ez + 1));
    double back = 0;
    for (int k = 0; k < 4; k++) {
        vec3 o = add(add(c, mul(cam->r, (k & 1 ? 0.5 : -0.5) * side)),
                     mul(cam->u, (k & 2 ? 0.5 : -0.5) * side));
        back = fmax(back, 1 + o.y / cam->f.y);
    }
    orient(cam, sub(c, mul(cam->f, back)), cam->f);
    orthographic(cam, side, side);
}

/* ------------------------------------------------------------ check */

typedef struct {
    const fp_cam_t *sun;  /* the sun map and its camera; NULL: none */
    const float *sun_z;
    int sun_n;
    long points;          /* hit points reprojected */
    double max_px;        /* largest distance from the pixel center, pixels */
    double max_depth;     /* largest depth error, relative (see check_point) */
    long shadow_any;      /* unambiguous sun-facing points shadowed by either */
    long shadow_both;     /* ... by both the map and the traced ray */
} fp_check_t;

/* [p,1] M through the matrix as the file stores it (floats). */
static void xform_stored(const double m[16], vec3 p, double out[4])
{
    for (int c = 0; c < 4; c++)
        out[c] = p.x * (float)m[c] + p.y * (float)m[4 + c] + p.z * (float)m[8 + c] +
                 (float)m[12 + c];
}

/* A hit point p seen by pixel (i, j) of a w x h image, depth z written. */
static void check_point(fp_check_t *chk, const fp_cam_t *cam, vec3 p, int i, int j, int w,
                        int h, float z)
{
    double c[4], n[4];
    xform_stored(cam->w2c, p, c);
    xform_stored(cam->w2n, p, n);
    double px = fmax(fabs(n[0] / n[3] * w - (i + 0.5)), fabs(n[1] / n[3] * h - (j + 0.5)));
    /* The divide is by z for a perspective camera, by exactly 1 for the
     * sun's.  Float matrices round the translation row at the scale of the
     * camera's distance from the origin, so errors are relative to that
     * plus the depth. */
    double dz = fmax(fabs(c[2] - z), fabs(n[3] - (cam->ortho ? 1 : z)));
    chk->points++;
    chk->max_px = fmax(chk->max_px, px);
    chk->max_depth = fmax(chk->max_depth, dz / (z + sqrt(dot(cam->c, cam->c))));
}

/* Does the sun map, looked up the way fogpipe will (project with its
 * worldToNDC, nearest texel, compare camera-space z), shadow the same
 * points as the traced shadow rays?  Counted where the map is unambiguous
 * (the 3x3 texels around the lookup all say the same: near a shadow edge
 * one texel cannot tell), as the overlap of the two shadowed sets, since
 * shadows cover a small part of the frame.  Bias: one texel of depth plus
 * the surface's depth slope over a texel. */
static void check_sun(fp_check_t *chk, vec3 p, vec3 n, fp_sun_t sun)
{
    if (!chk->sun || sun == FP_SUN_AWAY)
        return;
    const fp_cam_t *sc = chk->sun;
    const long size = chk->sun_n;
    double c[4], q[4];
    xform_stored(sc->w2c, p, c);
    xform_stored(sc->w2n, p, q);
    double tx = floor(q[0] / q[3] * size), ty = floor(q[1] / q[3] * size);
    if (tx < 1 || ty < 1 || tx >= size - 1 || ty >= size - 1)
        return;
    double ndl = fmax(dot(n, sun_dir()), 0.05), texel = sc->ww / size;
    double bias = texel * (1 + sqrt(1 - ndl * ndl) / ndl);
    int lit = 0;
    for (long k = 0; k < 9; k++) {
        size_t at = (size_t)((long)ty + k / 3 - 1) * size + (size_t)((long)tx + k % 3 - 1);
        lit += c[2] <= chk->sun_z[at] + bias;
    }
    if (lit % 9)
        return;
    chk->shadow_any += lit == 0 || sun == FP_SUN_SHADOWED;
    chk->shadow_both += lit == 0 && sun == FP_SUN_SHADOWED;
}

/* ------------------------------------------------------------ rendering */

/* One frame: color and planar depth of each pixel center's ray. */
static void render_frame(const fp_cam_t *cam, int w, int h, float sky, float *rgba[4], float *z,
                         fp_check_t *chk)
{
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            vec3 o, d;
            camera_ray(cam, (i + 0.5) / w, (j + 0.5) / h, &o, &d);
            hit_t hit = trace(o, d);
            fp_sun_t sun;
            vec3 col = shade(o, d, hit, &sun);
            size_t k = (size_t)j * w + i;
            rgba[0][k] = (float)col.x;
            rgba[1][k] = (float)col.y;
            rgba[2][k] = (float)col.z;
            rgba[3][k] = 1;
            /* Planar depth: the hit's camera-space z. */
            z[k] = hit.t >= SKY_T ? sky : (float)(hit.t * dot(d, cam->f));
            if (chk && hit.t < SKY_T) {
                vec3 p = add(o, mul(d, hit.t));
                check_point(chk, cam, p, i, j, w, h, z[k]);
                check_sun(chk, p, hit.n, sun);
            }
        }
}

/* The sun's depth map: each texel's ray starts on the camera plane and
 * runs along F, so its hit distance is the camera-space z. */
static void render_sun_map(const fp_cam_t *sc, int n, float *z, fp_check_t *chk)
{
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            vec3 o, d;
            camera_ray(sc, (i + 0.5) / n, (j + 0.5) / n, &o, &d);
            hit_t hit = trace(o, d);
            size_t k = (size_t)j * n + i;
            z[k] = hit.t >= SKY_T ? INFINITY : (float)hit.t;
            if (chk && hit.t < SKY_T)
                check_point(chk, sc, add(o, mul(d, hit.t)), i, j, n, n, z[k]);
        }
}

/* Patches of fog: a sum of smooth bumps, zero between them (so the sparse
 * walk has empty blocks to skip), values up to about 1.5. */
static void make_fogmap(int size, float *img)
{
    unsigned s = 2024;
    memset(img, 0, (size_t)size * size * sizeof *img);
    for (int b = 0; b < 18; b++) {
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
}

/* ------------------------------------------------------------ EXR output */

typedef struct {
    const char *name;
    exr_pixel_type_t type;
    const float *data;
} out_chan_t;

/* OpenEXR reports through a callback; keep its last message for our one
 * line instead of its default print. */
static char exr_message[512];

static void keep_exr_message(exr_const_context_t ctx, exr_result_t code, const char *msg)
{
    snprintf(exr_message, sizeof exr_message, "%s", msg ? msg : exr_get_default_error_message(code));
}

/* Writes a single-part ZIP scanline file atomically (a temporary name in
 * the same directory, then rename).  The data are floats, converted to
 * each channel's type by OpenEXR.  cam NULL: no camera attributes.  On
 * failure prints one line naming the file (and frame if >= 0). */
static int write_exr(const char *path, long frame, int w, int h, const out_chan_t *ch, int nch,
                     const fp_cam_t *cam, const char *desc)
{
    char tmp[FP_PATH_MAX + 64];
    const char *slash = strrchr(path, '/');
    int dirlen = slash ? (int)(slash - path + 1) : 0;
    snprintf(tmp, sizeof tmp, "%.*s.%s.tmp.%ld", dirlen, path, path + dirlen, (long)getpid());
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int idx = 0, inited = 0, ok;
    int32_t lpc = 1;
    init.error_handler_fn = keep_exr_message;
    exr_message[0] = 0;
    exr_result_t rv = exr_start_write(&ctx, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_add_part(ctx, "", EXR_STORAGE_SCANLINE, &idx);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(ctx, idx, w, h, EXR_COMPRESSION_ZIP);
    for (int c = 0; c < nch && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(ctx, idx, ch[c].name, ch[c].type, EXR_PERCEPTUALLY_LINEAR, 1, 1);
    if (cam) {
        exr_attr_m44f_t m1, m2;
        for (int i = 0; i < 16; i++) {
            m1.m[i] = (float)cam->w2c[i];
            m2.m[i] = (float)cam->w2n[i];
        }
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_attr_set_m44f(ctx, idx, "worldToCamera", &m1);
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_attr_set_m44f(ctx, idx, "worldToNDC", &m2);
    }
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
    exr_result_t fin = ctx ? exr_finish(&ctx) : EXR_ERR_SUCCESS;
    if (rv == EXR_ERR_SUCCESS)
        rv = fin;
    ok = rv == EXR_ERR_SUCCESS && rename(tmp, path) == 0;
    if (ok)
        return 0;
    const char *why = rv != EXR_ERR_SUCCESS
                          ? (exr_message[0] ? exr_message : exr_get_default_error_message(rv))
                          : strerror(errno);
    char at[32] = "";
    if (frame >= 0)
        snprintf(at, sizeof at, " frame %ld:", frame);
    fprintf(stderr, "fogpipe-scene: %s:%s cannot write (%s)\n", path, at, why);
    unlink(tmp);
    return 1;
}

/* ------------------------------------------------------------ options */

typedef struct {
    const char *dir;
    long width, height, shadow_size, blender, check, help;
    long frames[2];
    float sky_depth;
} fp_scene_args_t;

typedef enum { OPT_DIR, OPT_INT, OPT_FRAMES, OPT_LAYOUT, OPT_DEPTH, OPT_FLAG } fp_opt_kind_t;

typedef struct {
    const char *name, *arg, *def, *help;
    fp_opt_kind_t kind;
    size_t field;
    long min, max;
} fp_scene_opt_t;

#define FP_FIELD(f) offsetof(fp_scene_args_t, f)

/* The one table: parsing, range checks, defaults and --help read it. */
static const fp_scene_opt_t options[] = {
    { "-o", "DIR", NULL, "output directory, created if missing (optional with --check)", OPT_DIR,
      FP_FIELD(dir), 0, 0 },
    { "--width", "W", "320", "image width in pixels", OPT_INT, FP_FIELD(width), 1, 16384 },
    { "--height", "H", "180", "image height in pixels", OPT_INT, FP_FIELD(height), 1, 16384 },
    { "--frames", "A-B", "1-8", "frame range (the camera path is laid out for 1-8)", OPT_FRAMES,
      FP_FIELD(frames), 0, 99999999 },
    { "--layout", "plain|blender", "plain",
      "channels R,G,B,A,Z, or Blender's ViewLayer.Combined.R,G,B,A and ViewLayer.Depth.Z",
      OPT_LAYOUT, FP_FIELD(blender), 0, 1 },
    { "--shadow-size", "N", "1024", "sun depth map size in texels (0: no shadow.####.exr)",
      OPT_INT, FP_FIELD(shadow_size), 0, 16384 },
    { "--sky-depth", "V", "inf", "Z of sky pixels: inf, nan or a positive number (Cycles: 1e10)",
      OPT_DEPTH, FP_FIELD(sky_depth), 0, 0 },
    { "--check", NULL, NULL,
      "verify that hit points reproject into their pixels with their depth through the "
      "written matrices, and that the sun map shadows what the traced rays do; exit 1 if not",
      OPT_FLAG, FP_FIELD(check), 0, 1 },
    { "--help", NULL, NULL, "print this help", OPT_FLAG, FP_FIELD(help), 0, 1 },
};

/* One line for a bad command line; returns its exit status, 2. */
static int bad_option(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "fogpipe-scene: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, " (see --help)\n");
    va_end(ap);
    return 2;
}

static int parse_long(const char *s, long *out)
{
    char *end;
    errno = 0;
    *out = strtol(s, &end, 10);
    return end != s && *end == 0 && errno == 0;
}

/* Stores one option's value into args; 0 or 2 (bad value, message out). */
static int set_option(const fp_scene_opt_t *o, const char *v, fp_scene_args_t *args)
{
    char *field = (char *)args + o->field;
    switch (o->kind) {
    case OPT_DIR:
        if (!*v || strlen(v) > FP_DIR_MAX)
            return bad_option("%s: expected a directory name of 1 to 4000 bytes, got '%s'",
                              o->name, v);
        *(const char **)field = v;
        return 0;
    case OPT_INT: {
        long n;
        if (!parse_long(v, &n) || n < o->min || n > o->max)
            return bad_option("%s: expected an integer in %ld..%ld, got '%s'", o->name, o->min,
                              o->max, v);
        *(long *)field = n;
        return 0;
    }
    case OPT_FRAMES: {
        long *ab = (long *)field;
        char a[32];
        const char *dash = strchr(v, '-');
        size_t alen = dash ? (size_t)(dash - v) : strlen(v);
        int ok = alen < sizeof a;
        if (ok) {
            memcpy(a, v, alen);
            a[alen] = 0;
            ok = parse_long(a, &ab[0]) && parse_long(dash ? dash + 1 : a, &ab[1]);
        }
        if (!ok || ab[0] < o->min || ab[1] > o->max || ab[1] < ab[0])
            return bad_option("%s: expected A-B or A with 0 <= A <= B <= 99999999, got '%s'",
                              o->name, v);
        return 0;
    }
    case OPT_LAYOUT:
        if (strcmp(v, "plain") && strcmp(v, "blender"))
            return bad_option("%s: expected plain or blender, got '%s'", o->name, v);
        *(long *)field = !strcmp(v, "blender");
        return 0;
    case OPT_DEPTH: {
        char *end;
        double d = strtod(v, &end);
        if (end == v || *end || !(isnan(d) || (d > 0 && (d <= FLT_MAX || isinf(d)))))
            return bad_option("%s: expected inf, nan or a positive number up to %g, got '%s'",
                              o->name, FLT_MAX, v);
        *(float *)field = (float)d;
        return 0;
    }
    case OPT_FLAG:
        *(long *)field = 1;
        return 0;
    }
    return 2;
}

static void print_help(void)
{
    printf("usage: fogpipe-scene -o DIR [options]\n"
           "Writes the fogpipe sample scene: DIR/scene.####.exr (color + planar depth Z,\n"
           "worldToCamera, worldToNDC), DIR/shadow.####.exr (the sun's orthographic depth\n"
           "map) and DIR/fogmap.exr.\n");
    for (size_t i = 0; i < FP_COUNT(options); i++) {
        const fp_scene_opt_t *o = &options[i];
        char head[64], text[512];
        snprintf(head, sizeof head, "%s%s%s", o->name, o->arg ? " " : "", o->arg ? o->arg : "");
        snprintf(text, sizeof text, "%s%s%s%s", o->help, o->def ? " [" : "", o->def ? o->def : "",
                 o->def ? "]" : "");
        printf("  %-24s", head);
        /* the help text in a 52-column block beside the option, words kept whole */
        for (const char *t = text; *t;) {
            int len = (int)strlen(t);
            if (len > 52) {
                len = 52;
                while (len > 0 && t[len] != ' ')
                    len--;
                if (len == 0)
                    len = 52;
            }
            printf("%s%.*s\n", t == text ? "" : "                          ", len, t);
            t += len;
            while (*t == ' ')
                t++;
        }
    }
}

/* Parses argv into args (defaults from the table first); 0, or the exit
 * status (2 for a bad command line, -1 for --help done). */
static int parse_args(int argc, char **argv, fp_scene_args_t *args)
{
    memset(args, 0, sizeof *args);
    for (size_t i = 0; i < FP_COUNT(options); i++)
        if (options[i].def && set_option(&options[i], options[i].def, args))
            return 2;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *eq = strchr(a, '=');
        size_t len = eq && a[0] == '-' && a[1] == '-' ? (size_t)(eq - a) : strlen(a);
        const fp_scene_opt_t *o = NULL;
        for (size_t k = 0; k < FP_COUNT(options) && !o; k++)
            if (strlen(options[k].name) == len && !strncmp(a, options[k].name, len))
                o = &options[k];
        if (!o)
            return bad_option(a[0] == '-' ? "%s: unknown option" : "unexpected argument '%s'", a);
        const char *v = NULL;
        if (o->kind == OPT_FLAG) {
            if (a[len])
                return bad_option("%s: takes no value, got '%s'", o->name, a + len + 1);
        } else if (a[len]) {
            v = a + len + 1;
        } else if (i + 1 < argc) {
            v = argv[++i];
        } else {
            return bad_option("%s: missing value %s", o->name, o->arg);
        }
        if (set_option(o, v ? v : "", args))
            return 2;
        if (args->help) {
            print_help();
            return -1;
        }
    }
    if (!args->dir && !args->check)
        return bad_option("-o DIR is required (or --check alone, which writes nothing)");
    return 0;
}

/* mkdir -p, then insist on a directory; prints one line on failure. */
static int make_dir(const char *dir)
{
    char path[FP_PATH_MAX];
    struct stat st;
    snprintf(path, sizeof path, "%s", dir);
    for (char *p = path + 1;; p++) {
        char c = *p;
        if (c == '/' || c == 0) {
            *p = 0;
            if (mkdir(path, 0777) != 0 && errno != EEXIST) {
                fprintf(stderr, "fogpipe-scene: %s: cannot create directory (%s)\n", path,
                        strerror(errno));
                return 1;
            }
            *p = c;
        }
        if (c == 0)
            break;
    }
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        fprintf(stderr, "fogpipe-scene: %s: not a directory\n", dir);
        return 1;
    }
    return 0;
}

/* ------------------------------------------------------------ main */

int main(int argc, char **argv)
{
    fp_scene_args_t args;
    int rc = parse_args(argc, argv, &args);
    if (rc)
        return rc < 0 ? 0 : rc;
    if (args.dir && make_dir(args.dir))
        return 1;

    const int w = (int)args.width, h = (int)args.height, sn = (int)args.shadow_size;
    const char *dir = args.dir;
    size_t n = (size_t)w * h, nn = (size_t)sn * sn;
    float *rgba[4] = { NULL, NULL, NULL, NULL }, *z = malloc(n * sizeof *z);
    float *sun_z = sn ? malloc(nn * sizeof *sun_z) : NULL;
    float *fogmap = malloc(64 * 64 * sizeof *fogmap);
    int nomem = !z || (sn && !sun_z) || !fogmap;
    for (int c = 0; c < 4; c++)
        nomem |= !(rgba[c] = malloc(n * sizeof(float)));
    if (nomem) {
        fprintf(stderr, "fogpipe-scene: out of memory for %dx%d frames and a %dx%d sun map\n", w, h,
                sn, sn);
        rc = 1;
        goto done;
    }

    fp_check_t check = { 0 }, *chk = args.check ? &check : NULL;
    fp_cam_t sc = { 0 };
    vec3 l = sun_dir();
    char path[FP_PATH_MAX], desc[512];
    if (sn) {
        sun_camera(&sc);
        render_sun_map(&sc, sn, sun_z, chk);
        check.sun = &sc;
        check.sun_z = sun_z;
        check.sun_n = sn;
    }
    for (long frame = args.frames[0]; frame <= args.frames[1] && !rc; frame++) {
        fp_cam_t cam;
        vec3 eye, target;
        frame_path(frame, &eye, &target);
        frame_camera(&cam, frame, w, h);
        render_frame(&cam, w, h, args.sky_depth, rgba, z, chk);
        if (!dir)
            continue;
        snprintf(path, sizeof path, "%s/scene.%04ld.exr", dir, frame);
        snprintf(desc, sizeof desc,
                 "fogpipe sample scene, frame %ld: camera at (%.2f, %.2f, %.2f) aiming at "
                 "(%.2f, %.2f, %.2f), vertical fov %g deg; sun toward (%.4f, %.4f, %.4f); "
                 "Z planar, sky %g",
                 frame, eye.x, eye.y, eye.z, target.x, target.y, target.z, FP_VFOV_DEG, l.x, l.y,
                 l.z, args.sky_depth);
        out_chan_t plain[] = { { "R", EXR_PIXEL_HALF, rgba[0] }, { "G", EXR_PIXEL_HALF, rgba[1] },
                               { "B", EXR_PIXEL_HALF, rgba[2] }, { "A", EXR_PIXEL_HALF, rgba[3] },
                               { "Z", EXR_PIXEL_FLOAT, z } };
        out_chan_t layer[] = { { "ViewLayer.Combined.R", EXR_PIXEL_HALF, rgba[0] },
                               { "ViewLayer.Combined.G", EXR_PIXEL_HALF, rgba[1] },
                               { "ViewLayer.Combined.B", EXR_PIXEL_HALF, rgba[2] },
                               { "ViewLayer.Combined.A", EXR_PIXEL_HALF, rgba[3] },
                               { "ViewLayer.Depth.Z", EXR_PIXEL_FLOAT, z } };
        rc = write_exr(path, frame, w, h, args.blender ? layer : plain, 5, &cam, desc);
        if (rc || !sn)
            continue;
        snprintf(path, sizeof path, "%s/shadow.%04ld.exr", dir, frame);
        snprintf(desc, sizeof desc,
                 "fogpipe sample scene, sun depth map, frame %ld: orthographic %.1f x %.1f m "
                 "looking along -sun = (%.4f, %.4f, %.4f); Z = camera-space z, inf = nothing",
                 frame, sc.ww, sc.hw, -l.x, -l.y, -l.z);
        out_chan_t sch[] = { { "Z", EXR_PIXEL_FLOAT, sun_z } };
        rc = write_exr(path, frame, sn, sn, sch, 1, &sc, desc);
    }
    if (!rc && dir) {
        snprintf(path, sizeof path, "%s/fogmap.exr", dir);
        make_fogmap(64, fogmap);
        out_chan_t fch[] = { { "Y", EXR_PIXEL_FLOAT, fogmap } };
        rc = write_exr(path, -1, 64, 64, fch, 1, NULL, "fogpipe sample fogmap");
    }
    if (!rc && chk) {
        double texel = sn ? sc.ww / sn : 0;
        double iou = check.shadow_any ? (double)check.shadow_both / check.shadow_any : 1;
        int judged = sn && texel <= FP_CHECK_TEXEL;
        printf("fogpipe-scene: check: frames %ld-%ld, %ld hit points reprojected: max %.3g px from "
               "the pixel center, max depth error %.3g (relative)",
               args.frames[0], args.frames[1], check.points, check.max_px, check.max_depth);
        if (judged)
            printf("; sun map and traced shadows overlap %.2f%% (%ld shadowed points)\n",
                   100 * iou, check.shadow_any);
        else if (sn)
            printf("; sun map not compared with traced shadows (texel %.2f m > %g m)\n", texel,
                   FP_CHECK_TEXEL);
        else
            printf("; no sun map\n");
        if (check.max_px > FP_CHECK_PX || check.max_depth > FP_CHECK_DEPTH ||
            (judged && iou < FP_CHECK_SUN)) {
            fprintf(stderr, "fogpipe-scene: check failed: expected at most %g px, a relative depth "
                            "error of at most %g and a sun map overlap of at least %g%%\n",
                    FP_CHECK_PX, FP_CHECK_DEPTH, 100 * FP_CHECK_SUN);
            rc = 1;
        }
    }
done:
    for (int c = 0; c < 4; c++)
        free(rgba[c]);
    free(z);
    free(sun_z);
    free(fogmap);
    return rc;
}
