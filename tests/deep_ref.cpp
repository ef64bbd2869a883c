// tests/deep_ref: a reference deep compositor for the deep tests, written
// from OpenEXR's "Interpreting OpenEXR Deep Pixels" on OpenEXR's C++
// library (independent of fogpipe's C reader and writer).
//
//   deep_ref flatten IN.exr OUT.exr          tidy (split, merge) and composite
//   deep_ref merge IN.exr Z R G B OUT.exr    an opaque sample (R G B, alpha 1)
//                                            at deep depth Z merged into every
//                                            pixel, then flattened
//   deep_ref union A.exr B.exr OUT.exr       the samples of both (same size)
//                                            merged and flattened
//   deep_ref tidy IN.exr                     exit 1 unless every pixel is
//                                            sorted and non-overlapping; prints
//                                            samples per pixel
//   deep_ref deepen FLAT.exr OUT.exr [glass] a deep render from a flat one: per
//                                            pixel a sample at its Z (the
//                                            sky at infinity);
//                                            with "glass", also a volumetric
//                                            sample of alpha 0.4 over
//                                            [0.5 Z, 0.8 Z] and a point sample
//                                            of alpha 0.3 at 0.3 Z
//   deep_ref diff A.exr B.exr TOL [rel [R.exr]]
//                                            max |A - B| of R, G, B over the
//                                            pixels (rel: over max(1, the
//                                            brightest channel of B, or of
//                                            R: the range of the composite));
//                                            exit 1 above TOL
//
// Flattening: every volumetric sample is split at every other sample's
// Z and ZBack (alpha 1-(1-a)^f, colour in proportion), coincident pieces
// are combined (optical depths add), then composited front to back.
#include <ImfArray.h>
#include <ImfChannelList.h>
#include <ImfDeepFrameBuffer.h>
#include <ImfDeepScanLineInputFile.h>
#include <ImfDeepScanLineOutputFile.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfPartType.h>
#include <ImfFrameBuffer.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

using namespace OPENEXR_IMF_NAMESPACE;

struct Sample {
    double z, zb, a, c[3];
};

struct Deep {
    int w = 0, h = 0, x0 = 0, y0 = 0;
    Header header;
    std::vector<std::vector<Sample>> px;
};

static Deep read_deep(const char *path)
{
    DeepScanLineInputFile in(path);
    Deep d;
    d.header = in.header();
    Imath::Box2i dw = in.header().dataWindow();
    d.x0 = dw.min.x;
    d.y0 = dw.min.y;
    d.w = dw.max.x - dw.min.x + 1;
    d.h = dw.max.y - dw.min.y + 1;
    size_t n = (size_t)d.w * d.h;
    Array2D<unsigned int> counts(d.h, d.w);
    DeepFrameBuffer fb;
    fb.insertSampleCountSlice(Slice(UINT, (char *)(&counts[0][0] - d.x0 - d.y0 * d.w),
                                    sizeof(unsigned int), sizeof(unsigned int) * d.w));
    const char *names[6] = { "R", "G", "B", "A", "Z", "ZBack" };
    std::vector<std::vector<float>> store(6);
    std::vector<std::vector<float *>> ptr(6, std::vector<float *>(n));
    bool has[6];
    for (int c = 0; c < 6; c++) {
        has[c] = in.header().channels().findChannel(names[c]) != nullptr;
        if (has[c])
            fb.insert(names[c], DeepSlice(FLOAT, (char *)(ptr[c].data() - d.x0 - d.y0 * d.w),
                                          sizeof(float *), sizeof(float *) * d.w, sizeof(float)));
    }
    in.setFrameBuffer(fb);
    in.readPixelSampleCounts(dw.min.y, dw.max.y);
    size_t total = 0;
    for (size_t i = 0; i < n; i++)
        total += counts[i / d.w][i % d.w];
    for (int c = 0; c < 6; c++) {
        store[c].resize(total + 1);
        size_t at = 0;
        for (size_t i = 0; i < n; i++) {
            ptr[c][i] = store[c].data() + at;
            at += counts[i / d.w][i % d.w];
        }
    }
    in.readPixels(dw.min.y, dw.max.y);
    d.px.resize(n);
    for (size_t i = 0; i < n; i++) {
        unsigned k = counts[i / d.w][i % d.w];
        for (unsigned s = 0; s < k; s++) {
            Sample q;
            q.c[0] = ptr[0][i][s];
            q.c[1] = ptr[1][i][s];
            q.c[2] = ptr[2][i][s];
            q.a = has[3] ? ptr[3][i][s] : 1.0;
            q.z = ptr[4][i][s];
            q.zb = has[5] ? ptr[5][i][s] : q.z;
            if (q.zb < q.z)
                q.zb = q.z;
            d.px[i].push_back(q);
        }
    }
    return d;
}

