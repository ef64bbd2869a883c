/* Camera: OpenEXR header matrices, overrides, .chan files, view rays and
 * depth kinds. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "camera.h"
#include "fp.h"
#include "options.h"
#include "testutil.h"

static void norm(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= l;
}

/* OpenEXR's definitions, written out independently of src/scene/camera.c. */
static void header_camera(const double C[3], const double F0[3], double vfov, int w, int h,
                          fp_frame_info_t *info)
{
    double F[3] = { F0[0], F0[1], F0[2] }, R[3], U[3];
    norm(F);
    R[0] = -F[2];   /* cross(F, (0,1,0)) */
    R[1] = 0;
    R[2] = F[0];
    norm(R);
    U[0] = R[1] * F[2] - R[2] * F[1];
    U[1] = R[2] * F[0] - R[0] * F[2];
    U[2] = R[0] * F[1] - R[1] * F[0];
    double m[16] = { R[0], U[0], F[0], 0, R[1], U[1], F[1], 0, R[2], U[2], F[2], 0,
                     -(C[0] * R[0] + C[1] * R[1] + C[2] * R[2]),
                     -(C[0] * U[0] + C[1] * U[1] + C[2] * U[2]),
                     -(C[0] * F[0] + C[1] * F[1] + C[2] * F[2]), 1 };
    double sy = 1 / (2 * tan(vfov * M_PI / 360)), sx = sy * h / w;
    double P[16] = { sx, 0, 0, 0, 0, -sy, 0, 0, 0.5, 0.5, 1, 1, 0, 0, 0, 0 };
    memset(info, 0, sizeof *info);
    info->width = info->disp_w = w;
    info->height = info->disp_h = h;
    info->pixel_aspect = 1;
    info->has_world_to_camera = info->has_world_to_ndc = 1;
    memcpy(info->world_to_camera, m, sizeof m);
    fp_mat4_mul(m, P, info->world_to_ndc);
}

static void xform(const double m[16], const double p[3], double out[4])
{
    for (int j = 0; j < 4; j++)
        out[j] = p[0] * m[j] + p[1] * m[4 + j] + p[2] * m[8 + j] + m[12 + j];
}

static void test_header_rays(void **state)
{
    (void)state;
    for (int trial = 0; trial < 50; trial++) {
        double C[3] = { 100 * urand() - 50, 20 * urand(), 100 * urand() - 50 };
        double F[3] = { urand() - 0.5, 0.6 * (urand() - 0.5), urand() - 0.5 };
        int w = 64 + (int)(200 * urand()), h = 48 + (int)(100 * urand());
        fp_frame_info_t info;
        header_camera(C, F, 20 + 80 * urand(), w, h, &info);
        /* A data window inside a bigger display window. */
        info.data_x0 = 3;
        info.data_y0 = 5;
        info.disp_x0 = -2;
        info.disp_y0 = 1;
        info.width = w - 9;
        info.height = h - 11;
        fp_params_t p;
        fp_options_defaults(&p);
        p.camera.depth_kind = trial % 3;
        fp_camera_t c;
        fp_view_t v;
        assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
        assert_int_equal(fp_view_setup(&c, &p, &info, &v), FP_OK);
        for (int k = 0; k < 3; k++)
            assert_double_equal(c.origin[k], C[k], 1e-9 * (1 + fabs(C[k])));
        for (int s = 0; s < 20; s++) {
            int x = (int)(urand() * info.width), y = (int)(urand() * info.height);
            float depth = (float)(0.5 + 200 * urand());
            double dir[3], len, P[3], cam[4], ndc[4];
            fp_view_ray(&v, x, y, depth, dir, &len);
            for (int k = 0; k < 3; k++)
                P[k] = C[k] + dir[k] * len;
            xform(info.world_to_camera, P, cam);
            xform(info.world_to_ndc, P, ndc);
            double want_nx = (x + info.data_x0 + 0.5 - info.disp_x0) / (double)info.disp_w;
            double want_ny = (y + info.data_y0 + 0.5 - info.disp_y0) / (double)info.disp_h;
            assert_double_equal(ndc[0] / ndc[3], want_nx, 1e-9);
            assert_double_equal(ndc[1] / ndc[3], want_ny, 1e-9);
            if (p.camera.depth_kind == FP_DEPTH_PLANAR)
                assert_double_equal(cam[2], depth, 1e-9 * depth);
            else if (p.camera.depth_kind == FP_DEPTH_RADIAL)
                assert_double_equal(len, depth, 1e-9 * depth);
            else
                assert_double_equal(cam[2], 1.0 / depth, 1e-9 / depth);
        }
        fp_options_free(&p);
    }
}

