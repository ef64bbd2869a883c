#include "camera.h"
#include "fp.h"
#include "options.h"
#include "textfile.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CAM(f) offsetof(fp_params_t, camera.f)
const fp_option_t fp_camera_options[] = {
    { "camera-pos", 0, FP_OPT_VEC, CAM(pos), 3, 3, NULL, -INFINITY, INFINITY, NULL, "X,Y,Z",
      "camera position in world space (overrides the header's worldToCamera)", NULL, 0 },
    { "camera-target", 0, FP_OPT_VEC, CAM(target), 3, 3, NULL, -INFINITY, INFINITY, NULL, "X,Y,Z",
      "point the camera looks at (world up kept up)", NULL, 0 },
    { "camera-rot", 0, FP_OPT_VEC, CAM(rot), 3, 3, NULL, -360000, 360000, NULL, "RX,RY,RZ",
      "camera rotation in degrees, Nuke's ZXY order, camera looking down -Z with +Y up "
      "before rotation", NULL, 0 },
    { "vfov", 0, FP_OPT_REAL, CAM(vfov), 0, 0, NULL, 0.01, 179, NULL, "DEG",
      "vertical field of view in degrees (overrides the header's worldToNDC)", NULL, 0 },
    { "camera-chan", 0, FP_OPT_STRING, CAM(chan), 0, 0, NULL, 0, 0, NULL, "FILE",
      "Nuke .chan camera file: lines 'frame tx ty tz rx ry rz vfov'", NULL, 0 },
    { "chan-order", 0, FP_OPT_ENUM, CAM(chan_order), 0, 0, "zxy", 0, 0,
      "xyz|xzy|yxz|yzx|zxy|zyx", NULL,
      "order the .chan's rotations are applied in (Nuke's default zxy; Blender's .chan "
      "export writes xyz)", NULL, 0 },
    { "chan-up", 0, FP_OPT_ENUM, CAM(chan_up), 0, 0, "y", 0, 0, "y|z", NULL,
      "up axis of the .chan's coordinates, turned into --up's (Nuke: y; Blender's export "
      "with 'Make Y up' off: z)", NULL, 0 },
    { "chan-sensor", 0, FP_OPT_VEC, CAM(chan_sensor), 2, 2, NULL, 0.01, 10000, NULL, "W,H",
      "sensor of the camera that wrote the .chan, in mm: its last column is then Blender's "
      "angle_y (taken from the sensor height H whatever the fit), and the frame's field of "
      "view comes from that lens, the sensor and --chan-fit", NULL, 0 },
    { "chan-fit", 0, FP_OPT_ENUM, CAM(chan_fit), 0, 0, "auto", 0, 0,
      "auto|horizontal|vertical", NULL,
      "Blender's sensor fit for --chan-sensor (auto: the width W along the longer side)",
      NULL, 0 },
    { "up", 0, FP_OPT_ENUM, CAM(up), 0, 0, "y", 0, 0, "y|z", NULL,
      "world up axis (z for Blender-style data)", NULL, 0 },
    { "depth-kind", 0, FP_OPT_ENUM, CAM(depth_kind), 0, 0, "planar", 0, 0,
      "planar|radial|inverse", NULL,
      "what depth holds: camera-space z, distance along the ray, or 1/z", NULL, 0 },
    { "far", 0, FP_OPT_REAL, CAM(far), 0, 0, "inf", 0, INFINITY, NULL, "D",
      "depth at or beyond this is sky", NULL, 0 },
    { "clip-start", 0, FP_OPT_REAL, CAM(clip_start), 0, 0, "0", 0, 1e9, NULL, "D",
      "the fog starts at planar depth D from the camera, as Cycles' camera rays start at "
      "its clip start (orthographic: D along the view axis); surfaces nearer get no fog "
      "(default: the frame's rig, else 0)", NULL, 0 },
    FP_OPT_END
};

/* ------------------------------------------------------------ matrices */

void fp_mat4_mul(const double a[16], const double b[16], double out[16])
{
    double r[16];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += a[i * 4 + k] * b[k * 4 + j];
            r[i * 4 + j] = s;
        }
    memcpy(out, r, sizeof r);
}

/* Gauss-Jordan with partial pivoting, for any n. */
static int invert(int n, const double *m, double *out)
{
    double a[4][8];
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            a[i][j] = m[i * n + j];
            a[i][n + j] = i == j;
        }
    double scale = 0;
    for (int i = 0; i < n * n; i++)
        scale = fmax(scale, fabs(m[i]));
    if (!(scale > 0))
        return FP_ERR;
    for (int c = 0; c < n; c++) {
        int piv = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(a[r][c]) > fabs(a[piv][c]))
                piv = r;
        if (fabs(a[piv][c]) <= 1e-14 * scale)
            return FP_ERR;
        if (piv != c)
            for (int j = 0; j < 2 * n; j++) {
                double t = a[c][j];
                a[c][j] = a[piv][j];
                a[piv][j] = t;
            }
        double d = a[c][c];
        for (int j = 0; j < 2 * n; j++)
            a[c][j] /= d;
        for (int r = 0; r < n; r++) {
            if (r == c)
                continue;
            double f = a[r][c];
            for (int j = 0; j < 2 * n; j++)
                a[r][j] -= f * a[c][j];
        }
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            out[i * n + j] = a[i][n + j];
    return FP_OK;
}