// The part of a volumetric sample over the fraction f of its depth range.
static Sample piece(const Sample &s, double f)
{
    Sample p = s;
    if (f >= 1)
        return p;
    if (s.a >= 1) {
        p.a = 1;
    } else if (s.a <= 0) {
        for (double &c : p.c)
            c *= f;
    } else {
        p.a = 1 - std::pow(1 - s.a, f);
        for (double &c : p.c)
            c *= p.a / s.a;
    }
    return p;
}

static void merge_same(Sample &x, const Sample &y)
{
    if (x.a >= 1 || y.a >= 1) {
        for (int c = 0; c < 3; c++)
            x.c[c] = x.a >= 1 && y.a >= 1 ? (x.c[c] + y.c[c]) / 2 : x.a >= 1 ? x.c[c] : y.c[c];
        x.a = 1;
        return;
    }
    double u1 = -std::log(1 - x.a), u2 = -std::log(1 - y.a), u = u1 + u2;
    double a = 1 - (1 - x.a) * (1 - y.a);
    for (int c = 0; c < 3; c++) {
        double v1 = u1 > 1e-12 ? x.c[c] * u1 / x.a : x.c[c];
        double v2 = u2 > 1e-12 ? y.c[c] * u2 / y.a : y.c[c];
        x.c[c] = u > 1e-12 ? (v1 + v2) * a / u : v1 + v2;
    }
    x.a = a;
}

static std::vector<Sample> tidy(const std::vector<Sample> &in)
{
    std::vector<double> b;
    for (const Sample &s : in) {
        b.push_back(s.z);
        b.push_back(s.zb);
    }
    std::sort(b.begin(), b.end());
    b.erase(std::unique(b.begin(), b.end()), b.end());
    std::vector<Sample> out;
    for (const Sample &s : in) {
        if (!(s.zb > s.z)) {
            out.push_back(s);
            continue;
        }
        for (size_t k = 0; k + 1 < b.size(); k++)
            if (b[k] >= s.z && b[k + 1] <= s.zb) {
                Sample p = piece(s, (b[k + 1] - b[k]) / (s.zb - s.z));
                p.z = b[k];
                p.zb = b[k + 1];
                out.push_back(p);
            }
    }
    std::stable_sort(out.begin(), out.end(), [](const Sample &x, const Sample &y) {
        return x.z < y.z || (x.z == y.z && x.zb < y.zb);
    });
    std::vector<Sample> m;
    for (const Sample &s : out) {
        if (!m.empty() && m.back().z == s.z && m.back().zb == s.zb)
            merge_same(m.back(), s);
        else
            m.push_back(s);
    }
    return m;
}

static void flatten(const std::vector<Sample> &px, double out[4])
{
    out[0] = out[1] = out[2] = out[3] = 0;
    for (const Sample &s : tidy(px)) {
        double t = 1 - out[3];
        for (int c = 0; c < 3; c++)
            out[c] += t * s.c[c];
        out[3] += t * s.a;
    }
}

static void write_flat(const char *path, const Deep &d, const std::vector<float> &rgba)
{
    Header h(d.header.displayWindow(), d.header.dataWindow());
    for (auto it = d.header.begin(); it != d.header.end(); ++it) {
        std::string n = it.name();
        if (n == "channels" || n == "compression" || n == "type" || n == "version" ||
            n == "chunkCount" || n == "dataWindow" || n == "displayWindow" || n == "name" ||
            n == "maxSamplesPerPixel" || n == "tiles")
            continue;
        h.insert(n, it.attribute());
    }
    const char *names[4] = { "R", "G", "B", "A" };
    FrameBuffer fb;
    for (int c = 0; c < 4; c++) {
        h.channels().insert(names[c], Channel(FLOAT));
        fb.insert(names[c], Slice(FLOAT, (char *)(rgba.data() + c - 4 * (d.x0 + d.y0 * d.w)),
                                  4 * sizeof(float), 4 * sizeof(float) * d.w));
    }
    OutputFile out(path, h);
    out.setFrameBuffer(fb);
    out.writePixels(d.h);
}