static void center_dir(const char *const *args, int nargs, int up, double dir[3])
{
    fp_params_t p;
    fp_options_defaults(&p);
    for (int i = 0; i + 1 < nargs; i += 2)
        assert_int_equal(fp_options_apply(&p, args[i], args[i + 1], "test"), FP_OK);
    p.camera.up = up;
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = 101;
    info.height = info.disp_h = 51;
    info.pixel_aspect = 1;
    fp_camera_t c;
    fp_view_t v;
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 7, &c), FP_OK);
    assert_int_equal(fp_view_setup(&c, &p, &info, &v), FP_OK);
    double len;
    fp_view_ray(&v, 50, 25, 1, dir, &len);
    fp_options_free(&p);
}

static void test_overrides(void **state)
{
    (void)state;
    double d[3];
    /* No rotation: the camera looks down -Z. */
    const char *a1[] = { "camera-pos", "0,1,0", "camera-rot", "0,0,0", "vfov", "40" };
    center_dir(a1, 6, FP_UP_Y, d);
    assert_double_equal(d[2], -1, 1e-12);
    /* Yaw 90 degrees about Y turns -Z into -X. */
    const char *a2[] = { "camera-pos", "0,1,0", "camera-rot", "0,90,0", "vfov", "40" };
    center_dir(a2, 6, FP_UP_Y, d);
    assert_double_equal(d[0], -1, 1e-12);
    /* Pitch +30 about X looks up. */
    const char *a3[] = { "camera-pos", "0,1,0", "camera-rot", "30,0,0", "vfov", "40" };
    center_dir(a3, 6, FP_UP_Y, d);
    assert_double_equal(d[1], sin(M_PI / 6), 1e-12);
    /* Look-at; with --up z, fog space is (x, z, -y). */
    const char *a4[] = { "camera-pos", "1,2,3", "camera-target", "4,6,3", "vfov", "40" };
    center_dir(a4, 6, FP_UP_Z, d);
    assert_double_equal(d[0], 0.6, 1e-12);
    assert_double_equal(d[1], 0, 1e-12);
    assert_double_equal(d[2], -0.8, 1e-12);
}

static void test_chan_and_errors(void **state)
{
    (void)state;
    char path[] = "/tmp/fp-chan-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    const char *text = "1 0 1 0 0 0 0 40\n2 0 1 0 0 90 0 40\n";
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    fp_params_t p;
    fp_options_defaults(&p);
    assert_int_equal(fp_options_apply(&p, "camera-chan", path, "test"), FP_OK);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = 40;
    info.height = info.disp_h = 30;
    info.pixel_aspect = 1;
    fp_camera_t c;
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 2, &c), FP_OK);
    assert_double_equal(c.c2w[2], -1, 1e-12);   /* forward = -X */
    assert_int_not_equal(fp_camera_resolve(&p, &info, "t.exr", 3, &c), FP_OK);
    fp_options_free(&p);
    unlink(path);
    /* No header camera and no overrides. */
    fp_options_defaults(&p);
    assert_int_not_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
    fp_options_free(&p);
}

/* A .chan file with `text`; resolve frame `frame` with extra options. */
static int chan_camera(const char *text, const char *const *args, int nargs, int w, int h,
                       long frame, fp_camera_t *c)
{
    char path[] = "/tmp/fp-chan-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    fp_params_t p;
    fp_options_defaults(&p);
    assert_int_equal(fp_options_apply(&p, "camera-chan", path, "test"), FP_OK);
    for (int i = 0; i + 1 < nargs; i += 2)
        assert_int_equal(fp_options_apply(&p, args[i], args[i + 1], "test"), FP_OK);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = w;
    info.height = info.disp_h = h;
    info.pixel_aspect = 1;
    int rc = fp_camera_resolve(&p, &info, "t.exr", frame, c);
    fp_options_free(&p);
    unlink(path);
    return rc;
}