int fp_mat4_inverse(const double m[16], double out[16]) { return invert(4, m, out); }
int fp_mat3_inverse(const double m[9], double out[9]) { return invert(3, m, out); }

static void mat3_mul(const double a[9], const double b[9], double out[9])
{
    double r[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r[i * 3 + j] = a[i * 3] * b[j] + a[i * 3 + 1] * b[3 + j] + a[i * 3 + 2] * b[6 + j];
    memcpy(out, r, sizeof r);
}

static void rot_x(double deg, double r[9])
{
    double c = cos(deg * M_PI / 180), s = sin(deg * M_PI / 180);
    double m[9] = { 1, 0, 0, 0, c, -s, 0, s, c };
    memcpy(r, m, sizeof m);
}
static void rot_y(double deg, double r[9])
{
    double c = cos(deg * M_PI / 180), s = sin(deg * M_PI / 180);
    double m[9] = { c, 0, s, 0, 1, 0, -s, 0, c };
    memcpy(r, m, sizeof m);
}
static void rot_z(double deg, double r[9])
{
    double c = cos(deg * M_PI / 180), s = sin(deg * M_PI / 180);
    double m[9] = { c, -s, 0, s, c, 0, 0, 0, 1 };
    memcpy(r, m, sizeof m);
}

static void normalize3(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0)
        for (int i = 0; i < 3; i++)
            v[i] /= l;
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    double r[3] = { a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0] };
    memcpy(out, r, sizeof r);
}

/* ------------------------------------------------------------ sources */

/* A projective matrix (worldToCamera, worldToNDC) is the same camera at any
 * nonzero scale, and a header's or a host's may be scaled far from 1
 * (1e300, 1e-300) where single precision (the kernels' view, fp_view_pack)
 * holds nothing but 0 and inf.  Scale it, in double, so that its largest
 * |element| is in [1, 2); NULL, or why it is no projection at all. */
static const char *normalize_projective(const double in[16], double out[16])
{
    double big = 0;
    for (int i = 0; i < 16; i++) {
        if (!isfinite(in[i]))
            return "has a non-finite element (expected 16 finite numbers)";
        big = fmax(big, fabs(in[i]));
    }
    if (!(big > 0))
        return "is all zeros (expected a projective matrix)";
    /* By a power of two: exact, so that a matrix near 1 already gives the
     * very same camera as before, bit for bit. */
    int e = ilogb(big);
    for (int i = 0; i < 16; i++)
        out[i] = ldexp(in[i], -e);
    return NULL;
}

/* Orientation and position from worldToCamera: C2W = inverse(W2C); a
 * camera-space point c maps to [c,1] * C2W, the world point times C2W[15]
 * (1 for an affine worldToCamera; any scale of a normalized one). */
static const char *camera_to_world(const double w2c[16], double c2w[16])
{
    if (fp_mat4_inverse(w2c, c2w))
        return "is not invertible";
    double big = 0;
    for (int i = 0; i < 16; i++)
        big = fmax(big, fabs(c2w[i]));
    if (!(fabs(c2w[15]) > 1e-12 * big))
        return "puts the camera at infinity (the w of its inverse's origin row is 0)";
    /* To w = 1: its power of two exactly, the rest (w's mantissa) only when
     * it is not 1 up to rounding (dividing by 1 + an ulp would move every
     * number of an ordinary camera by one). */
    int e = ilogb(c2w[15]);
    double m = ldexp(c2w[15], -e);
    for (int i = 0; i < 16; i++) {
        c2w[i] = ldexp(c2w[i], -e);
        if (fabs(m - 1) > 1e-12)
            c2w[i] /= m;
    }
    return NULL;
}

/* NULL, or why worldToCamera gives no camera. */
static const char *from_world_to_camera(const double w2c[16], fp_camera_t *c)
{
    double c2w[16];
    const char *why = camera_to_world(w2c, c2w);
    if (why)
        return why;
    for (int i = 0; i < 3; i++) {
        c->origin[i] = c2w[12 + i];
        for (int j = 0; j < 3; j++)
            c->c2w[i * 3 + j] = c2w[j * 4 + i];  /* transpose: column convention */
    }
    return NULL;
}

/* The NDC->camera homography from worldToNDC and worldToCamera: for
 * camera points (x, y, 1), ndc_h = [x, y, 1, 1] * C2N, so the 3x3 map G
 * from (x, y, 1) to (nx w, ny w, w) is read off C2N; invert it. */
