/* fogpipe: single scattering along one view ray, deterministic, shared by
 * the OpenCL kernel (kernels/scatter.cl, float) and the C reference
 * (filters/scatter.c, double).  Include after fog_core.h and light_core.h.
 *
 * Transmittance tau(O,P) is the exact optical depth of fog_core.h.  The
 * in-scattered light
 *   S = albedo int tau(O,u) sigma_t(u) J(u) du,
 *   J = L_amb + E_sun p(mu_sun) V(u) tau_sun(u)            (+ local lights)
 * is integrated over N segments of the ray's stretch through the fog:
 * each segment's optical depth x is exact (fp_fog_od over the segment) and
 * J is taken linear between the segment's ends, which integrates in closed
 * form against the segment's attenuation:
 *   int_seg = tau_a [ J_a (1 - e^-x) + (J_b - J_a) ((1 - e^-x)/x - e^-x) ].
 * The ambient term (J constant) is therefore exact: S_amb = albedo (1 -
 * tau) L_amb, seed 000's eq. 4.  Local lights are integrated separately,
 * with Gauss-Legendre nodes placed equiangularly as seen from the light
 * (t = t_c + D tan(theta)), which turns the 1/d^2 peak into a constant
 * (dt / d^2 = dtheta / D): halos stay clean at high g. */
#ifndef FP_SCATTER_CORE_H
#define FP_SCATTER_CORE_H

#define FP_SCATTER_MAX_STEPS_ 256

/* Where along o + t dir, t in [0, len], fog can be: the main fog's box and
 * top (and the fogmap's rectangle when it does not wrap), joined with the
 * haze's stretch.  Returns 0 when nowhere. */
FP_FN int fp_fog_span(FP_CONSTANT const fp_real *fp, fp_real ox, fp_real oy, fp_real oz,
                      fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real *ta, fp_real *tb)
{
    fp_real a, b, lo = FP_INF, hi = -FP_INF;
    if (fp_main_span(fp, ox, oy, oz, dx, dy, dz, len, &a, &b)) {
        lo = a;
        hi = b;
    }
    if (fp_haze_span(fp, oy, dy, len, &a, &b)) {
        lo = fmin(lo, a);
        hi = fmax(hi, b);
    }
    *ta = lo;
    *tb = hi;
    return hi > lo;
}

/* J at a point: sun (phase value `ph_sun` for this ray) and ambient. */
FP_FN void fp_scatter_source(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                             FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                             FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                             FP_GLOBAL const float *smap, FP_GLOBAL const float *grid,
                             FP_CONSTANT const float *view, FP_GLOBAL const float *depth,
                             int width, int height, fp_real ph_sun, fp_real x, fp_real y,
                             fp_real z, fp_real *J)
{
    J[0] = lt[FP_LT_AMB];
    J[1] = lt[FP_LT_AMB + 1];
    J[2] = lt[FP_LT_AMB + 2];
    if (lt[FP_LT_SUN_ON] == 0 || ph_sun <= 0)
        return;
    fp_real v = fp_sun_visibility(lt, smap, view, depth, width, height, x, y, z);
    if (v <= 0)
        return;
    v *= ph_sun * fp_sun_tau(fp, lvi, lvf, coef, occ, lt, grid, x, y, z);
    J[0] += v * lt[FP_LT_SUN_E];
    J[1] += v * lt[FP_LT_SUN_E + 1];
    J[2] += v * lt[FP_LT_SUN_E + 2];
}