/* Rotation by `deg` about axis 0/1/2, applied to the columns of m (m = R m). */
static void rotate(int axis, double deg, double m[9])
{
    double c = cos(deg * M_PI / 180), s = sin(deg * M_PI / 180), r[9] = { 0 }, out[9];
    int a = (axis + 1) % 3, b = (axis + 2) % 3;
    r[axis * 3 + axis] = 1;
    r[a * 3 + a] = c;
    r[a * 3 + b] = -s;
    r[b * 3 + a] = s;
    r[b * 3 + b] = c;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[i * 3 + j] = r[i * 3] * m[j] + r[i * 3 + 1] * m[3 + j] + r[i * 3 + 2] * m[6 + j];
    memcpy(m, out, sizeof out);
}

static void test_chan_orders_and_up(void **state)
{
    (void)state;
    const char *orders[6] = { "xyz", "xzy", "yxz", "yzx", "zxy", "zyx" };
    const double rot[3] = { 30, -40, 55 };
    for (int k = 0; k < 6; k++) {
        const char *args[] = { "chan-order", orders[k] };
        fp_camera_t c;
        assert_int_equal(chan_camera("1 1 2 3 30 -40 55 40\n", args, 2, 40, 30, 1, &c), FP_OK);
        /* The axes applied one after the other, the camera looking down -Z. */
        double m[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
        for (int i = 0; i < 3; i++) {
            int axis = orders[k][i] - 'x';
            rotate(axis, rot[axis], m);
        }
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                assert_double_equal(c.c2w[i * 3 + j], j == 2 ? -m[i * 3 + j] : m[i * 3 + j], 1e-12);
    }
    /* Blender's exporter's 'Make Y up': (x, y, z) -> (x, z, -y) and the
     * rotation before the Euler angles.  The same camera written Z-up with
     * --chan-up z, or Y-up with --chan-up y, is one camera with --up z. */
    const char *zup[] = { "chan-order", "xyz", "chan-up", "z", "up", "z" };
    const char *yup[] = { "chan-order", "xyz", "chan-up", "y", "up", "z" };
    fp_camera_t a, b;
    assert_int_equal(chan_camera("1 4 -5 3 70 0 35 40\n", zup, 6, 40, 30, 1, &a), FP_OK);
    /* Y-up: position (4, 3, 5); rotation Rx(-90) * Rz(35) Rx(70) = Rz'... as XYZ Euler:
     * the same world rotation expressed after the axis change, computed here. */
    double m[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    rotate(0, 70, m);
    rotate(2, 35, m);
    rotate(0, -90, m);
    /* Euler XYZ angles of m (m = Rz Ry Rx): ry = -asin(m20), rx = atan2(m21, m22),
     * rz = atan2(m10, m00). */
    double ry = -asin(m[6]) * 180 / M_PI, rx = atan2(m[7], m[8]) * 180 / M_PI,
           rz = atan2(m[3], m[0]) * 180 / M_PI;
    char line[200];
    snprintf(line, sizeof line, "1 4 3 5 %.17g %.17g %.17g 40\n", rx, ry, rz);
    assert_int_equal(chan_camera(line, yup, 6, 40, 30, 1, &b), FP_OK);
    for (int i = 0; i < 3; i++)
        assert_double_equal(a.origin[i], b.origin[i], 1e-12);
    for (int i = 0; i < 9; i++)
        assert_double_equal(a.c2w[i], b.c2w[i], 1e-12);
}

/* The vertical FOV of a resolved camera (rays through the middles of the
 * top and bottom edges). */
static double vfov_of(const fp_camera_t *c)
{
    const double *h = c->ndc_to_cam;
    double y0 = (h[3] * 0.5 + h[5]) / (h[6] * 0.5 + h[8]);
    double y1 = (h[3] * 0.5 + h[4] + h[5]) / (h[6] * 0.5 + h[7] + h[8]);
    return (atan(fabs(y0)) + atan(fabs(y1))) * 180 / M_PI;
}

static void test_chan_blender_sensor(void **state)
{
    (void)state;
    fp_camera_t c;
    /* Blender's default 36 x 24 mm sensor, a 30 mm lens, 1920x1080: the
     * exporter writes angle_y = 2 atan(12 / 30) = 43.6 deg; the frame's
     * vertical FOV is 2 atan(18 * 1080 / 1920 / 30) = 37.3 deg. */
    char line[100];
    snprintf(line, sizeof line, "1 0 0 0 0 0 0 %.17g\n", 2 * atan(12.0 / 30) * 180 / M_PI);
    assert_int_equal(chan_camera(line, NULL, 0, 1920, 1080, 1, &c), FP_OK);
    assert_double_equal(vfov_of(&c), 43.6028, 1e-4);
    const char *auto_fit[] = { "chan-sensor", "36,24" };
    assert_int_equal(chan_camera(line, auto_fit, 2, 1920, 1080, 1, &c), FP_OK);
    assert_double_equal(vfov_of(&c), 2 * atan(18.0 * 1080 / 1920 / 30) * 180 / M_PI, 1e-9);
    /* Portrait with auto: the width W along the height. */
    assert_int_equal(chan_camera(line, auto_fit, 2, 1080, 1920, 1, &c), FP_OK);
    assert_double_equal(vfov_of(&c), 2 * atan(18.0 / 30) * 180 / M_PI, 1e-9);
    const char *vert[] = { "chan-sensor", "36,24", "chan-fit", "vertical" };
    assert_int_equal(chan_camera(line, vert, 4, 1920, 1080, 1, &c), FP_OK);
    assert_double_equal(vfov_of(&c), 2 * atan(12.0 / 30) * 180 / M_PI, 1e-9);
    const char *horiz[] = { "chan-sensor", "36,24", "chan-fit", "horizontal" };
    assert_int_equal(chan_camera(line, horiz, 4, 1080, 1920, 1, &c), FP_OK);
    assert_double_equal(vfov_of(&c), 2 * atan(18.0 * 1920 / 1080 / 30) * 180 / M_PI, 1e-9);
}

static void test_chan_range(void **state)
{
    (void)state;
    fp_camera_t c;
    const char *bad[] = { "1 0 0 0 0 0 0 0\n", "1 0 0 0 0 0 0 179.5\n", "1 nan 0 0 0 0 0 40\n",
                          "1 0 0 0 0 inf 0 40\n", "1 0 0 0 0 0 0 40\n2 0 0 0 0 0 0 nan\n",
                          "1 0 0 0 400000 0 0 40\n", "1 0 0 0 0 0 40\n" };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        assert_int_not_equal(chan_camera(bad[i], NULL, 0, 40, 30, 1, &c), FP_OK);
    assert_int_equal(chan_camera("# comment\n\n1 0 0 0 0 0 0 0.01\n", NULL, 0, 40, 30, 1, &c),
                     FP_OK);
}

static void test_camera_text(void **state)
{
    (void)state;
    fp_params_t p;
    fp_options_defaults(&p);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = 40;
    info.height = info.disp_h = 30;
    info.pixel_aspect = 1;
    snprintf(info.camera_text_attr, sizeof info.camera_text_attr, "Note");
    /* A camera at (1, 2, 3) looking down world +z, vfov 90 deg on 40x30
     * (tan(vfov/2) = 1: NDC y = 0.5 - 0.5 y/z, x = 0.5 + 0.5 * 0.75 x/z). */
    snprintf(info.camera_text, sizeof info.camera_text,
             "shot 12 | fogpipe-camera 1 worldToCamera 1 0 0 0 0 1 0 0 0 0 1 0 -1 -2 -3 1 "
             "worldToNDC 0.375 0 0 0 0 -0.5 0 0 0.5 0.5 0 1 -1.875 -0.5 0 -3");
    fp_camera_t c;
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
    assert_double_equal(c.origin[0], 1, 1e-12);
    assert_double_equal(c.origin[2], 3, 1e-12);
    assert_double_equal(vfov_of(&c), 90, 1e-9);
    assert_non_null(strstr(c.source, "Note (fogpipe-camera)"));
    /* Orthographic, 4 x 3 scene units on 40x30 pixels, looking down +z from
     * (1, 2, 3): NDC x = 0.5 + x / 4, y = 0.5 - y / 3.  Pixel (0, 0)'s ray
     * starts at (1 - 1.95, 2 + 1.45, 3) and runs along +z for its depth,
     * planar or radial alike. */
    snprintf(info.camera_text, sizeof info.camera_text,
             "fogpipe-camera 1 worldToCamera 1 0 0 0 0 1 0 0 0 0 1 0 -1 -2 -3 1 "
             "worldToNDC 0.25 0 0 0 0 -0.333333333333333333 0 0 0 0 1 0 0.25 1.16666666666666667 -3 1");
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
    assert_true(c.ortho);
    for (int kind = FP_DEPTH_PLANAR; kind <= FP_DEPTH_INVERSE; kind++) {
        fp_view_t v;
        p.camera.depth_kind = kind;
        assert_int_equal(fp_view_setup(&c, &p, &info, &v), FP_OK);
        double dir[3], len, o[3];
        fp_view_ray(&v, 0, 0, kind == FP_DEPTH_INVERSE ? 0.2f : 5.0f, dir, &len);
        fp_view_origin_at(&v, 0, 0, o);
        assert_double_equal(o[0], 1 - 1.95, 1e-12);
        assert_double_equal(o[1], 2 + 1.45, 1e-12);
        assert_double_equal(o[2], 3, 1e-12);
        assert_double_equal(dir[2], 1, 1e-12);
        assert_double_equal(len, 5, 1e-6);
    }
    p.camera.depth_kind = FP_DEPTH_PLANAR;
    /* Cut short, not finite, an unknown version, an oblique orthographic
     * projection: refused. */
    const char *bad[] = { "fogpipe-camera 1 worldToCamera 1 0 0 0 0 1 0 0 0 0 1 0 -1 -2 -3 1",
                          "fogpipe-camera 2 worldToCamera 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 "
                          "worldToNDC 1 0 0 0 0 1 0 0 0 0 1 1 0 0 0 0",
                          "fogpipe-camera 1 worldToCamera nan 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 "
                          "worldToNDC 1 0 0 0 0 1 0 0 0 0 1 1 0 0 0 0",
                          "fogpipe-camera 1 worldToCamera 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 "
                          "worldToNDC 0.1 0 0 0 0 -0.1 0 0 0.05 0 1 0 0.5 0.5 0 1" };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(info.camera_text, sizeof info.camera_text, "%s", bad[i]);
        assert_int_not_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
    }
    fp_options_free(&p);
}

/* The header's Lens (Blender's stamp) against a .chan read with
 * --chan-sensor: a 50 mm lens in the header, a .chan whose angle_y says
 * 30 mm, one warning naming both; the warning comes once a run. */
static void test_chan_lens_warning(void **state)
{
    (void)state;
    char path[] = "/tmp/fp-chan-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    char line[100];
    snprintf(line, sizeof line, "1 0 0 0 0 0 0 %.17g\n2 0 0 0 0 0 0 %.17g\n",
             2 * atan(12.0 / 30) * 180 / M_PI, 2 * atan(12.0 / 50) * 180 / M_PI);
    assert_int_equal(write(fd, line, strlen(line)), (ssize_t)strlen(line));
    close(fd);
    fp_params_t p;
    fp_options_defaults(&p);
    assert_int_equal(fp_options_apply(&p, "camera-chan", path, "test"), FP_OK);
    assert_int_equal(fp_options_apply(&p, "chan-sensor", "36,24", "test"), FP_OK);
    fp_frame_info_t info;
    memset(&info, 0, sizeof info);
    info.width = info.disp_w = 64;
    info.height = info.disp_h = 36;
    info.pixel_aspect = 1;
    info.lens_mm = 50;
    fp_camera_t c;
    fp_msgbuf_t buf;
    memset(&buf, 0, sizeof buf);
    fp_msgbuf_t *prev = fp_msg_capture(&buf);
    /* Frame 2 agrees (50 mm): no warning; frame 1 (30 mm) warns. */
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 2, &c), FP_OK);
    assert_int_equal((int)buf.len, 0);
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
    assert_int_equal(fp_camera_resolve(&p, &info, "t.exr", 1, &c), FP_OK);
    fp_msg_capture(prev);
    assert_non_null(buf.text);
    /* The kept lines are buf.len bytes, not a C string. */
    char text[1024];
    snprintf(text, sizeof text, "%.*s", (int)buf.len, buf.text);
    assert_non_null(strstr(text, "t.exr: frame 1: camera file"));
    assert_non_null(strstr(text, "gives a 30.00 mm lens, the header's Lens says 50.00 mm"));
    assert_null(strchr(strchr(text, '\n') + 1, '\n'));   /* one line */
    fp_msg_free(&buf);
    fp_options_free(&p);
    unlink(path);
}

