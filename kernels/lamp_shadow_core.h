/* fogpipe: local lights (point, spot, area) shadowed by what the camera's
 * depth buffer shows (--lamp-shadows screen), the sun's screen-space rule
 * (light_core.h fp_ss_walk_dir) walked toward a lamp at a finite
 * distance.  Compiled as OpenCL C (float) and as C (double).  Include
 * after light_core.h; scatter_core.h includes it after fp_light_ray for
 * the fast rule's correction (fp_ls_fix).
 *
 * A point P is in the lamp's shadow when its segment to the lamp's center
 * passes through what a depth-buffer pixel shows, taken as a cell THICK
 * deep behind the pixel's camera z (--screen-shadow's THICK, the sun's
 * rule).  For the view ray o + t d, the segments from its points to the
 * lamp Q are X(a, c) = Q + a d + c (o - Q) with a = c t, c in [0, 1] (c
 * the share of the way from the lamp): the triangle (0, 0), (t0, 1),
 * (t1, 1) of one plane through the camera, which projects onto one line
 * on screen, from the ray's pixel toward the lamp's (away from it when
 * the lamp is behind the camera).  Each cell's conditions are linear in
 * (a, c) (fp_ss_cells' clipping), so what the cell shadows is a convex
 * polygon; the t of its points is the central projection t = a / c from
 * the apex, an interval between two of its vertices.  The lamp is the
 * origin so that the vertices near it, where that projection divides by
 * a small c, keep their relative precision in single precision.  The walk over the pixels of that line (the depth
 * buffer's min-max pyramid, as the sun's) gives the ray's shadowed t
 * exactly, as sorted intervals; a cell that holds the lamp shadows all.
 * What is outside the frame casts nothing (the limit of screen space). */
#ifndef FP_LAMP_SHADOW_GEOM_H
#define FP_LAMP_SHADOW_GEOM_H

/* The depth pyramid the lamps' walk reads: FP_LT_LS_ZOFF floats into the
 * shadow-map buffer (after the sun's map when there is one). */
FP_FN FP_GLOBAL const float *fp_ls_zpyr(FP_CONSTANT const fp_real *lt, FP_GLOBAL const float *smap)
{
    return smap + (int)lt[FP_LT_LS_ZOFF];
}

/* The t-interval of the triangle's part that pixels [i0, i1) x [j0, j1)
 * with camera z in (zlo, zhi) hold (nt, ns, nc: the NDC rows of D, W =
 * o - Q, C0 = Q as fp_ss_cells'); for a point (t0 = t1 = 0, D = 0) its
 * c-interval.  Returns 0 when none. */
FP_FN int fp_ls_cells(FP_CONSTANT const fp_real *ndc, const fp_real *nt, const fp_real *ns,
                      const fp_real *nc, const fp_real *D, const fp_real *W, const fp_real *C0,
                      int i0, int i1, int j0, int j1, fp_real zlo, fp_real zhi, fp_real t0,
                      fp_real t1, int point, fp_real *ia, fp_real *ib)
{
    fp_real pt[16] = { t0, t1, 0 }, ps[16] = { 1, 1, 0 };
    int n = 3;
    n = fp_ss_clip_block(ndc, nt, ns, nc, D, W, C0, i0, i1, j0, j1, zlo, zhi, pt, ps, n);
    if (n < 3)
        return 0;
    fp_real lo = FP_INF, hi = -FP_INF;
    int apex = 0;
    for (int k = 0; k < n; k++) {
        apex |= ps[k] <= (fp_real)1e-6;
        fp_real v = point ? ps[k] : pt[k] / fmax(ps[k], (fp_real)1e-30);
        lo = fmin(lo, v);
        hi = fmax(hi, v);
    }
    /* The lamp itself in the cell: every segment ends there. */
    if (apex && !point) {
        lo = t0;
        hi = t1;
    }
    *ia = point ? lo : fmax(lo, t0);
    *ib = point ? hi : fmin(hi, t1);
    return *ib > *ia;
}

/* The shadowed t of the segments from o + t d, t in [t0, t1] (finite),
 * to the lamp at q (fog space) into iv (sorted, disjoint), their count
 * returned; (ax, ay) the ray's pixel in the depth buffer's units
 * (fp_ss_pixel).  A point (d = 0, t0 = t1 = 0) stops at its first shadow. */