static int from_world_to_ndc(const double w2c[16], const double w2n[16], fp_camera_t *c)
{
    double c2w[16], c2n[16], g[9];
    if (camera_to_world(w2c, c2w))
        return FP_ERR;   /* (from_world_to_camera said why) */
    fp_mat4_mul(c2w, w2n, c2n);
    /* A perspective projection's w grows with the depth z; an orthographic
     * one's does not (its rays are parallel, fp_view_origin_at). */
    double wz = fabs(c2n[2 * 4 + 3]), wscale = fabs(c2n[0 * 4 + 3]) + fabs(c2n[1 * 4 + 3]) +
                                                  fabs(c2n[3 * 4 + 3]);
    /* (The header's matrices are single precision, 1e-5 is far above their
     * rounding and far below a real perspective's w.) */
    c->ortho = !(wz > 1e-5 * wscale);
    /* Orthographic: NDC must not change along the view axis (no oblique
     * projection), and G maps the camera plane's (x, y, 1) (z = 0). */
    if (c->ortho && (fabs(c2n[2 * 4 + 0]) + fabs(c2n[2 * 4 + 1]) >
                     1e-5 * (fabs(c2n[0]) + fabs(c2n[5]))))
        return FP_ERR;
    const int cols[3] = { 0, 1, 3 };
    for (int r = 0; r < 3; r++) {
        int k = cols[r];
        g[r * 3 + 0] = c2n[0 * 4 + k];
        g[r * 3 + 1] = c2n[1 * 4 + k];
        g[r * 3 + 2] = (c->ortho ? 0 : c2n[2 * 4 + k]) + c2n[3 * 4 + k];
    }
    if (fp_mat3_inverse(g, c->ndc_to_cam))
        return FP_ERR;
    /* A homography too: any scale, the one that single precision holds
     * (a power of two: exact). */
    double big = 0;
    for (int i = 0; i < 9; i++)
        big = fmax(big, fabs(c->ndc_to_cam[i]));
    if (!(big > 0) || !isfinite(big))
        return FP_ERR;
    int e = ilogb(big);
    for (int i = 0; i < 9; i++)
        c->ndc_to_cam[i] = ldexp(c->ndc_to_cam[i], -e);
    return FP_OK;
}

/* What the kernels get in single precision (fp_view_pack) must be finite
 * there: 1 when every number of `v` (n of them) is below 1e30. */
static int fits_float(const double *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!(fabs(v[i]) < 1e30))
            return 0;
    return 1;
}

static void from_vfov(double vfov_deg, const fp_frame_info_t *info, fp_camera_t *c)
{
    double aspect = (double)info->disp_w * (info->pixel_aspect > 0 ? info->pixel_aspect : 1) /
                    info->disp_h;
    double sy = 1 / (2 * tan(vfov_deg * M_PI / 360));
    double sx = sy / aspect;
    double h[9] = { 1 / sx, 0, -0.5 / sx, 0, -1 / sy, 0.5 / sy, 0, 0, 1 };
    memcpy(c->ndc_to_cam, h, sizeof h);
    c->ortho = 0;
}

/* Rotation angles applied in `order` (FP_ORDER_*: Nuke's ZXY rotates about
 * Z, then X, then Y, R = Ry Rx Rz), camera looking down -Z; OpenEXR camera
 * space looks down +z, so flip z. */
static void from_rotation(const double rot[3], int order, fp_camera_t *c)
{
    static const char axes[6][3] = { { 0, 1, 2 }, { 0, 2, 1 }, { 1, 0, 2 },
                                     { 1, 2, 0 }, { 2, 0, 1 }, { 2, 1, 0 } };
    double m[3][9], r[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    rot_x(rot[0], m[0]);
    rot_y(rot[1], m[1]);
    rot_z(rot[2], m[2]);
    /* Applied first = rightmost: R = M[third] M[second] M[first]. */
    for (int k = 0; k < 3; k++)
        mat3_mul(m[(int)axes[order][k]], r, r);
    const double flip[9] = { 1, 0, 0, 0, 1, 0, 0, 0, -1 };
    mat3_mul(r, flip, c->c2w);
}

/* A .chan's coordinates (up axis chan_up) turned into the world's (up). */
static void chan_to_world(int chan_up, int up, fp_camera_t *c)
{
    if (chan_up == up)
        return;
    /* y up -> z up: (x, y, z) -> (x, -z, y); z up -> y up: (x, y, z) -> (x, z, -y)
     * (Blender's exporter's 'Make Y up'). */
    const double s = chan_up == FP_UP_Y ? 1 : -1;
    const double m[9] = { 1, 0, 0, 0, 0, -s, 0, s, 0 };
    double o[3] = { c->origin[0], -s * c->origin[2], s * c->origin[1] };
    memcpy(c->origin, o, sizeof o);
    mat3_mul(m, c->c2w, c->c2w);
}

static int from_target(const double target[3], int up, fp_camera_t *c,
                       const char *where_file, long frame)
{
    double f[3] = { target[0] - c->origin[0], target[1] - c->origin[1], target[2] - c->origin[2] };
    double wup[3] = { 0, up == FP_UP_Z ? 0 : 1, up == FP_UP_Z ? 1 : 0 };
    normalize3(f);
    double r[3], u[3];
    cross3(f, wup, r);
    if (sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) < 1e-9)
        return fp_usage_error("%s: frame %ld: --camera-target is straight above or below the "
                              "camera (expected a view direction not parallel to up)",
                              where_file, frame);
    normalize3(r);
    cross3(r, f, u);
    for (int i = 0; i < 3; i++) {
        c->c2w[i * 3 + 0] = r[i];
        c->c2w[i * 3 + 1] = u[i];
        c->c2w[i * 3 + 2] = f[i];
    }
    return FP_OK;
}