static int cmd_flatten(const char *in, const char *out, const Sample *extra)
{
    Deep d = read_deep(in);
    std::vector<float> rgba((size_t)d.w * d.h * 4);
    for (size_t i = 0; i < d.px.size(); i++) {
        std::vector<Sample> px = d.px[i];
        if (extra)
            px.push_back(*extra);
        double o[4];
        flatten(px, o);
        for (int c = 0; c < 4; c++)
            rgba[4 * i + c] = (float)o[c];
    }
    write_flat(out, d, rgba);
    return 0;
}

static int cmd_union(const char *a, const char *b, const char *out)
{
    Deep d = read_deep(a), e = read_deep(b);
    if (d.px.size() != e.px.size()) {
        std::fprintf(stderr, "deep_ref: %s and %s differ in size\n", a, b);
        return 2;
    }
    std::vector<float> rgba((size_t)d.w * d.h * 4);
    for (size_t i = 0; i < d.px.size(); i++) {
        std::vector<Sample> px = d.px[i];
        px.insert(px.end(), e.px[i].begin(), e.px[i].end());
        double o[4];
        flatten(px, o);
        for (int c = 0; c < 4; c++)
            rgba[4 * i + c] = (float)o[c];
    }
    write_flat(out, d, rgba);
    return 0;
}

static int cmd_tidy(const char *in)
{
    Deep d = read_deep(in);
    size_t total = 0, maxn = 0;
    for (size_t i = 0; i < d.px.size(); i++) {
        const std::vector<Sample> &p = d.px[i];
        total += p.size();
        maxn = std::max(maxn, p.size());
        for (size_t k = 1; k < p.size(); k++) {
            const Sample &a = p[k - 1], &b = p[k];
            bool ordered = a.z < b.z || (a.z == b.z && a.zb <= b.zb);
            bool apart = a.zb <= b.z || (a.z == a.zb && a.z == b.z);
            if (!ordered || !apart) {
                std::printf("not tidy at pixel %zu: [%g, %g] then [%g, %g]\n", i, a.z, a.zb,
                            b.z, b.zb);
                return 1;
            }
        }
    }
    std::printf("%.3f samples per pixel (at most %zu)\n",
                (double)total / (double)d.px.size(), maxn);
    return 0;
}

static int cmd_deepen(const char *in, const char *out, bool glass)
{
    InputFile f(in);
    Imath::Box2i dw = f.header().dataWindow();
    int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    size_t n = (size_t)w * h;
    std::vector<float> px(n * 5, 0.0f);
    FrameBuffer fb;
    const char *names[5] = { "R", "G", "B", "A", "Z" };
    for (int c = 0; c < 5; c++)
        fb.insert(names[c], Slice(FLOAT, (char *)(px.data() + c - 5 * ((size_t)dw.min.x +
                                                                       (size_t)dw.min.y * w)),
                                  5 * sizeof(float), 5 * sizeof(float) * w, 1, 1,
                                  c == 3 ? 1.0 : 0.0));
    f.setFrameBuffer(fb);
    f.readPixels(dw.min.y, dw.max.y);
    Header hd(f.header());
    hd.channels() = ChannelList();
    const char *dn[6] = { "R", "G", "B", "A", "Z", "ZBack" };
    for (int c = 0; c < 6; c++)
        hd.channels().insert(dn[c], Channel(FLOAT));
    hd.setType(DEEPSCANLINE);
    hd.compression() = ZIPS_COMPRESSION;
    std::vector<unsigned int> counts(n);
    std::vector<std::vector<float>> vals(6);
    std::vector<std::vector<float *>> ptr(6, std::vector<float *>(n));
    std::vector<std::vector<Sample>> all(n);
    for (size_t i = 0; i < n; i++) {
        const float *p = &px[5 * i];
        float z = p[4];
        if (!(z > 0) || !std::isfinite(z) || z >= 1e9f) {
            // the sky: a point at infinity, as oiiotool --deepen writes it
            all[i].push_back({ INFINITY, INFINITY, p[3], { p[0], p[1], p[2] } });
            continue;
        }
        if (glass) {
            all[i].push_back({ 0.3 * z, 0.3 * z, 0.3, { 0.05, 0.02, 0.1 } });
            all[i].push_back({ 0.5 * z, 0.8 * z, 0.4, { 0.1, 0.15, 0.05 } });
        }
        all[i].push_back({ z, z, p[3], { p[0], p[1], p[2] } });
    }
    size_t total = 0;
    for (size_t i = 0; i < n; i++)
        total += counts[i] = (unsigned)all[i].size();
    DeepFrameBuffer dfb;
    dfb.insertSampleCountSlice(Slice(UINT, (char *)(counts.data() - dw.min.x - (size_t)dw.min.y * w),
                                     sizeof(unsigned), sizeof(unsigned) * w));
    for (int c = 0; c < 6; c++) {
        vals[c].resize(total + 1);
        size_t at = 0;
        for (size_t i = 0; i < n; i++) {
            ptr[c][i] = vals[c].data() + at;
            for (const Sample &s : all[i]) {
                double v = c < 3 ? s.c[c] : c == 3 ? s.a : c == 4 ? s.z : s.zb;
                vals[c][at++] = (float)v;
            }
        }
        dfb.insert(dn[c], DeepSlice(FLOAT, (char *)(ptr[c].data() - dw.min.x - (size_t)dw.min.y * w),
                                    sizeof(float *), sizeof(float *) * w, sizeof(float)));
    }
    DeepScanLineOutputFile o(out, hd);
    o.setFrameBuffer(dfb);
    o.writePixels(h);
    return 0;
}