/* The fog layer of one view ray: S (3) and returns tau. */
FP_FN fp_real fp_scatter_ray_core(FP_CONSTANT const fp_real *fp, FP_CONSTANT const int *lvi,
                             FP_CONSTANT const fp_real *lvf, FP_GLOBAL const float *coef,
                             FP_GLOBAL const unsigned char *occ, FP_CONSTANT const fp_real *lt,
                             FP_GLOBAL const float *smap, FP_GLOBAL const float *grid,
                             FP_CONSTANT const float *view, FP_GLOBAL const float *depth,
                             int width, int height, fp_real ox, fp_real oy, fp_real oz,
                             fp_real dx, fp_real dy, fp_real dz, fp_real len, fp_real offset,
                             fp_real *S)
{
    S[0] = S[1] = S[2] = 0;
    fp_real od_total = fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, len, 0);
    fp_real tau = exp(-od_total);
    fp_real ta, tb;
    if (!(od_total > 0) || !fp_fog_span(fp, ox, oy, oz, dx, dy, dz, len, &ta, &tb))
        return tau;
    fp_real albedo = lt[FP_LT_ALBEDO];
    if (lt[FP_LT_SUN_ON] == 0 && lt[FP_LT_NLIGHTS] == 0) {
        /* Ambient light alone: the closed form (seed 000 eq. 4). */
        for (int c = 0; c < 3; c++)
            S[c] = albedo * -expm1(-od_total) * lt[FP_LT_AMB + c];
        return tau;
    }
    fp_real od_stop = lt[FP_LT_OD_STOP];
    {
        /* Go only as far as the fog still matters: until its optical depth
         * from ta passes od_stop, or nearly all of it is behind (a sky
         * ray, or geometry far beyond the fog), found by doubling. */
        fp_real span = tb - ta;
        fp_real step = fmax((fp_real)1 / fmax(fp[FP_F_SIGMA] + fp[FP_F_HAZE], (fp_real)1e-12),
                            (fp_real)1e-3);
        if (step < span) {
            fp_real od_before = fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, ta, 0);
            for (int k = 0; k < 80 && step < span && step < fp[FP_F_CAP]; k++) {
                fp_real od =
                    fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, ta + step, 0);
                if (od - od_before >= od_stop ||
                    (isfinite(od_total) && od_total - od <= (fp_real)1e-4 * od_total))
                    break;
                step *= 2;
            }
            tb = ta + fmin(fmin(step, fp[FP_F_CAP]), span);
        }
    }
    FP_CONSTANT const fp_real *ph = lt + FP_LT_PHASE;
    FP_CONSTANT const fp_real *l = lt + FP_LT_SUN_DIR;
    int kind = (int)ph[0];
    fp_real ph_sun = fp_phase(kind, ph[1], ph[2], dx * l[0] + dy * l[1] + dz * l[2]);
    int n = (int)lt[FP_LT_STEPS];
    n = n < 1 ? 1 : n > FP_SCATTER_MAX_STEPS_ / 2 ? FP_SCATTER_MAX_STEPS_ / 2 : n;
    /* Interleaved sampling: the first segment is `offset` of one long,
     * which shifts every later end along the ray. */
    fp_real h0 = (tb - ta) / n, xmax = lt[FP_LT_SEG_OD];
    fp_real h = offset > 0 ? offset * h0 : h0;
    /* Segment ends and the optical depth from the camera there (for the
     * lights).  Segments are at most (tb - ta) / n long and hold at most
     * xmax of optical depth (halved until they do, down to h0 / 256), so
     * dense fog gets more of them; MAX_STEPS bounds the count. */
    fp_real segt[FP_SCATTER_MAX_STEPS_ + 1], odc[FP_SCATTER_MAX_STEPS_ + 1];
    fp_real Ja[3], Jb[3];
    fp_real od = ta > 0 ? fp_fog_od(fp, lvi, lvf, coef, occ, ox, oy, oz, dx, dy, dz, ta, 0) : 0;
    fp_scatter_source(fp, lvi, lvf, coef, occ, lt, smap, grid, view, depth, width, height, ph_sun,
                      ox + ta * dx, oy + ta * dy, oz + ta * dz, Ja);
    segt[0] = ta;
    odc[0] = od;
    int last = 0;
    fp_real t0 = ta;
    for (int guard = 0; t0 < tb && last < FP_SCATTER_MAX_STEPS_ && guard < 4 * FP_SCATTER_MAX_STEPS_;
         guard++) {
        int final_seg = last + 1 == FP_SCATTER_MAX_STEPS_;
        fp_real hs = final_seg ? tb - t0 : fmin(h, tb - t0);
        fp_real t1 = hs >= tb - t0 ? tb : t0 + hs;
        fp_real x = fp_fog_od(fp, lvi, lvf, coef, occ, ox + t0 * dx, oy + t0 * dy, oz + t0 * dz,
                              dx, dy, dz, t1 - t0, 0);
        if (x > xmax && !final_seg && hs > h0 * (fp_real)(1.0 / 256)) {
            h = hs * fmax((fp_real)0.8 * xmax / x, (fp_real)0.1);
            continue;
        }
        fp_scatter_source(fp, lvi, lvf, coef, occ, lt, smap, grid, view, depth, width, height,
                          ph_sun, ox + t1 * dx, oy + t1 * dy, oz + t1 * dz, Jb);
        fp_real e = exp(-x), ta_w = exp(-od) * albedo;
        fp_real c0 = -expm1(-x), c1 = x > 0 ? fp_expm1_ratio(x) - e : 0;
        /* The light changes fast here (a shadow's edge): halve the segment
         * while the change, weighted by what the segment adds to the pixel,
         * is above FP_LT_SEG_JUMP of the light. */
        fp_real jump = 0, jscale = (fp_real)1e-12;
        for (int c = 0; c < 3; c++) {
            jump = fmax(jump, fabs(Jb[c] - Ja[c]));
            jscale = fmax(jscale, (fp_real)0.5 * (Ja[c] + Jb[c]));
        }
        if (jump * c0 * exp(-od) > lt[FP_LT_SEG_JUMP] * jscale && !final_seg &&
            hs > h0 * (fp_real)(1.0 / 256)) {
            h = (fp_real)0.5 * hs;
            continue;
        }
        for (int c = 0; c < 3; c++) {
            S[c] += ta_w * (Ja[c] * c0 + (Jb[c] - Ja[c]) * c1);
            Ja[c] = Jb[c];
        }
        od += x;
        t0 = t1;
        last++;
        segt[last] = t1;
        odc[last] = od;
        if (od > od_stop)
            break;
        if (x < (fp_real)0.25 * xmax && jump * c0 < (fp_real)0.25 * lt[FP_LT_SEG_JUMP] * jscale)
            h = fmin(2 * h, h0);
    }
    /* Beyond tb (an unbounded ray stops with 1e-4 of its optical depth
     * left): that fog with the light of the last point. */
    for (int c = 0; c < 3; c++)
        S[c] += albedo * Ja[c] * fmax(exp(-od) - tau, (fp_real)0);
    /* Local lights over [ta, t_last]. */
    int nl = (int)lt[FP_LT_NLIGHTS];
    fp_real tl = segt[last];
    int panels = (int)lt[FP_LT_PANELS];
    for (int k = 0; k < nl; k++) {
        FP_CONSTANT const fp_real *row = lt + FP_LT_LIGHTS + k * FP_LT_LIGHT_STRIDE;
        fp_real qx = row[FP_LL_POS] - ox, qy = row[FP_LL_POS + 1] - oy, qz = row[FP_LL_POS + 2] - oz;
        fp_real tc = qx * dx + qy * dy + qz * dz;
        fp_real rx = qx - tc * dx, ry = qy - tc * dy, rz = qz - tc * dz;
        fp_real D = fmax(sqrt(rx * rx + ry * ry + rz * rz), (fp_real)1e-6 * (1 + fabs(tc)));
        fp_real th0 = atan2(ta - tc, D), th1 = atan2(tl - tc, D);
        /* The phase function's peak (mu = -sin(theta) -> 1 for g > 0, at
         * theta = -pi/2; mirrored for g < 0) is about 1 - |g| wide in
         * theta: with e the angle from the peak, panels grow
         * geometrically away from it, starting at (1 - |g|) / 4. */
        fp_real g = ph[1];
        int peaked = (kind == FP_PHASE_HG || kind == FP_PHASE_CS || kind == FP_PHASE_MIX ||
                      kind == FP_PHASE_MIXHG) && fabs(g) > (fp_real)0.2;
        fp_real sgn = g < 0 ? (fp_real)-1 : (fp_real)1, hp = (fp_real)1.5707963267948966;
        fp_real ea = hp + sgn * (sgn > 0 ? th0 : th1), eb = hp + sgn * (sgn > 0 ? th1 : th0);
        fp_real es = fmax(ea, (fp_real)0.25 * (1 - fabs(g)));
        int geo = peaked && panels > 1 && es < eb && ea >= 0;
        int first = geo && ea < es;   /* a uniform panel before the geometric ones */
        fp_real ratio = geo ? pow(eb / es, (fp_real)1 / (panels - first)) : 1;
        fp_real acc = 0;
        for (int q = 0; q < panels; q++) {
            fp_real pa, pb;
            if (!geo) {
                pa = ea + (eb - ea) * q / panels;
                pb = ea + (eb - ea) * (q + 1) / panels;
            } else if (first && q == 0) {
                pa = ea;
                pb = es;
            } else {
                pa = es * pow(ratio, (fp_real)(q - first));
                pb = q + 1 == panels ? eb : es * pow(ratio, (fp_real)(q + 1 - first));
            }
            for (int gq = 0; gq < 4; gq++) {
                fp_real e = pa + (pb - pa) * fp_gl_x[FP_GL_FIRST(4) + gq];
                fp_real th = sgn * (e - hp);
                fp_real t = tc + D * tan(th);
                fp_real px = ox + t * dx, py = oy + t * dy, pz = oz + t * dz;
                fp_real sig = fp_sigma_t(fp, lvi, lvf, coef, px, py, pz);
                if (sig <= 0)
                    continue;
                fp_real vx = row[FP_LL_POS] - px, vy = row[FP_LL_POS + 1] - py,
                        vz = row[FP_LL_POS + 2] - pz;
                fp_real r = sqrt(vx * vx + vy * vy + vz * vz);
                vx /= r;
                vy /= r;
                vz /= r;
                fp_real cone = fp_light_cone(row, -vx, -vy, -vz);
                if (cone <= 0)
                    continue;
                /* Camera-side optical depth: linear between segment ends. */
                int lo = 0, hi = last;
                while (hi - lo > 1) {
                    int mid = (lo + hi) / 2;
                    if (segt[mid] <= t)
                        lo = mid;
                    else
                        hi = mid;
                }
                fp_real f = fmin(fmax((t - segt[lo]) / fmax(segt[hi] - segt[lo], (fp_real)1e-30),
                                      (fp_real)0), (fp_real)1);
                fp_real odt = odc[lo] + f * (odc[hi] - odc[lo]);
                fp_real odl = fp_fog_od(fp, lvi, lvf, coef, occ, px, py, pz, vx, vy, vz, r, 0);
                acc += fp_gl_w[FP_GL_FIRST(4) + gq] * (pb - pa) * sig * exp(-odt - odl) * cone *
                       fp_phase(kind, ph[1], ph[2], vx * dx + vy * dy + vz * dz);
            }
        }
        acc *= albedo / D;
        for (int c = 0; c < 3; c++)
            S[c] += acc * row[FP_LL_I + c];
    }
    return tau;
}

#endif