/* The camera as text in a string attribute (Blender's stamp Note written by
 * samples/blender/fogpipe_camera.py, whose Python writes this format):
 *   fogpipe-camera 1 worldToCamera <16 numbers> worldToNDC <16 numbers>
 * the two matrices as OpenEXR defines them (row-vector convention, row by
 * row).  Blender can write only strings into an EXR header, so its render
 * carries the standard matrices this way. */
static int parse_camera_text(const fp_frame_info_t *info, const char *where_file, long frame,
                             double w2c[16], double w2n[16])
{
    const char *s = strstr(info->camera_text, "fogpipe-camera");
    const char *const names[2] = { "worldToCamera", "worldToNDC" };
    double *mats[2] = { w2c, w2n };
    char *end;
    int ok = s != NULL;
    long version = 0;
    if (ok) {
        s += strlen("fogpipe-camera");
        version = strtol(s, &end, 10);
        ok = end != s && version == 1;
        s = end;
    }
    for (int m = 0; ok && m < 2; m++) {
        while (*s == ' ' || *s == '\t' || *s == '\n' || *s == ';')
            s++;
        size_t n = strlen(names[m]);
        if (strncmp(s, names[m], n) != 0) {
            ok = 0;
            break;
        }
        s += n;
        for (int i = 0; ok && i < 16; i++) {
            mats[m][i] = strtod(s, &end);
            ok = end != s && isfinite(mats[m][i]);
            s = end;
        }
    }
    if (!ok)
        return fp_error("%s: frame %ld: attribute '%s': expected 'fogpipe-camera 1 worldToCamera "
                        "<16 numbers> worldToNDC <16 numbers>' (from samples/blender/"
                        "fogpipe_blender.py)", where_file, frame, info->camera_text_attr);
    return FP_OK;
}

/* Whether tok is a decimal number as a .chan holds them: [+-] digits [.
 * digits] [e [+-] digits].  strtod also takes hexadecimal ("0x10" is 16,
 * "0x1p3" is 8), which no camera exporter writes: a column mangled into
 * one is a corrupt file, not a camera.  (Its "inf" and "nan" are refused
 * by name, as not finite.) */
static int chan_decimal(const char *tok)
{
    const char *s = tok + (*tok == '+' || *tok == '-');
    int digits = 0;
    while (*s >= '0' && *s <= '9')
        s++, digits++;
    if (*s == '.')
        for (s++; *s >= '0' && *s <= '9'; s++)
            digits++;
    if (!digits)
        return 0;
    if (*s == 'e' || *s == 'E') {
        s += 1 + (s[1] == '+' || s[1] == '-');
        if (*s < '0' || *s > '9')
            return 0;
        while (*s >= '0' && *s <= '9')
            s++;
    }
    return *s == 0;
}

/* One line of a Nuke .chan file for `frame`: frame tx ty tz rx ry rz vfov.
 * Every line is checked as the camera options are (finite numbers, the
 * rotations in --camera-rot's range, the FOV in --vfov's), so a bad file is
 * refused whichever frame is asked for. */
static int read_chan(const char *path, long frame, double v[7])
{
    static const char *const names[8] = { "frame", "tx", "ty", "tz", "rx", "ry", "rz",
                                          "vertical FOV" };
    const fp_option_t *rot_opt = fp_option_lookup(fp_camera_options, "camera-rot");
    const fp_option_t *fov_opt = fp_option_lookup(fp_camera_options, "vfov");
    /* Bounded (src/base/textfile.h): --camera-chan /dev/zero fails instead of
     * reading forever. */
    fp_text_t t;
    int rc = fp_text_open(&t, path, "camera file", 0);
    if (rc)
        return rc;
    char *line;
    int found = 0, got;
    while (rc == FP_OK && (got = fp_text_next(&t, &line)) > 0) {
        int lineno = t.lineno;
        char *s = line;
        while (*s == ' ' || *s == '\t')
            s++;
        if (*s == '#' || *s == '\n' || *s == '\r' || *s == 0)
            continue;
        /* Exactly 8 blank-separated numbers, each column a whole number
         * (extra columns are another format, not ours to guess). */
        double a[8];
        int n = 0;
        for (char *tok = strtok(s, " \t"); tok; tok = strtok(NULL, " \t"), n++) {
            char *end;
            double x = strtod(tok, &end);
            if (end == tok || *end || (isfinite(x) && !chan_decimal(tok))) {
                rc = fp_error("%s:%d: column %d '%.40s' is not a number (expected 8 decimal "
                              "numbers: 'frame tx ty tz rx ry rz vfov')", path, lineno, n + 1, tok);
                break;
            }
            if (n < 8)
                a[n] = x;
        }
        if (rc != FP_OK)
            break;
        if (n != 8) {
            rc = fp_error("%s:%d: %d column%s (expected 8: 'frame tx ty tz rx ry rz vfov')", path,
                          lineno, n, n == 1 ? "" : "s");
            break;
        }
        for (int i = 0; i < 8 && rc == FP_OK; i++) {
            double lo = i >= 4 && i < 7 ? rot_opt->min : i == 7 ? fov_opt->min : -INFINITY;
            double hi = i >= 4 && i < 7 ? rot_opt->max : i == 7 ? fov_opt->max : INFINITY;
            if (!isfinite(a[i]))
                rc = fp_error("%s:%d: %s is %g (expected a finite number)", path, lineno,
                              names[i], a[i]);
            else if (a[i] < lo || a[i] > hi)
                rc = fp_error("%s:%d: %s %g is out of range (expected %g..%g, as --%s)", path,
                              lineno, names[i], a[i], lo, hi, i == 7 ? "vfov" : "camera-rot");
        }
        if (rc == FP_OK && !found && fabs(a[0] - (double)frame) < 1e-6) {
            memcpy(v, a + 1, 7 * sizeof(double));
            found = 1;
        }
    }
    if (rc == FP_OK && got < 0)
        rc = t.rc;
    fp_text_close(&t);
    if (rc == FP_OK && !found)
        rc = fp_error("%s: no line for frame %ld", path, frame);
    return rc;
}