static int cmd_diff(const char *a, const char *b, double tol, bool rel, const char *range_path)
{
    float *img[3] = { nullptr, nullptr, nullptr };
    std::vector<float> buf[3];
    int w = 0, h = 0;
    const char *paths[3] = { a, b, range_path };
    for (int k = 0; k < 3; k++) {
        if (!paths[k])
            continue;
        InputFile f(paths[k]);
        Imath::Box2i dw = f.header().dataWindow();
        w = dw.max.x - dw.min.x + 1;
        h = dw.max.y - dw.min.y + 1;
        buf[k].assign((size_t)w * h * 3, 0.0f);
        FrameBuffer fb;
        const char *names[3] = { "R", "G", "B" };
        for (int c = 0; c < 3; c++)
            fb.insert(names[c], Slice(FLOAT, (char *)(buf[k].data() + c - 3 * ((size_t)dw.min.x +
                                                                               (size_t)dw.min.y * w)),
                                      3 * sizeof(float), 3 * sizeof(float) * w));
        f.setFrameBuffer(fb);
        f.readPixels(dw.min.y, dw.max.y);
        img[k] = buf[k].data();
    }
    if (buf[0].size() != buf[1].size()) {
        std::printf("sizes differ\n");
        return 1;
    }
    double worst = 0;
    size_t at = 0;
    for (size_t i = 0; i < buf[0].size(); i++) {
        double d = std::fabs((double)img[0][i] - img[1][i]);
        if (rel) {
            // the composite's range: the brightest channel of the pixel, at least 1
            size_t p = i / 3 * 3;
            double range = 1;
            const float *r = img[2] ? img[2] : img[1];
            for (int c = 0; c < 3; c++)
                range = std::max(range, std::fabs((double)r[p + c]));
            d /= range;
        }
        if (!(d <= worst)) {
            worst = d;
            at = i / 3;
        }
    }
    std::printf("max |diff| %.3g at pixel %zu,%zu (tolerance %g)\n", worst, at % (size_t)w,
                at / (size_t)w, tol);
    return worst <= tol ? 0 : 1;
}

int main(int argc, char **argv)
{
    try {
        std::string c = argc > 1 ? argv[1] : "";
        if (c == "flatten" && argc == 4)
            return cmd_flatten(argv[2], argv[3], nullptr);
        if (c == "merge" && argc == 8) {
            Sample s = { atof(argv[3]), atof(argv[3]), 1.0, { atof(argv[4]), atof(argv[5]),
                                                              atof(argv[6]) } };
            return cmd_flatten(argv[2], argv[7], &s);
        }
        if (c == "union" && argc == 5)
            return cmd_union(argv[2], argv[3], argv[4]);
        if (c == "tidy" && argc == 3)
            return cmd_tidy(argv[2]);
        if (c == "deepen" && (argc == 4 || argc == 5))
            return cmd_deepen(argv[2], argv[3], argc == 5 && std::string(argv[4]) == "glass");
        if (c == "diff" && argc >= 5 && argc <= 7)
            return cmd_diff(argv[2], argv[3], atof(argv[4]),
                            argc >= 6 && std::string(argv[5]) == "rel", argc == 7 ? argv[6] : nullptr);
    } catch (const std::exception &e) {
        std::fprintf(stderr, "deep_ref: %s\n", e.what());
        return 2;
    }
    std::fprintf(stderr, "usage: deep_ref flatten|merge|tidy|deepen|diff ... (see the source)\n");
    return 2;
}