FP_FN int fp_ls_walk(FP_CONSTANT const fp_real *lt, fp_real qx, fp_real qy, fp_real qz,
                     FP_CONSTANT const float *view, FP_GLOBAL const float *zpyr, fp_real ox,
                     fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real t0,
                     fp_real t1, fp_real ax, fp_real ay, int point, fp_real *iv)
{
    FP_CONSTANT const fp_real *m = lt + FP_LT_SS_M, *h = lt + FP_LT_SS_H;
    int ortho = view[FP_VIEW_ORTHO] != 0;
    fp_real thick = lt[FP_LT_SS_THICK];
    fp_real q[3] = { qx - view[0], qy - view[1], qz - view[2] };
    fp_real w[3] = { ox - qx, oy - qy, oz - qz };
    fp_real D[3], W[3], C0[3], nt[3], ns[3], nc[3];
    for (int k = 0; k < 3; k++) {
        D[k] = m[3 * k] * dx + m[3 * k + 1] * dy + m[3 * k + 2] * dz;
        W[k] = m[3 * k] * w[0] + m[3 * k + 1] * w[1] + m[3 * k + 2] * w[2];
        C0[k] = m[3 * k] * q[0] + m[3 * k + 1] * q[1] + m[3 * k + 2] * q[2];
    }
    fp_ss_ndc(h, D, ortho, 0, nt);
    fp_ss_ndc(h, W, ortho, 0, ns);
    fp_ss_ndc(h, C0, ortho, 1, nc);
    /* The lamp's pixel, homogeneous (w: its camera side): the line on
     * screen runs toward it when w > 0, away from it when w < 0. */
    int PW = (int)lt[FP_LT_SS_PW], PH = (int)lt[FP_LT_SS_PH], NL = (int)lt[FP_LT_SS_PLEVELS];
    fp_real lw = nc[2];
    fp_real hx = nc[0] / lt[FP_LT_SS_NDC] + ((fp_real)0.5 - lt[FP_LT_SS_NDC + 2]) * lw;
    fp_real hy = nc[1] / lt[FP_LT_SS_NDC + 1] + ((fp_real)0.5 - lt[FP_LT_SS_NDC + 3]) * lw;
    fp_real ex = hx - ax * lw, ey = hy - ay * lw;
    fp_real el = sqrt(ex * ex + ey * ey);
    if (lw > (fp_real)1e-6 * el) {
        ex /= lw;
        ey /= lw;
    } else if (el > 0) {
        /* Behind the camera (or on its plane): to past the screen's edge. */
        ex *= 4 * (fp_real)(PW + PH) / el;
        ey *= 4 * (fp_real)(PW + PH) / el;
    }
    fp_pyr_walk_t pw;
    if (!fp_pyr_walk_begin(&pw, PW, PH, NL, ax, ay, ex, ey))
        return 0;
    int n = 0;
    for (int guard = 0; guard < 8 * (PW + PH) + 64; guard++) {
        int x0, x1, y0, y1;
        fp_real zlo, zhi, a, b;
        fp_pyr_walk_block(&pw, zpyr, &x0, &x1, &y0, &y1, &zlo, &zhi);
        int hit = zlo < FP_INF && fp_ls_cells(lt + FP_LT_SS_NDC, nt, ns, nc, D, W, C0, x0, x1, y0,
                                              y1, zlo, zhi + thick, t0, t1, point, &a, &b);
        if (hit && pw.lv == 0) {
            n = fp_ss_insert(iv, n, a, b);
            if (point)
                break;
        }
        if (!fp_pyr_walk_next(&pw, hit))
            break;
    }
    return n;
}

/* Far along a view ray a lamp is seen at nearly the same angle (dt / r^2
 * = dtheta / D): beyond FP_LS_REACH times its distance D from the ray past
 * its closest point, the in-scatter left is under 1 / FP_LS_REACH of the
 * angle, and the walk takes it as lit (the walk needs a finite stretch). */
#define FP_LS_REACH 1000

/* The stretches of the view ray o + t d over [ta, tb] (tb may be +inf)
 * in the shadow of local light `row`: sorted, disjoint, into iv; returns
 * their count (0 when lamp shadows are off). */
