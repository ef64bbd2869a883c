/* fogpipe: the optical depths of the fast rule's nodes (fp_ln_fast in
 * scatter_lanes.h) in fog without a box (every bound of the main fog's box
 * infinite), from the heights of their ends.  Include from scatter_lanes.h.
 *
 * A height profile sigma h(y) (h = 1 below y0, exp(-(y - y0)/H) up to
 * top, 0 above) has along a straight stretch of direction dy (per unit
 * length) the optical depth sigma (below + above): `below` the length
 * under min(y0, top), `above` the integral of h over the length w in
 * [y0, top].  fp_light_height_od (scatter_core.h) takes `above` as
 *   w h_lo (1 - e^-x) / x,   x = |dy| w / H,
 * h_lo the larger h of the band's part of the stretch: two exponentials
 * per stretch.  Since dh/dt = -h dy / H along the stretch, the same
 * integral is (h_a - h_b) H / |dy| with h_a, h_b the h at its ends (both
 * clamped to [h(top), 1], where the stretch enters and leaves the band),
 * and a node has those: the camera's h and the light's are the same for
 * every node of a ray, and the node's own h is the one its extinction
 * needs anyway.  So a node costs one exponential for its h and one for
 * its transmittance, where fp_ln_plain_sigma and two fp_ln_plain_od cost
 * five (seven with haze), and one division (toward the light) where they
 * cost about ten.  For x < 1/8 the difference would cancel, so there the
 * series of (1 - e^-x) / x is taken (its first term left out, x^7 / 8!,
 * under 2e-11 relative), with h_lo the larger of h_a, h_b.  In float
 * the difference at x = 1/8 holds its h's rounding over 1 - e^-x
 * (about 1e-6 of the stretch's optical depth), as 1 - exp(-x) does in
 * fp_ln_one_minus_exp at its switch.  tests/test_lightfast.c compares
 * the lanes (with these in double) to fp_light_ray at 1e-9 of S. */
#ifndef FP_LIGHT_BAND_LANES_H
#define FP_LIGHT_BAND_LANES_H

/* min and max of the nodes' lanes as selects: one vminps / vmaxps on the
 * CPU device, where fmin and fmax (IEEE minNum: a NaN loses) take three
 * instructions each; no NaN reaches them on a node that is kept (t and r
 * finite, H > 0). */
FP_LN_FN fp_lnr fp_ln_lo(fp_lnr a, fp_lnr b)
{
    return a < b ? a : b;
}

FP_LN_FN fp_lnr fp_ln_hi(fp_lnr a, fp_lnr b)
{
    return a > b ? a : b;
}

/* (1 - e^-x) / x for 0 <= x < 1/8. */
FP_LN_FN fp_lnr fp_ln_ratio_series(fp_lnr x)
{
    return 1 - x * ((fp_real)1 / 2 -
                    x * ((fp_real)1 / 6 -
                         x * ((fp_real)1 / 24 -
                              x * ((fp_real)1 / 120 -
                                   x * ((fp_real)1 / 720 - x * ((fp_real)1 / 5040))))));
}

/* One height profile (the main fog's in its frame, or the haze's) as the
 * lanes' view rays and one light see it. */
typedef struct fp_ln_band_t {
    fp_real sigma, y0, top, lo, inv_h, H, h_top;
    fp_real h_light;            /* h at the light, clamped to [h_top, 1] */
    fp_lnr bl_a, bl_b;          /* the view ray below lo: [bl_a, min(bl_b, t)] */
    fp_lnr a2, e2;              /* ... in the band: [a2, min(e2, t)] */
    fp_lnr h_cam, ady, k_cam;   /* h at the ray's origin (clamped), |dy|, H / |dy| */
} fp_ln_band_t;

/* h(y) unclamped: exp(-(y - y0) / H) (1 or more below y0). */
FP_LN_FN fp_lnr fp_ln_band_h(const fp_ln_band_t *b, fp_lnr y)
{
    return exp((b->y0 - y) * b->inv_h);
}

/* h clamped to the band's ends: h at the nearest height in [y0, top]. */
FP_LN_FN fp_lnr fp_ln_band_clamp(const fp_ln_band_t *b, fp_lnr h)
{
    return fp_ln_lo(fp_ln_hi(h, FP_LN(b->h_top)), FP_LN(1));
}

/* The profile (sigma > 0) for view rays from height oy (its frame) along
 * dy, and a light at height yl. */