/* The vertical field of view of a camera in degrees: the angle between the
 * rays through the middles of the display window's top and bottom edges. */
static double camera_vfov(const fp_camera_t *c)
{
    double d[2][3];
    for (int k = 0; k < 2; k++) {
        const double *h = c->ndc_to_cam;
        double x = h[0] * 0.5 + h[1] * k + h[2];
        double y = h[3] * 0.5 + h[4] * k + h[5];
        double w = h[6] * 0.5 + h[7] * k + h[8];
        double v[3] = { x / w, y / w, 1 };
        normalize3(v);
        memcpy(d[k], v, sizeof v);
    }
    return acos(fmin(1, d[0][0] * d[1][0] + d[0][1] * d[1][1] + d[0][2] * d[1][2])) * 180 / M_PI;
}

/* The frame's vertical FOV from a .chan written by Blender's exporter: its
 * column is angle_y = 2 atan(H / 2 lens) whatever the sensor fit; Blender
 * fits the sensor W (auto: along the longer side; horizontal: along the
 * width) or H (vertical) to the frame.  *lens gets the focal length. */
static double chan_blender_vfov(const fp_camera_params_t *cp, const fp_frame_info_t *info,
                                double col, double *lens)
{
    double w = info->disp_w * (info->pixel_aspect > 0 ? info->pixel_aspect : 1);
    double h = info->disp_h;
    *lens = cp->chan_sensor[1] / (2 * tan(col * M_PI / 360));
    int fit = cp->chan_fit;
    double sensor = cp->chan_sensor[0];
    if (fit == FP_FIT_AUTO)
        fit = w >= h ? FP_FIT_HORIZONTAL : FP_FIT_VERTICAL;
    else if (fit == FP_FIT_VERTICAL)
        sensor = cp->chan_sensor[1];
    double t = sensor / (2 * *lens);          /* tan(half the fitted angle) */
    if (fit == FP_FIT_HORIZONTAL)
        t *= h / w;
    return 2 * atan(t) * 180 / M_PI;
}

/* Once a run (the context's, src/base/fp_ctx.h): what a .chan says
 * against what the frame's header says. */
static const char chan_warned = 0;

static void chan_check(const fp_camera_params_t *cp, const fp_frame_info_t *info,
                       const char *where_file, long frame, double chan_vfov, double chan_lens,
                       double header_vfov)
{
    char msg[400] = "";
    if (header_vfov > 0 && fabs(header_vfov - chan_vfov) > 0.05)
        snprintf(msg, sizeof msg, "its vertical FOV %.3f deg disagrees with the header's "
                 "camera (%.3f deg)", chan_vfov, header_vfov);
    else if (info->lens_mm > 0 && chan_lens > 0 && fabs(chan_lens / info->lens_mm - 1) > 0.005)
        snprintf(msg, sizeof msg, "its FOV with the sensor height %g mm gives a %.2f mm lens, "
                 "the header's Lens says %.2f mm", cp->chan_sensor[1], chan_lens, info->lens_mm);
    if (!msg[0] || !fp_once(&chan_warned))
        return;
    fp_warn("%s: frame %ld: camera file %s: %s (Blender's .chan export: --chan-order xyz, "
            "--chan-sensor W,H; see doc/hosts/nuke.md)", where_file, frame, cp->chan, msg);
}

int fp_camera_matrices(const fp_frame_info_t *info, const char *where_file, long frame,
                       const char *what, double w2c[16], double w2n[16])
{
    if (info->has_world_to_camera && info->has_world_to_ndc) {
        memcpy(w2c, info->world_to_camera, 16 * sizeof *w2c);
        memcpy(w2n, info->world_to_ndc, 16 * sizeof *w2n);
        return FP_OK;
    }
    if (info->camera_text[0])
        return parse_camera_text(info, where_file, frame, w2c, w2n);
    return fp_error("%s: frame %ld: %s without a camera (expected worldToCamera and worldToNDC "
                    "in its header, or a string attribute 'fogpipe-camera 1 ...' as Blender's "
                    "add-on writes into the Note)", where_file, frame, what);
}