static void test_sky(void **state)
{
    (void)state;
    fp_view_t v;
    memset(&v, 0, sizeof v);
    v.far = 500;
    int s;
    assert_true(fp_view_is_sky(&v, INFINITY, &s) && !s);
    assert_true(fp_view_is_sky(&v, 1e10f, &s) && !s);
    assert_true(fp_view_is_sky(&v, 600, &s) && !s);
    assert_true(fp_view_is_sky(&v, NAN, &s) && s);
    assert_true(fp_view_is_sky(&v, -1, &s) && s);
    assert_false(fp_view_is_sky(&v, 10, &s));
    v.depth_kind = FP_DEPTH_INVERSE;
    assert_true(fp_view_is_sky(&v, 0, &s) && !s);
    assert_false(fp_view_is_sky(&v, 0.1f, &s));
    assert_true(fp_view_is_sky(&v, 0.001f, &s));   /* z = 1000 beyond far */
}

/* The direction of pixel (x, y)'s ray as the kernels compute it, in single
 * precision from the packed view (kernels/fp_common.h). */
static void float_dir(const float *view, int x, int y, double out[3])
{
    const float *m = view + 3, *h = view + 12;
    float nx = ((float)x + view[23]) * view[21], ny = ((float)y + view[24]) * view[22];
    float cw = h[6] * nx + h[7] * ny + h[8];
    float cx = (h[0] * nx + h[1] * ny + h[2]) / cw, cy = (h[3] * nx + h[4] * ny + h[5]) / cw;
    float d[3], l = 0;
    for (int i = 0; i < 3; i++) {
        d[i] = m[i * 3] * cx + m[i * 3 + 1] * cy + m[i * 3 + 2];
        l += d[i] * d[i];
    }
    for (int i = 0; i < 3; i++)
        out[i] = d[i] / sqrtf(l);
}