FP_FN int fp_ls_ray_iv(FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *row,
                       FP_CONSTANT const float *view, FP_GLOBAL const float *smap, fp_real ox,
                       fp_real oy, fp_real oz, fp_real dx, fp_real dy, fp_real dz, fp_real ta,
                       fp_real tb, fp_real *iv)
{
    if (lt[FP_LT_LS_ON] == 0 || !(tb > ta))
        return 0;
    fp_real lx = row[FP_LL_POS], ly = row[FP_LL_POS + 1], lz = row[FP_LL_POS + 2];
    fp_real qx = lx - ox, qy = ly - oy, qz = lz - oz;
    fp_real tc = qx * dx + qy * dy + qz * dz;
    fp_real rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
    fp_real D = sqrt(rx * rx + ry * ry + rz * rz);
    fp_real tw = fmin(tb, fmax(tc, ta) + FP_LS_REACH * fmax(D, (fp_real)1e-3));
    FP_CONSTANT const fp_real *m = lt + FP_LT_SS_M, *h = lt + FP_LT_SS_H;
    /* A lamp beyond the deepest z the depth buffer holds plus THICK: the
     * segments from the points beyond it stay beyond every cell. */
    fp_real reach = lt[FP_LT_SS_ZMAX] + lt[FP_LT_SS_THICK];
    fp_real dzc = m[6] * dx + m[7] * dy + m[8] * dz;
    fp_real czo = m[6] * (ox - view[0]) + m[7] * (oy - view[1]) + m[8] * (oz - view[2]);
    fp_real czl = m[6] * (lx - view[0]) + m[7] * (ly - view[1]) + m[8] * (lz - view[2]);
    if (czl > reach && dzc > 0)
        tw = fmin(tw, fmax((reach - czo) / dzc, ta));
    /* The ray's pixel in the depth buffer: where a point of it projects. */
    fp_real c[3], nn[3], q1[3] = { ox + dx - view[0], oy + dy - view[1], oz + dz - view[2] };
    for (int k = 0; k < 3; k++)
        c[k] = m[3 * k] * q1[0] + m[3 * k + 1] * q1[1] + m[3 * k + 2] * q1[2];
    if (!(c[2] > 0) || !(tw > ta))
        return 0;
    fp_ss_ndc(h, c, view[FP_VIEW_ORTHO] != 0, 1, nn);
    fp_real px = fp_ss_pixel(lt, nn, 0), py = fp_ss_pixel(lt, nn, 1);
    return fp_ls_walk(lt, lx, ly, lz, view, fp_ls_zpyr(lt, smap), ox, oy, oz, dx, dy, dz, ta, tw,
                      px, py, 0, iv);
}

/* Whether t lies in one of the n sorted intervals iv. */
FP_FN int fp_ls_in(const fp_real *iv, int n, fp_real t)
{
    for (int k = 0; k < n; k++)
        if (t >= iv[2 * k] && t <= iv[2 * k + 1])
            return 1;
    return 0;
}

/* Local light `row`'s visibility at a point (1 lit, 0 shadowed), by the
 * same rule (the Monte Carlo reference's next-event estimates). */
FP_FN fp_real fp_ls_visible(FP_CONSTANT const fp_real *lt, FP_GLOBAL const fp_real *row,
                            FP_CONSTANT const float *view, FP_GLOBAL const float *smap, fp_real x,
                            fp_real y, fp_real z)
{
    if (lt[FP_LT_LS_ON] == 0)
        return 1;
    FP_CONSTANT const fp_real *m = lt + FP_LT_SS_M, *h = lt + FP_LT_SS_H;
    fp_real q[3] = { x - view[0], y - view[1], z - view[2] }, c[3], n[3];
    for (int k = 0; k < 3; k++)
        c[k] = m[3 * k] * q[0] + m[3 * k + 1] * q[1] + m[3 * k + 2] * q[2];
    if (!(c[2] > 0))
        return 1;
    fp_ss_ndc(h, c, view[FP_VIEW_ORTHO] != 0, 1, n);
    fp_real px = fp_ss_pixel(lt, n, 0), py = fp_ss_pixel(lt, n, 1);
    if (!(px >= 0 && py >= 0 && px < lt[FP_LT_SS_PW] && py < lt[FP_LT_SS_PH]))
        return 1;
    fp_real iv[2 * FP_SS_MAX_IV];
    return fp_ls_walk(lt, row[FP_LL_POS], row[FP_LL_POS + 1], row[FP_LL_POS + 2], view,
                      fp_ls_zpyr(lt, smap), x, y, z, 0, 0, 0, 0, 0, px, py, 1, iv) > 0
               ? (fp_real)0
               : (fp_real)1;
}

#endif