int fp_camera_resolve(const fp_params_t *p, const fp_frame_info_t *info,
                      const char *where_file, long frame, fp_camera_t *out)
{
    const fp_camera_params_t *cp = &p->camera;
    fp_camera_t c;
    memset(&c, 0, sizeof c);
    int have_pose = 0, have_proj = 0;
    char src_pose[200] = "", src_proj[200] = "";

    if (info->has_world_to_camera) {
        double w2c[16], w2n[16];
        const char *why = normalize_projective(info->world_to_camera, w2c);
        if (why || (why = from_world_to_camera(w2c, &c)))
            return fp_error("%s: frame %ld: worldToCamera %s (override with "
                            "--camera-pos/--camera-rot)", where_file, frame, why);
        have_pose = 1;
        snprintf(src_pose, sizeof src_pose, "header worldToCamera");
        if (info->has_world_to_ndc) {
            why = normalize_projective(info->world_to_ndc, w2n);
            if (why || from_world_to_ndc(w2c, w2n, &c))
                return fp_error("%s: frame %ld: worldToNDC %s (override with --vfov)",
                                where_file, frame, why ? why : "is not a usable projection");
            have_proj = 1;
            snprintf(src_proj, sizeof src_proj, "header worldToNDC");
        }
    } else if (info->camera_text[0]) {
        double w2c[16], w2n[16];
        if (parse_camera_text(info, where_file, frame, w2c, w2n))
            return FP_ERR;
        const char *why = normalize_projective(w2c, w2c);
        if (why || (why = from_world_to_camera(w2c, &c)))
            return fp_error("%s: frame %ld: attribute '%s': worldToCamera %s", where_file,
                            frame, info->camera_text_attr, why);
        why = normalize_projective(w2n, w2n);
        if (why || from_world_to_ndc(w2c, w2n, &c))
            return fp_error("%s: frame %ld: attribute '%s': worldToNDC %s", where_file, frame,
                            info->camera_text_attr, why ? why : "is not a usable projection");
        have_pose = have_proj = 1;
        snprintf(src_pose, sizeof src_pose, "header %.64s (fogpipe-camera)", info->camera_text_attr);
        snprintf(src_proj, sizeof src_proj, "header %.64s (fogpipe-camera)", info->camera_text_attr);
    }

    double chan[7];
    if (cp->chan) {
        if (read_chan(cp->chan, frame, chan))
            return FP_ERR;
        double header_vfov = have_proj && !c.ortho ? camera_vfov(&c) : 0, lens = 0,
               vfov = chan[6];
        if (fp_options_given(p, "chan-sensor"))
            vfov = chan_blender_vfov(cp, info, chan[6], &lens);
        if (!(vfov >= 0.01 && vfov <= 179))
            return fp_error("%s: frame %ld: camera file %s: --chan-sensor %g,%g gives a "
                            "vertical FOV of %g deg (expected 0.01..179)", where_file, frame,
                            cp->chan, cp->chan_sensor[0], cp->chan_sensor[1], vfov);
        chan_check(cp, info, where_file, frame, vfov, lens, header_vfov);
        memcpy(c.origin, chan, 3 * sizeof(double));
        from_rotation(chan + 3, cp->chan_order, &c);
        chan_to_world(cp->chan_up, cp->up, &c);
        from_vfov(vfov, info, &c);
        have_pose = have_proj = 1;
        snprintf(src_pose, sizeof src_pose, "%.150s", cp->chan);
        snprintf(src_proj, sizeof src_proj, "%.150s", cp->chan);
    }
    if (fp_options_given(p, "camera-pos")) {
        memcpy(c.origin, cp->pos, sizeof c.origin);
        if (!have_pose)
            memcpy(c.c2w, (double[9]){ 1, 0, 0, 0, 1, 0, 0, 0, -1 }, sizeof c.c2w);
        have_pose = 1;
        snprintf(src_pose, sizeof src_pose, "options");
    }
    if (fp_options_given(p, "camera-target")) {
        if (!have_pose)
            return fp_usage_error("%s: frame %ld: --camera-target needs a camera position "
                                  "(--camera-pos or the header's worldToCamera)", where_file, frame);
        if (from_target(cp->target, cp->up, &c, where_file, frame))
            return FP_EUSAGE;
        snprintf(src_pose, sizeof src_pose, "options");
    } else if (fp_options_given(p, "camera-rot")) {
        if (!have_pose)
            return fp_usage_error("%s: frame %ld: --camera-rot needs a camera position "
                                  "(--camera-pos or the header's worldToCamera)", where_file, frame);
        from_rotation(cp->rot, FP_ORDER_ZXY, &c);
        snprintf(src_pose, sizeof src_pose, "options");
    }
    if (fp_options_given(p, "vfov")) {
        from_vfov(cp->vfov, info, &c);
        have_proj = 1;
        snprintf(src_proj, sizeof src_proj, "--vfov");
    }
    if (!have_pose)
        return fp_error("%s: frame %ld: no camera (expected a worldToCamera header attribute; "
                        "or give --camera-pos with --camera-rot or --camera-target, and --vfov, "
                        "or --camera-chan)", where_file, frame);
    if (!have_proj)
        return fp_error("%s: frame %ld: no projection (expected a worldToNDC header attribute; "
                        "or give --vfov)", where_file, frame);
    /* A position or a scale of camera space beyond single precision (a
     * worldToCamera whose 3x3 part is 1e-300 with w = 1 is such a camera,
     * not a scaled projective matrix). */
    if (!fits_float(c.origin, 3) || !fits_float(c.c2w, 9))
        return fp_error("%s: frame %ld: the camera position/orientation from %s is beyond "
                        "single precision (expected |position| and camera-space scale "
                        "below 1e30)", where_file, frame, src_pose);
    snprintf(c.source, sizeof c.source, "position/orientation from %s, projection from %s",
             src_pose, src_proj);
    *out = c;
    return FP_OK;
}