/* The error message of resolving `info`'s camera ("" when it resolves),
 * with the option `opt` set to `val` when not NULL. */
static int resolve_msg(const fp_frame_info_t *info, const char *opt, const char *val,
                       fp_camera_t *c, char *msg, size_t n)
{
    fp_params_t p;
    fp_options_defaults(&p);
    if (opt)
        assert_int_equal(fp_options_apply(&p, opt, val, "test"), FP_OK);
    fp_msgbuf_t buf;
    memset(&buf, 0, sizeof buf);
    fp_msgbuf_t *prev = fp_msg_capture(&buf);
    int rc = fp_camera_resolve(&p, info, "t.exr", 4, c);
    fp_msg_capture(prev);
    snprintf(msg, n, "%.*s", (int)buf.len, buf.text ? buf.text : "");
    fp_msg_free(&buf);
    fp_options_free(&p);
    return rc;
}

/* worldToCamera and worldToNDC scaled by any nonzero factor (1e300,
 * 1e-300, -1) are the same projective camera: the same position, the same
 * rays in double, and in the kernels' single precision finite and the
 * same rays (before, 1e300 made the packed view inf and the frame NaN). */
static void test_scaled_matrices(void **state)
{
    (void)state;
    const double scales[] = { 1, 1e300, 1e-300, 1e150, 1e-150, -1, -1e-200 };
    const int ns = (int)(sizeof scales / sizeof scales[0]);
    for (int trial = 0; trial < 8; trial++) {
        double C[3] = { 100 * urand() - 50, 20 * urand(), 100 * urand() - 50 };
        double F[3] = { urand() - 0.5, 0.6 * (urand() - 0.5), urand() - 0.5 };
        fp_frame_info_t ref;
        header_camera(C, F, 20 + 80 * urand(), 96, 64, &ref);
        fp_params_t p;
        fp_options_defaults(&p);
        for (int a = 0; a < ns; a++)
            for (int b = 0; b < ns; b++) {
                fp_frame_info_t info = ref;
                for (int i = 0; i < 16; i++) {
                    info.world_to_camera[i] *= scales[a];
                    info.world_to_ndc[i] *= scales[b];
                }
                /* The same matrices as a fogpipe-camera text attribute. */
                fp_frame_info_t text = info;
                text.has_world_to_camera = text.has_world_to_ndc = 0;
                snprintf(text.camera_text_attr, sizeof text.camera_text_attr, "Note");
                int o = snprintf(text.camera_text, sizeof text.camera_text,
                                 "fogpipe-camera 1 worldToCamera");
                for (int i = 0; i < 32; i++)
                    o += snprintf(text.camera_text + o, sizeof text.camera_text - (size_t)o,
                                  "%s %.17g", i == 16 ? " worldToNDC" : "",
                                  i < 16 ? info.world_to_camera[i] : info.world_to_ndc[i - 16]);
                assert_true(o < (int)sizeof text.camera_text);
                const fp_frame_info_t *src[2] = { &info, &text };
                for (int k = 0; k < 2; k++) {
                    fp_camera_t c;
                    fp_view_t v;
                    char msg[600];
                    int rc = resolve_msg(src[k], NULL, NULL, &c, msg, sizeof msg);
                    if (rc != FP_OK)
                        printf("# scales %g, %g (%s): %s", scales[a], scales[b],
                               k ? "text" : "header", msg);
                    assert_int_equal(rc, FP_OK);
                    assert_int_equal(fp_view_setup(&c, &p, src[k], &v), FP_OK);
                    float view[FP_VIEW_FLOATS];
                    fp_view_pack(&v, view);
                    for (int i = 0; i < FP_VIEW_FLOATS; i++)
                        if (i != 25 && !isfinite(view[i])) {   /* 25: --far, inf */
                            printf("# scales %g, %g (%s): view[%d] = %g\n", scales[a],
                                   scales[b], k ? "text" : "header", i, view[i]);
                            fail();
                        }
                    for (int i = 0; i < 3; i++)
                        assert_double_equal(c.origin[i], C[i], 1e-9 * (1 + fabs(C[i])));
                    for (int s = 0; s < 12; s++) {
                        int x = (int)(urand() * 96), y = (int)(urand() * 64);
                        double dir[3], len, fdir[3], cam[4], P[3];
                        fp_view_ray(&v, x, y, 10.0f, dir, &len);
                        float_dir(view, x, y, fdir);
                        for (int i = 0; i < 3; i++) {
                            P[i] = C[i] + dir[i] * len;
                            assert_double_equal(fdir[i], dir[i], 1e-5);
                        }
                        /* Planar depth 10 in the unscaled camera. */
                        xform(ref.world_to_camera, P, cam);
                        assert_double_equal(cam[2], 10, 1e-8);
                    }
                }
            }
        fp_options_free(&p);
    }
}

