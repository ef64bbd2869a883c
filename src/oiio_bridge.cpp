// fogpipe: extern "C" bridge to OpenImageIO (see oiio_bridge.h).
#include "oiio_bridge.h"

#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

extern "C" int fp_error(const char *fmt, ...);

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

extern "C" int fp_oiio_read_channel(const char *path, const char *channel, float **data,
                                    int *width, int *height)
{
    try {
        // Values are data: no linearization, no premultiplication.
        ImageSpec config;
        config.attribute("oiio:RawColor", 1);
        config.attribute("oiio:UnassociatedAlpha", 1);
        auto in = ImageInput::open(path, &config);
        if (!in) {
            std::string e = OIIO::geterror();
            return fp_error("%s: cannot read the image (%s)", path,
                            e.empty() ? "unknown format" : e.c_str());
        }
        const ImageSpec &spec = in->spec();
        int ch = 0;
        if (channel && *channel) {
            ch = spec.channelindex(channel);
            if (ch < 0) {
                std::string names;
                for (const auto &n : spec.channelnames)
                    names += (names.empty() ? "" : ", ") + n;
                return fp_error("%s: no channel '%s' (the image has %s)", path, channel,
                                names.c_str());
            }
        }
        size_t n = (size_t)spec.width * spec.height;
        if (n == 0 || spec.depth > 1)
            return fp_error("%s: expected a 2D image, got %dx%dx%d", path, spec.width,
                            spec.height, spec.depth);
        float *buf = (float *)malloc(n * sizeof(float));
        if (!buf)
            return fp_error("%s: out of memory", path);
        if (!in->read_image(0, 0, ch, ch + 1, TypeDesc::FLOAT, buf)) {
            std::string e = in->geterror();
            free(buf);
            return fp_error("%s: cannot read the pixels (%s)", path, e.c_str());
        }
        *data = buf;
        *width = spec.width;
        *height = spec.height;
        return 0;
    } catch (const std::exception &e) {
        return fp_error("%s: %s", path, e.what());
    } catch (...) {
        return fp_error("%s: unexpected error reading the image", path);
    }
}

// Deterministic dither in [-1/2, 1/2): a hash of the pixel and channel.
static double dither_at(int x, int y, int c)
{
    uint32_t h = (uint32_t)x * 73856093u ^ (uint32_t)y * 19349663u ^ (uint32_t)c * 83492791u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return (h & 0xffffffu) / 16777216.0 - 0.5;
}

extern "C" int fp_oiio_write_preview(const char *path, const float *pixels, int width,
                                     int height, int nchannels, int bits, int dither)
{
    std::string tmp;
    try {
        if (bits != 8 && bits != 16)
            return fp_error("%s: expected 8 or 16 bits, got %d", path, bits);
        std::string p(path);
        size_t slash = p.rfind('/');
        std::string dir = slash == std::string::npos ? "" : p.substr(0, slash + 1);
        std::string base = slash == std::string::npos ? p : p.substr(slash + 1);
        size_t dot = base.rfind('.');
        std::string ext = dot == std::string::npos ? "" : base.substr(dot);
        // Keep the extension: OpenImageIO picks the format from it.
        tmp = dir + "." + base + ".tmp." + std::to_string((long)getpid()) + ext;
        auto out = ImageOutput::create(tmp);
        if (!out)
            return fp_error("%s: no image format for this extension (%s)", path,
                            OIIO::geterror().c_str());
        double top = bits == 8 ? 255.0 : 65535.0;
        size_t n = (size_t)width * height * nchannels;
        std::vector<uint16_t> q16(bits == 16 ? n : 0);
        std::vector<uint8_t> q8(bits == 8 ? n : 0);
        for (size_t i = 0; i < n; i++) {
            int c = (int)(i % nchannels), x = (int)(i / nchannels % width),
                y = (int)(i / nchannels / width);
            double v = std::isfinite(pixels[i]) ? pixels[i] : 0.0;
            v = std::fmin(1.0, std::fmax(0.0, v)) * top + 0.5;
            if (dither)
                v += dither_at(x, y, c);
            v = std::fmin(top, std::fmax(0.0, std::floor(v)));
            if (bits == 16)
                q16[i] = (uint16_t)v;
            else
                q8[i] = (uint8_t)v;
        }
        ImageSpec spec(width, height, nchannels, bits == 16 ? TypeDesc::UINT16 : TypeDesc::UINT8);
        bool ok = out->open(tmp, spec) &&
                  out->write_image(bits == 16 ? TypeDesc::UINT16 : TypeDesc::UINT8,
                                   bits == 16 ? (const void *)q16.data() : (const void *)q8.data()) &&
                  out->close();
        if (!ok) {
            std::string e = out->geterror();
            unlink(tmp.c_str());
            return fp_error("%s: cannot write (%s)", path, e.c_str());
        }
        if (rename(tmp.c_str(), path) != 0) {
            int err = errno;
            unlink(tmp.c_str());
            return fp_error("%s: cannot write (%s)", path, strerror(err));
        }
        return 0;
    } catch (const std::exception &e) {
        if (!tmp.empty())
            unlink(tmp.c_str());
        return fp_error("%s: %s", path, e.what());
    } catch (...) {
        if (!tmp.empty())
            unlink(tmp.c_str());
        return fp_error("%s: unexpected error writing the image", path);
    }
}