void fp_camera_print(FILE *out, const fp_camera_t *c, const fp_frame_info_t *info,
                     const char *where_file, long frame)
{
    /* The image center and the middles of its edges: directions for a
     * perspective camera (the fields of view), points on the camera's plane
     * for an orthographic one (the view's size). */
    double cc[3], top[3], bot[3], lft[3], rgt[3];
    double pts[5][2] = { { 0.5, 0.5 }, { 0.5, 0 }, { 0.5, 1 }, { 0, 0.5 }, { 1, 0.5 } };
    double *dirs[5] = { cc, top, bot, lft, rgt };
    for (int k = 0; k < 5; k++) {
        const double *h = c->ndc_to_cam;
        double x = h[0] * pts[k][0] + h[1] * pts[k][1] + h[2];
        double y = h[3] * pts[k][0] + h[4] * pts[k][1] + h[5];
        double w = h[6] * pts[k][0] + h[7] * pts[k][1] + h[8];
        double v[3] = { x / w, y / w, 1 };
        if (!c->ortho)
            normalize3(v);
        memcpy(dirs[k], v, sizeof v);
    }
    double fw[3], up[3], rt[3], center[3];
    const double axis[3] = { 0, 0, 1 }, *f = c->ortho ? axis : cc;
    for (int i = 0; i < 3; i++) {
        fw[i] = c->c2w[i * 3] * f[0] + c->c2w[i * 3 + 1] * f[1] + c->c2w[i * 3 + 2] * f[2];
        rt[i] = c->c2w[i * 3];
        up[i] = c->c2w[i * 3 + 1];
        center[i] = c->origin[i] + c->c2w[i * 3] * cc[0] + c->c2w[i * 3 + 1] * cc[1];
    }
    normalize3(fw);
    normalize3(up);
    normalize3(rt);
    char proj[200];
    if (c->ortho) {
        snprintf(proj, sizeof proj, "orthographic view %.6g x %.6g centered at %.6g %.6g %.6g",
                 fabs(rgt[0] - lft[0]), fabs(top[1] - bot[1]), center[0], center[1], center[2]);
    } else {
        double vfov = acos(fmin(1, top[0] * bot[0] + top[1] * bot[1] + top[2] * bot[2])) * 180 / M_PI;
        double hfov = acos(fmin(1, lft[0] * rgt[0] + lft[1] * rgt[1] + lft[2] * rgt[2])) * 180 / M_PI;
        snprintf(proj, sizeof proj, "vfov %.4f deg, hfov %.4f deg", vfov, hfov);
    }
    fprintf(out,
            "%s: frame %ld: camera (%s)\n"
            "  position  %.6g %.6g %.6g\n"
            "  forward   %.6f %.6f %.6f\n"
            "  up        %.6f %.6f %.6f\n"
            "  right     %.6f %.6f %.6f\n"
            "  %s, display window %dx%d at (%d,%d), data window %dx%d at (%d,%d)\n",
            where_file, frame, c->source, c->origin[0], c->origin[1], c->origin[2],
            fw[0], fw[1], fw[2], up[0], up[1], up[2], rt[0], rt[1], rt[2], proj,
            info->disp_w, info->disp_h, info->disp_x0, info->disp_y0, info->width,
            info->height, info->data_x0, info->data_y0);
}

/* ------------------------------------------------------------ view */

void fp_world_to_fog(int up, const double w[3], double f[3])
{
    double r[3] = { w[0], up == FP_UP_Z ? w[2] : w[1], up == FP_UP_Z ? -w[1] : w[2] };
    memcpy(f, r, sizeof r);
}