FP_LN_FN void fp_ln_band_init(fp_ln_band_t *b, fp_real sigma, fp_real y0, fp_real H, fp_real top,
                              fp_lnr oy, fp_lnr dy, fp_real yl)
{
    b->sigma = sigma;
    b->y0 = y0;
    b->top = top;
    b->lo = fmin(y0, top);
    b->H = H;
    b->inv_h = 1 / H;
    b->h_top = isinf(top) ? (fp_real)0 : exp(-(top - y0) / H);
    b->h_light = fmin(fmax(exp((y0 - yl) * b->inv_h), b->h_top), (fp_real)1);
    fp_lnr ddy = fabs(dy) > (fp_real)1e-30 ? dy : FP_LN((fp_real)1e-30);
    fp_lnr inv = 1 / ddy;
    fp_lnr u = (b->lo - oy) * inv;
    b->bl_a = ddy > 0 ? FP_LN(0) : fmax(u, (fp_real)0);
    b->bl_b = ddy > 0 ? u : FP_LN(FP_INF);
    fp_lnr u0 = (y0 - oy) * inv, u1 = (top - oy) * inv;
    b->a2 = fmax(fmin(u0, u1), (fp_real)0);
    b->e2 = fmax(u0, u1);
    b->h_cam = fp_ln_band_clamp(b, fp_ln_band_h(b, oy));
    b->ady = fabs(dy);
    b->k_cam = H * fabs(inv);
}

/* The integral of h over a stretch of length w in the band, |dy| its
 * slope, k = H / |dy|, ha and hb (clamped) at its ends. */
FP_LN_FN fp_lnr fp_ln_band_above(fp_lnr w, fp_lnr ady, fp_real inv_h, fp_lnr k, fp_lnr ha,
                                 fp_lnr hb)
{
    fp_lnr x = ady * w * inv_h;
    fp_lnr near = w * fp_ln_hi(ha, hb) * fp_ln_ratio_series(x);
    fp_lnr far = fabs(ha - hb) * k;
    return x < (fp_real)0.125 ? near : far;
}

/* Optical depth along the view ray from its origin to t, ht the clamped
 * h there. */
FP_LN_FN fp_lnr fp_ln_band_cam(const fp_ln_band_t *b, fp_lnr t, fp_lnr ht)
{
    fp_lnr below = fp_ln_hi(fp_ln_lo(b->bl_b, t) - b->bl_a, FP_LN(0));
    fp_lnr w = fp_ln_hi(fp_ln_lo(b->e2, t) - b->a2, FP_LN(0));
    return b->sigma * (below + fp_ln_band_above(w, b->ady, b->inv_h, b->k_cam, b->h_cam, ht));
}

/* Optical depth from height py (h clamped hp) along dy (inv = 1 / dy, dy
 * kept off 0 as fp_light_height_od does) over length r: to the light. */
FP_LN_FN fp_lnr fp_ln_band_light(const fp_ln_band_t *b, fp_lnr py, fp_lnr dy, fp_lnr inv,
                                 fp_lnr r, fp_lnr hp)
{
    fp_lni up = dy > 0;
    fp_lnr u = (b->lo - py) * inv;
    fp_lnr a1 = up ? FP_LN(0) : fp_ln_hi(u, FP_LN(0));
    fp_lnr b1 = up ? fp_ln_lo(u, r) : r;
    fp_lnr below = fp_ln_hi(b1 - a1, FP_LN(0));
    fp_lnr u0 = (b->y0 - py) * inv, u1 = (b->top - py) * inv;
    fp_lnr w = fp_ln_hi(fp_ln_lo(fp_ln_hi(u0, u1), r) - fp_ln_hi(fp_ln_lo(u0, u1), FP_LN(0)),
                        FP_LN(0));
    return b->sigma * (below + fp_ln_band_above(w, fabs(dy), b->inv_h, b->H * fabs(inv), hp,
                                                b->h_light));
}

/* A node at t of the view ray, at height py (the main fog's frame) and
 * y (the world's), u_y the y of the unit vector from the light to it, r
 * its distance to the light: its extinction (*sig) and the optical depth
 * from the camera to it and from it to the light (*od).  main_on and
 * haze_on: whether each profile has fog (sigma > 0). */
FP_LN_FN void fp_ln_band_node(const fp_ln_band_t *m, int main_on, const fp_ln_band_t *hz,
                              int haze_on, fp_lnr t, fp_lnr py, fp_lnr y, fp_lnr uy, fp_lnr r,
                              fp_lnr *sig, fp_lnr *od)
{
    /* Toward the light: dy = -u_y. */
    fp_lnr dyl = -uy;
    fp_lnr ddy = fabs(dyl) > (fp_real)1e-30 ? dyl : FP_LN((fp_real)1e-30);
    fp_lnr inv = 1 / ddy;
    fp_lnr s = FP_LN(0), o = FP_LN(0);
    if (main_on) {
        fp_lnr e = fp_ln_band_h(m, py), h = fp_ln_band_clamp(m, e);
        s = py < m->top ? m->sigma * fp_ln_lo(e, FP_LN(1)) : FP_LN(0);
        o = fp_ln_band_cam(m, t, h) + fp_ln_band_light(m, py, ddy, inv, r, h);
    }
    if (haze_on) {
        fp_lnr e = fp_ln_band_h(hz, y), h = fp_ln_band_clamp(hz, e);
        s += y < hz->top ? hz->sigma * fp_ln_lo(e, FP_LN(1)) : FP_LN(0);
        o += fp_ln_band_cam(hz, t, h) + fp_ln_band_light(hz, y, ddy, inv, r, h);
    }
    *sig = s;
    *od = o;
}

#endif