/* Matrices that are no projection: refused with their name. */
static void test_degenerate_matrices(void **state)
{
    (void)state;
    static const double C[3] = { 1, 2, 3 }, F[3] = { 0, 0, 1 };
    struct {
        int which;   /* 0: worldToCamera, 1: worldToNDC */
        int kind;
        const char *want;
    } cases[] = {
        { 0, 0, "worldToCamera has a non-finite element" },
        { 1, 0, "worldToNDC has a non-finite element" },
        { 0, 1, "worldToCamera has a non-finite element" },
        { 0, 2, "worldToCamera is all zeros" },
        { 1, 2, "worldToNDC is all zeros" },
        { 0, 3, "worldToCamera is not invertible" },
        { 1, 3, "worldToNDC is not a usable projection" },
        { 0, 4, "worldToCamera is not invertible" },
        { 0, 6, "camera position/orientation from options is beyond single precision" },
        { 0, 5, "worldToCamera puts the camera at infinity" },
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        fp_frame_info_t info;
        header_camera(C, F, 40, 32, 24, &info);
        double *m = cases[k].which ? info.world_to_ndc : info.world_to_camera;
        switch (cases[k].kind) {
        case 0: m[5] = NAN; break;
        case 1: m[12] = INFINITY; break;
        case 2: memset(m, 0, 16 * sizeof *m); break;
        case 3:   /* rank 2: the second column a copy of the first */
            for (int r = 0; r < 4; r++)
                m[r * 4 + 1] = m[r * 4];
            break;
        case 4:   /* camera space 1e-300 of the world's, w = 1: not a projective scale */
            for (int i = 0; i < 12; i++)
                m[i] *= 1e-300;
            break;
        case 5: {   /* invertible, the camera's point at infinity (z and w swapped) */
            const double swap[16] = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0 };
            memcpy(m, swap, sizeof swap);
            break;
        }
        case 6:   /* a position that single precision does not hold */
            break;
        }
        fp_camera_t c;
        char msg[600];
        int far = cases[k].kind == 6;
        assert_int_not_equal(resolve_msg(&info, far ? "camera-pos" : NULL, "1e35,0,0", &c, msg,
                                         sizeof msg), FP_OK);
        printf("# %s", msg);
        assert_non_null(strstr(msg, "t.exr: frame 4: "));
        assert_non_null(strstr(msg, cases[k].want));
    }
}