int fp_view_setup(const fp_camera_t *c, const fp_params_t *p,
                  const fp_frame_info_t *info, fp_view_t *out)
{
    fp_view_t v;
    memset(&v, 0, sizeof v);
    fp_world_to_fog(p->camera.up, c->origin, v.origin);
    for (int j = 0; j < 3; j++) {
        double col[3] = { c->c2w[j], c->c2w[3 + j], c->c2w[6 + j] }, fcol[3];
        fp_world_to_fog(p->camera.up, col, fcol);
        for (int i = 0; i < 3; i++)
            v.m[i * 3 + j] = fcol[i];
    }
    memcpy(v.h, c->ndc_to_cam, sizeof v.h);
    v.ndc_scale[0] = 1.0 / info->disp_w;
    v.ndc_scale[1] = 1.0 / info->disp_h;
    v.ndc_offset[0] = info->data_x0 + 0.5 - info->disp_x0;
    v.ndc_offset[1] = info->data_y0 + 0.5 - info->disp_y0;
    v.far = p->camera.far;
    v.depth_kind = p->camera.depth_kind;
    v.width = info->width;
    v.height = info->height;
    v.ortho = c->ortho;
    v.clip = p->camera.clip_start;
    *out = v;
    return FP_OK;
}

int fp_view_is_sky(const fp_view_t *v, float depth, int *suspicious)
{
    *suspicious = 0;
    if (isnan(depth) || depth < 0) {
        *suspicious = 1;
        return 1;
    }
    double z = depth;
    if (v->depth_kind == FP_DEPTH_INVERSE) {
        if (depth == 0)
            return 1;
        z = 1.0 / depth;
    }
    return isinf(z) || z >= 1e10 || z >= v->far;
}

/* The camera-space point (perspective: direction (x/z, y/z, 1); orthographic:
 * the point (x, y) on the camera's plane) of pixel (x, y). */
static void view_cam(const fp_view_t *v, int x, int y, double c[2])
{
    const double *h = v->h;
    double nx = (x + v->ndc_offset[0]) * v->ndc_scale[0];
    double ny = (y + v->ndc_offset[1]) * v->ndc_scale[1];
    double cw = h[6] * nx + h[7] * ny + h[8];
    c[0] = (h[0] * nx + h[1] * ny + h[2]) / cw;
    c[1] = (h[3] * nx + h[4] * ny + h[5]) / cw;
}

void fp_view_ray(const fp_view_t *v, int x, int y, float depth, double dir[3], double *len)
{
    double p[2];
    view_cam(v, x, y, p);
    /* An orthographic ray runs along the view axis; its depth is the
     * distance from the camera's plane, planar or along the ray alike. */
    double c[3] = { v->ortho ? 0 : p[0], v->ortho ? 0 : p[1], 1 };
    int suspicious;
    double scale;   /* camera-space point = c * scale */
    int sky = fp_view_is_sky(v, depth, &suspicious);
    if (!sky) {
        if (v->depth_kind == FP_DEPTH_PLANAR)
            scale = depth;
        else if (v->depth_kind == FP_DEPTH_RADIAL)
            scale = depth / sqrt(c[0] * c[0] + c[1] * c[1] + 1);
        else
            scale = 1.0 / depth;
    } else {
        scale = 1;
    }
    /* Direction from the unscaled camera vector, so that a zero depth still
     * has a direction. */
    double d[3];
    for (int i = 0; i < 3; i++)
        d[i] = v->m[i * 3] * c[0] + v->m[i * 3 + 1] * c[1] + v->m[i * 3 + 2] * c[2];
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int i = 0; i < 3; i++)
        dir[i] = d[i] / l;
    *len = sky ? INFINITY : l * scale;
    /* From the clip plane (planar depth clip: l * clip along the ray). */
    if (v->clip > 0 && !sky)
        *len = fmax(*len - l * v->clip, 0);
}

void fp_view_origin_at(const fp_view_t *v, int x, int y, double o[3])
{
    memcpy(o, v->origin, 3 * sizeof(double));
    if (!v->ortho && !(v->clip > 0))
        return;
    double p[2];
    view_cam(v, x, y, p);
    if (v->ortho)
        for (int i = 0; i < 3; i++)
            o[i] += v->m[i * 3] * p[0] + v->m[i * 3 + 1] * p[1];
    if (v->clip > 0) {
        /* To the clip plane: the camera vector (x/z, y/z, 1) (orthographic:
         * (0, 0, 1)) times the planar depth. */
        double c[3] = { v->ortho ? 0 : p[0], v->ortho ? 0 : p[1], 1 };
        for (int i = 0; i < 3; i++)
            o[i] += v->clip * (v->m[i * 3] * c[0] + v->m[i * 3 + 1] * c[1] + v->m[i * 3 + 2]);
    }
}

void fp_view_pack(const fp_view_t *v, float out[FP_VIEW_FLOATS])
{
    memset(out, 0, FP_VIEW_FLOATS * sizeof(float));
    for (int i = 0; i < 3; i++)
        out[i] = (float)v->origin[i];
    for (int i = 0; i < 9; i++) {
        out[3 + i] = (float)v->m[i];
        out[12 + i] = (float)v->h[i];
    }
    out[21] = (float)v->ndc_scale[0];
    out[22] = (float)v->ndc_scale[1];
    out[23] = (float)v->ndc_offset[0];
    out[24] = (float)v->ndc_offset[1];
    out[25] = (float)v->far;
    out[26] = (float)v->depth_kind;
    out[27] = (float)v->ortho;
    out[28] = (float)v->clip;
}
