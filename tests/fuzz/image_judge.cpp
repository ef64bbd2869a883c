// fogpipe fuzz harness: OpenImageIO as the outside judge (tests/fuzz/fuzz.py).
//
//   image_judge image FILE    OpenImageIO reads the image (the first
//                             subimage's pixels as float) and reports no error
//   image_judge finite IN OUT 1 if a pixel of OUT has a non-finite R, G, B or
//                             A where IN's R, G, B and A are all finite
//
// Exit 0: accepted (finite); 1: rejected (the reason on stdout, one line);
// 2: usage or not comparable.
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

int judge_image(const char *path)
{
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        std::string e = OIIO::geterror();
        for (char &c : e)
            if (c == '\n')
                c = ' ';
        std::printf("OpenImageIO cannot open it: %s\n", e.c_str());
        return 1;
    }
    // The first subimage, as fogpipe reads a fogmap: looking for a second
    // one follows a TIFF's next-directory offset, whose corruption OpenImageIO
    // reports as an error although the image itself reads (and its tools
    // accept the file).
    const OIIO::ImageSpec &spec = in->spec();
    size_t n = (size_t)spec.width * spec.height * spec.depth * spec.nchannels;
    // Never more than the harness's memory limit allows: a header this
    // large is the size-limit suite's to judge, not this one's.
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || n > (size_t)64 << 20) {
        std::printf("OpenImageIO: it is %dx%dx%d (not read)\n", spec.width, spec.height,
                    spec.nchannels);
        return spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0;
    }
    std::vector<float> px(n);
    // An error with pixels is an error: a truncated TIFF or JPEG reads as
    // pixels and an error (oiiotool prints nothing and exits 0; the library
    // reports it, and fogpipe must not take the garbage).
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data()) ||
        in->has_error()) {
        std::string e = in->geterror();
        for (char &c : e)
            if (c == '\n')
                c = ' ';
        std::printf("OpenImageIO cannot read it: %s\n", e.c_str());
        return 1;
    }
    return 0;
}

// The R, G, B, A of the first subimage as floats (w*h*4), -1 if absent.
bool rgba_of(const char *path, std::vector<float> &px, int &w, int &h)
{
    auto in = OIIO::ImageInput::open(path);
    if (!in)
        return false;
    const OIIO::ImageSpec &spec = in->spec();
    w = spec.width;
    h = spec.height;
    if (w <= 0 || h <= 0 || (size_t)w * h * spec.nchannels > (size_t)64 << 20)
        return false;
    std::vector<float> all((size_t)w * h * spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
        return false;
    static const char *const names[4] = { "R", "G", "B", "A" };
    px.assign((size_t)w * h * 4, 0.0f);
    for (int k = 0; k < 4; k++) {
        int c = spec.channelindex(names[k]);
        for (size_t i = 0; c >= 0 && i < (size_t)w * h; i++)
            px[4 * i + k] = all[i * spec.nchannels + c];
    }
    return true;
}

int judge_finite(const char *a, const char *b)
{
    std::vector<float> in, out;
    int w, h, w2, h2;
    if (!rgba_of(a, in, w, h) || !rgba_of(b, out, w2, h2) || w != w2 || h != h2) {
        std::printf("cannot compare (unreadable or sizes differ)\n");
        return 2;
    }
    size_t bad = 0, first = 0;
    for (size_t i = 0; i < (size_t)w * h; i++) {
        bool fin_in = true, fin_out = true;
        for (int k = 0; k < 4; k++) {
            fin_in = fin_in && std::isfinite(in[4 * i + k]);
            fin_out = fin_out && std::isfinite(out[4 * i + k]);
        }
        if (fin_in && !fin_out && !bad++)
            first = i;
    }
    if (bad) {
        std::printf("%zu of %zu output pixels not finite (first at %zu,%zu)\n", bad,
                    (size_t)w * h, first % w, first / w);
        return 1;
    }
    return 0;
}

}  // namespace

int main(int argc, char **argv)
{
    if (argc == 4 && !std::strcmp(argv[1], "finite"))
        return judge_finite(argv[2], argv[3]);
    if (argc == 3 && !std::strcmp(argv[1], "image"))
        return judge_image(argv[2]);
    std::fprintf(stderr, "usage: image_judge image FILE | finite IN OUT\n");
    return 2;
}