/* A .chan line has exactly the 8 columns 'frame tx ty tz rx ry rz vfov':
 * more or fewer, or a column that is not all number, is refused with the
 * file and line (extra columns used to be ignored). */
static void test_chan_columns(void **state)
{
    (void)state;
    const char *good = "1 0 1 5 0 0 0 40\n";
    struct {
        const char *line2, *want;
    } bad[] = {
        { "2 0 1 5 0 0 0 40 7\n", ":2: 9 columns (expected 8: 'frame tx ty tz rx ry rz vfov')" },
        { "2 0 1 5 0 0 0 40 0 0 0 0\n", ":2: 12 columns (expected 8" },
        { "2 0 1 5 0 0 0\n", ":2: 7 columns (expected 8" },
        { "2 0 1 5 0 0 0 40 # a note\n", ":2: column 9 '#' is not a number" },
        { "2 0 1 5 0 0 0 40abc\n", ":2: column 8 '40abc' is not a number" },
        { "2 0 1 5 0 0,5 0 40\n", ":2: column 6 '0,5' is not a number" },
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        char text[256];
        snprintf(text, sizeof text, "%s%s", good, bad[k].line2);
        fp_msgbuf_t buf;
        memset(&buf, 0, sizeof buf);
        fp_msgbuf_t *prev = fp_msg_capture(&buf);
        fp_camera_t c;
        int rc = chan_camera(text, NULL, 0, 40, 30, 1, &c);
        fp_msg_capture(prev);
        char msg[600];
        snprintf(msg, sizeof msg, "%.*s", (int)buf.len, buf.text ? buf.text : "");
        fp_msg_free(&buf);
        printf("# %s", msg);
        assert_int_not_equal(rc, FP_OK);
        assert_non_null(strstr(msg, "fogpipe: /tmp/fp-chan-"));
        assert_non_null(strstr(msg, bad[k].want));
    }
    /* Tabs, blanks around, CRLF and exponents are fine. */
    fp_camera_t c;
    assert_int_equal(chan_camera("  1\t0 1 5 0 0 0 4e1  \r\n2 0 1 5 0 0 0 40\n", NULL, 0, 40, 30,
                                 1, &c), FP_OK);
    assert_double_equal(c.origin[2], 5, 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_header_rays),
        cmocka_unit_test(test_overrides),
        cmocka_unit_test(test_chan_and_errors),
        cmocka_unit_test(test_chan_orders_and_up),
        cmocka_unit_test(test_chan_blender_sensor),
        cmocka_unit_test(test_chan_range),
        cmocka_unit_test(test_camera_text),
        cmocka_unit_test(test_chan_lens_warning),
        cmocka_unit_test(test_sky),
        cmocka_unit_test(test_scaled_matrices),
        cmocka_unit_test(test_degenerate_matrices),
        cmocka_unit_test(test_chan_columns),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
