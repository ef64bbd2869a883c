// fogpipe: extern "C" bridge to OpenImageIO 2.4 (see oiio_bridge.h), the
// module fogpipe_oiio.so.  C++ stays in this file: every entry point
// catches everything, prints one line through fp_error() and returns a
// status.
#include "config.h"
#include "oiio_bridge.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

extern "C" {
#include "fp.h"
}

// The host's fp_error and fp_warn (the module is loaded into a process
// whose messages go where the host says: src/base/fp.h), set by fp_oiio_module.
namespace {
fp_oiio_error_fn host_error;
fp_oiio_warn_fn host_warn;
fp_oiio_limits_fn host_limits;
}  // namespace
#define fp_error host_error
#define fp_warn host_warn

using OIIO::ImageBuf;
using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;
using OIIO::ROI;
namespace ImageBufAlgo = OIIO::ImageBufAlgo;

namespace {

const char *name_of(const char *path)
{
    return path && *path ? path : "(no file name)";
}

// OpenImageIO's messages may span lines; ours are one line each.
std::string one_line(std::string s)
{
    while (!s.empty() && (s.back() == '\n' || s.back() == ' '))
        s.pop_back();
    for (size_t i; (i = s.find('\n')) != std::string::npos;)
        s.replace(i, 1, "; ");
    return s.empty() ? "no reason given" : s;
}

// Runs an entry point's body; no exception gets past this.
template <typename F> int guarded(const char *path, const char *doing, F &&body)
{
    try {
        return body();
    } catch (const std::bad_alloc &) {
        return fp_error("%s: out of memory %s", name_of(path), doing);
    } catch (const std::exception &e) {
        return fp_error("%s: error %s (%s)", name_of(path), doing, e.what());
    } catch (...) {
        return fp_error("%s: unexpected error %s", name_of(path), doing);
    }
}

// Some channels of an image, interleaved, rows top to bottom as displayed.
struct Pixels {
    std::vector<float> v;
    int width = 0, height = 0, nchannels = 0;
    int bits = 0;  // 8 when the channels are stored in 8 bits, else 16 (or more)
};

uint32_t be32(const unsigned char *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

// PNG's CRC-32 (ISO 3309, the PNG specification's annex D).
uint32_t png_crc(uint32_t crc, const unsigned char *p, size_t n)
{
    static uint32_t table[256];
    static bool made = [] {
        for (uint32_t i = 0; i < 256; i++) {
            uint32_t c = i;
            for (int k = 0; k < 8; k++)
                c = c & 1 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            table[i] = c;
        }
        return true;
    }();
    (void)made;
    for (size_t i = 0; i < n; i++)
        crc = table[(crc ^ p[i]) & 0xff] ^ (crc >> 8);
    return crc;
}

// A PNG's chunks, each there whole with its CRC, up to IEND, before libpng
// reads it: libpng prints its errors on stderr besides returning them (a
// second line), and a truncated or damaged file is ours to name.  Files
// that are not PNGs pass.
int check_png(const char *path)
{
    static const unsigned char sig[8] = { 0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n' };
    std::unique_ptr<FILE, int (*)(FILE *)> f(fopen(path, "rb"), fclose);
    unsigned char head[8];
    if (!f || fread(head, 1, 8, f.get()) != 8 || memcmp(head, sig, 8) != 0)
        return FP_OK;
    std::vector<unsigned char> buf(1 << 16);
    for (long long at = 8, n = 0;; n++) {
        char type[5] = "";
        if (fread(head, 1, 8, f.get()) != 8)
            return fp_error("%s: truncated PNG (the file ends at byte %lld, after %lld chunks "
                            "and no IEND)", path, at, n);
        uint32_t len = be32(head);
        memcpy(type, head + 4, 4);
        for (int i = 0; i < 4; i++)
            if (!isalpha((unsigned char)type[i]))
                type[i] = '?';
        if (len > 0x7fffffffu)
            return fp_error("%s: corrupt PNG (chunk %lld \"%s\" at byte %lld claims %lu bytes)",
                            path, n + 1, type, at, (unsigned long)len);
        uint32_t crc = png_crc(0xffffffffu, head + 4, 4);
        for (uint32_t left = len; left > 0;) {
            size_t want = std::min<size_t>(left, buf.size());
            size_t got = fread(buf.data(), 1, want, f.get());
            crc = png_crc(crc, buf.data(), got);
            if (got != want)
                return fp_error("%s: truncated PNG (chunk %lld \"%s\" at byte %lld has %lu "
                                "bytes; the file ends %lu bytes into it)", path, n + 1, type,
                                at, (unsigned long)len, (unsigned long)(len - left + got));
            left -= (uint32_t)got;
        }
        if (fread(head, 1, 4, f.get()) != 4)
            return fp_error("%s: truncated PNG (the file ends in chunk %lld \"%s\"'s CRC)",
                            path, n + 1, type);
        if (be32(head) != (crc ^ 0xffffffffu))
            return fp_error("%s: corrupt PNG (chunk %lld \"%s\" at byte %lld fails its CRC)",
                            path, n + 1, type, at);
        if (memcmp(type, "IEND", 4) == 0)
            return FP_OK;
        at += 12 + (long long)len;
    }
}

// The image's size from its header against the host's budget, before any
// pixel is read: the pixels, a scanline of every channel (what a reader
// decodes at once) and a tile.
int check_size(const ImageSpec &spec, const char *path)
{
    if (spec.deep)
        return fp_error("%s: deep image, expected flat pixels", path);
    if (spec.depth != 1)
        return fp_error("%s: expected a 2D image, got %dx%dx%d pixels", path, spec.width,
                        spec.height, spec.depth);
    int64_t bytes = 1;
    for (int c = 0; c < spec.nchannels; c++)
        bytes = std::max<int64_t>(bytes, (int64_t)spec.channelformat(c).size());
    if (host_limits(path, -1, "image", spec.width, spec.height, spec.nchannels, bytes))
        return FP_ERR;
    if (spec.tile_width > 0 &&
        host_limits(path, -1, "tile", spec.tile_width, spec.tile_height, spec.nchannels, bytes))
        return FP_ERR;
    return FP_OK;
}

// Opens `path` for reading values as data.  Prints the message and returns
// null on failure.
std::unique_ptr<ImageInput> open_data(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        fp_error("%s: cannot open the image (%s)", path, strerror(errno));
        return nullptr;
    }
    if (S_ISDIR(st.st_mode)) {
        fp_error("%s: is a directory, expected an image file", path);
        return nullptr;
    }
    if (check_png(path) != FP_OK)
        return nullptr;
    ImageSpec config;
    // CMYK (TIFF, PSD) and YCbCr (DPX) as stored, not converted to RGB.
    config.attribute("oiio:RawColor", 1);
    // PNG, TIFF, PSD... readers premultiply unassociated alpha by default
    // (PNG in linearized sRGB), which would change the colour channels.
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = ImageInput::open(path, &config);
    if (!in) {
        fp_error("%s: not an image OpenImageIO can read (%s)", path,
                 one_line(OIIO::geterror()).c_str());
        return nullptr;
    }
    if (check_size(in->spec(), path) != FP_OK)
        return nullptr;
    return in;
}

// Reads stored integers and divides: OpenImageIO's own conversion multiplies
// by 1/255 (1/65535), which misses the correctly rounded value for about
// half the codes (128 would not read back as 128.0f / 255.0f).
template <typename T>
bool read_unorm(ImageInput &in, int chbegin, int chend, TypeDesc type, float top,
                std::vector<float> &v)
{
    std::vector<T> raw(v.size());
    if (!in.read_image(0, 0, chbegin, chend, type, raw.data()))
        return false;
    for (size_t i = 0; i < raw.size(); i++)
        v[i] = (float)raw[i] / top;
    return true;
}

// Reads channels [chbegin, chend) of the first subimage's data window, and
// applies the "Orientation" so that row 0 is the displayed top row.
int read_channels(ImageInput &in, const char *path, int chbegin, int chend, Pixels &px)
{
    const ImageSpec &spec = in.spec();
    if (spec.deep)
        return fp_error("%s: deep image, expected flat pixels", path);
    if (spec.depth != 1 || spec.width <= 0 || spec.height <= 0)
        return fp_error("%s: expected a 2D image, got %dx%dx%d pixels", path, spec.width,
                        spec.height, spec.depth);
    int nch = chend - chbegin;
    size_t n = (size_t)spec.width * spec.height * nch;
    // One storage type for the channels read, or UNKNOWN when they differ
    // (EXR may mix half and float).
    TypeDesc stored = spec.channelformat(chbegin);
    for (int c = chbegin + 1; c < chend; c++)
        if (spec.channelformat(c) != stored)
            stored = TypeDesc::UNKNOWN;
    px.v.assign(n, 0.0f);
    bool ok;
    if (stored == TypeDesc::UINT8)
        ok = read_unorm<uint8_t>(in, chbegin, chend, TypeDesc::UINT8, 255.0f, px.v);
    else if (stored == TypeDesc::UINT16)
        ok = read_unorm<uint16_t>(in, chbegin, chend, TypeDesc::UINT16, 65535.0f, px.v);
    else
        ok = in.read_image(0, 0, chbegin, chend, TypeDesc::FLOAT, px.v.data());
    // A reader may return pixels and an error (a truncated TIFF strip, a
    // JPEG that ends early): the pixels are then garbage.
    std::string err = in.geterror();
    if (!ok || !err.empty())
        return fp_error("%s: cannot read the pixels: truncated or corrupt image (%s)", path,
                        one_line(err).c_str());
    if (!in.close() || in.has_error())
        return fp_error("%s: cannot read the image (%s)", path,
                        one_line(in.geterror()).c_str());
    px.width = spec.width;
    px.height = spec.height;
    px.nchannels = nch;
    px.bits = stored == TypeDesc::UINT8 ? 8 : 16;

    // ImageInput returns rows as stored; a TIFF or JPEG may say they are
    // to be flipped or rotated for display (EXIF/TIFF Orientation 2..8).
    int orientation = spec.get_int_attribute("Orientation", 1);
    if (orientation >= 2 && orientation <= 8) {
        ImageSpec s(px.width, px.height, nch, TypeDesc::FLOAT);
        s.attribute("Orientation", orientation);
        ImageBuf stored_buf(s, px.v.data());
        ImageBuf shown = OIIO::ImageBufAlgo::reorient(stored_buf);
        std::vector<float> v(n);
        if (shown.has_error() || !shown.get_pixels(shown.roi(), TypeDesc::FLOAT, v.data()))
            return fp_error("%s: cannot apply the image's orientation %d (%s)", path,
                            orientation, one_line(shown.geterror()).c_str());
        px.v.swap(v);
        px.width = shown.spec().width;
        px.height = shown.spec().height;
    }
    return FP_OK;
}

// A temporary file that is removed unless kept: one exit path for every
// failure, exceptions included.
struct TmpFile {
    std::string name;
    bool keep = false;
    ~TmpFile()
    {
        if (!name.empty() && !keep)
            unlink(name.c_str());
    }
};

// An image file in memory that a writer may seek in, write over and read
// back (libtiff does; OpenImageIO's IOVecOutput has no read, and the TIFFs
// written through it lack their directory).
class MemFile : public OIIO::Filesystem::IOProxy {
public:
    explicit MemFile(std::vector<unsigned char> &buf) : IOProxy("", Write), m_buf(buf) {}
    const char *proxytype() const override { return "fogpipe-memory"; }
    size_t read(void *buf, size_t size) override
    {
        size_t n = pread(buf, size, m_pos);
        m_pos += (int64_t)n;
        return n;
    }
    size_t write(const void *buf, size_t size) override
    {
        size_t n = pwrite(buf, size, m_pos);
        m_pos += (int64_t)n;
        return n;
    }
    size_t pread(void *buf, size_t size, int64_t offset) override
    {
        if (offset < 0 || (uint64_t)offset >= m_buf.size())
            return 0;
        size_t n = std::min(size, m_buf.size() - (size_t)offset);
        memcpy(buf, m_buf.data() + offset, n);
        return n;
    }
    size_t pwrite(const void *buf, size_t size, int64_t offset) override
    {
        if (offset < 0)
            return 0;
        if ((size_t)offset + size > m_buf.size())
            m_buf.resize((size_t)offset + size);
        memcpy(m_buf.data() + offset, buf, size);
        return size;
    }
    size_t size() const override { return m_buf.size(); }

private:
    std::vector<unsigned char> &m_buf;
};

// Writes `bytes` as the file `name`, every write and the close checked;
// -1 with errno set on failure.
int write_whole(const char *name, const std::vector<unsigned char> &bytes)
{
    int fd = open(name, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0)
        return -1;
    const unsigned char *p = bytes.data();
    size_t left = bytes.size();
    while (left > 0) {
        ssize_t w = write(fd, p, left);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0) {
            int e = w < 0 ? errno : ENOSPC;
            close(fd);
            errno = e;
            return -1;
        }
        p += w;
        left -= (size_t)w;
    }
    return close(fd);
}

// Interleaved gradient noise (J. Jimenez, "Next Generation Post Processing
// in Call of Duty: Advanced Warfare", SIGGRAPH 2014 course): a threshold in
// [0,1) whose neighbours differ a lot (blue-noise-like), from the pixel
// position alone, so the same image dithers to the same bytes.
double dither_threshold(int x, int y)
{
    double f = 0.06711056 * x + 0.00583715 * y;
    f = 52.9829189 * (f - std::floor(f));
    return f - std::floor(f);
}

// floor(v * top + t): t = 1/2 rounds to nearest; a threshold in [0,1) is a
// +-1/2 step dither, which leaves 0 and top exact and moves no value by a
// whole step.  Every channel of a pixel gets the same threshold, so gray
// stays gray (no coloured noise).
template <typename T>
std::vector<T> quantize(const float *pixels, int width, int height, int nch, double top,
                        bool dither)
{
    size_t npix = (size_t)width * height;
    std::vector<T> q(npix * nch);
    for (size_t p = 0; p < npix; p++) {
        double t = dither ? dither_threshold((int)(p % width), (int)(p / width)) : 0.5;
        for (int c = 0; c < nch; c++) {
            double v = pixels[p * nch + c];
            v = v > 0.0 ? (v < 1.0 ? v : 1.0) : 0.0;  // NaN too goes to 0
            q[p * nch + c] = (T)std::floor(v * top + t);
        }
    }
    return q;
}

// Writes an integer image atomically.  With `fewer_bits_ok`, a 16-bit
// request goes to 8 bits in a format that holds only 8 (JPEG); otherwise
// that is an error.
int write_pixels(const char *path, const float *pixels, int width, int height, int nch,
                 int bits, bool dither, bool fewer_bits_ok)
{
    if (!path || !*path)
        return fp_error("fp_oiio_write_preview: no file name");
    if (!pixels || width <= 0 || height <= 0)
        return fp_error("%s: expected pixels of a positive size, got %dx%d", path, width,
                        height);
    if (nch != 1 && nch != 3 && nch != 4)
        return fp_error("%s: expected 1, 3 or 4 channels, got %d", path, nch);
    if (bits != 8 && bits != 16)
        return fp_error("%s: expected 8 or 16 bits per channel, got %d", path, bits);

    std::string p(path);
    size_t slash = p.rfind('/');
    std::string dir = slash == std::string::npos ? "" : p.substr(0, slash + 1);
    std::string base = slash == std::string::npos ? p : p.substr(slash + 1);
    size_t dot = base.rfind('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == base.size())
        return fp_error("%s: no extension to choose the image format by (expected .png, "
                        ".tif or .jpg)", path);
    std::string ext = base.substr(dot);
    TmpFile tmp;
    tmp.name = dir + "." + base.substr(0, dot) + ".tmp." + std::to_string((long)getpid()) + ext;

    // The writer encodes into memory and the file is written here, every
    // write checked: OpenImageIO's writers do not all report a failed write
    // (a PNG on a full disk was "written", cut), and libjpeg's exits the
    // process.  TIFF is the exception: libtiff checks its own writes, and
    // rewrites its directory in place (an EXIF one for the color space),
    // which OpenImageIO 2.4's TIFF writer cannot do through a proxy.
    std::vector<unsigned char> bytes;
    MemFile vec(bytes);
    auto out = ImageOutput::create(path);
    if (!out)
        return fp_error("%s: no image format for the extension \"%s\" (expected .png, .tif, "
                        ".jpg or another OpenImageIO writes)", path, ext.c_str());
    bool in_memory = strcmp(out->format_name(), "tiff") != 0;
    if (in_memory && !out->supports("ioproxy"))
        return fp_error("%s: the %s format cannot be written here (expected .png, .tif or "
                        ".jpg)", path, out->format_name());
    if (nch == 4 && !out->supports("alpha"))
        return fp_error("%s: the %s format has no alpha channel; expected 1 or 3 channels",
                        path, out->format_name());

    TypeDesc type = bits == 16 ? TypeDesc::UINT16 : TypeDesc::UINT8;
    ImageSpec spec(width, height, nch, type);
    spec.attribute("oiio:ColorSpace", "sRGB");
    // The values are written as given: no de-association of alpha (PNG)
    // and TIFF marks the alpha as unassociated.
    spec.attribute("oiio:UnassociatedAlpha", 1);
    // The TIFF writer stamps the current time unless DateTime is set; an
    // empty one writes no tag, so the same pixels give the same bytes.
    spec.attribute("DateTime", "");
    // Set just before open: a JPEG writer destroyed with a proxy and never
    // opened crashes (OpenImageIO 2.4).
    if (in_memory ? !out->set_ioproxy(&vec) || !out->open(path, spec)
                  : !out->open(tmp.name, spec))
        return fp_error("%s: cannot write (%s)", path, one_line(out->geterror()).c_str());
    // Writers adapt what they cannot store (JPEG: 8 bits, no alpha) silently.
    const ImageSpec &got = out->spec();
    if (got.nchannels != nch)
        return fp_error("%s: the %s format stores %d channels here, not %d", path,
                        out->format_name(), got.nchannels, nch);
    if (got.format != type) {
        if (!(fewer_bits_ok && got.format == TypeDesc::UINT8))
            return fp_error("%s: the %s format stores %s, not %d bits per channel (expected "
                            "8 bits, or a .png or .tif name)", path, out->format_name(),
                            got.format.c_str(), bits);
        type = TypeDesc::UINT8;
    }

    bool ok;
    if (type == TypeDesc::UINT16) {
        auto q = quantize<uint16_t>(pixels, width, height, nch, 65535.0, dither);
        ok = out->write_image(type, q.data());
    } else {
        auto q = quantize<uint8_t>(pixels, width, height, nch, 255.0, dither);
        ok = out->write_image(type, q.data());
    }
    ok = ok && !out->has_error();
    ok = out->close() && ok && !out->has_error();
    if (!ok)
        return fp_error("%s: cannot write (%s)", path, one_line(out->geterror()).c_str());
    out.reset();
    if (in_memory && write_whole(tmp.name.c_str(), bytes) != 0)
        return fp_error("%s: cannot write (%s)", path, strerror(errno));
    if (rename(tmp.name.c_str(), path) != 0)
        return fp_error("%s: cannot rename %s into place (%s)", path, tmp.name.c_str(),
                        strerror(errno));
    tmp.keep = true;
    return FP_OK;
}

}  // namespace

namespace {

int read_channel(const char *path, const char *channel, float **data, int *width, int *height)
{
    return guarded(path, "reading the image", [&]() -> int {
        if (!path || !*path || !data || !width || !height)
            return fp_error("fp_oiio_read_channel: expected a file name and three outputs");
        auto in = open_data(path);
        if (!in)
            return FP_ERR;
        const ImageSpec &spec = in->spec();
        int ch = 0;
        if (channel && *channel) {
            ch = spec.channelindex(channel);
            if (ch < 0) {
                std::string names;
                for (size_t i = 0; i < spec.channelnames.size() && i < 24; i++)
                    names += (i ? ", " : "") + spec.channelnames[i];
                if (spec.channelnames.size() > 24)
                    names += ", ...";
                return fp_error("%s: no channel \"%s\" (the image has %s)", path, channel,
                                names.c_str());
            }
        }
        if (spec.x != spec.full_x || spec.y != spec.full_y || spec.width != spec.full_width ||
            spec.height != spec.full_height)
            fp_warn("%s: the data window (%dx%d at %d,%d) differs from the display window "
                    "(%dx%d at %d,%d); using the data window's pixels",
                    path, spec.width, spec.height, spec.x, spec.y, spec.full_width,
                    spec.full_height, spec.full_x, spec.full_y);
        Pixels px;
        if (read_channels(*in, path, ch, ch + 1, px) != FP_OK)
            return FP_ERR;
        float *buf = (float *)malloc(px.v.size() * sizeof(float));
        if (!buf)
            return fp_error("%s: out of memory for %dx%d pixels", path, px.width, px.height);
        memcpy(buf, px.v.data(), px.v.size() * sizeof(float));
        *data = buf;
        *width = px.width;
        *height = px.height;
        return FP_OK;
    });
}

int write_preview(const char *path, const float *pixels, int width, int height, int nchannels,
                  int bits, int dither)
{
    return guarded(path, "writing the image", [&]() -> int {
        return write_pixels(path, pixels, width, height, nchannels, bits, dither != 0, false);
    });
}

int tile_sheet(const char *const *paths, int count, int columns, int max_size,
               const char *out_path)
{
    return guarded(out_path, "making the contact sheet", [&]() -> int {
        if (!out_path || !*out_path)
            return fp_error("fp_oiio_tile_sheet: no output file name");
        if (!paths || count < 1)
            return fp_error("%s: expected at least one image for the contact sheet, got %d",
                            out_path, count);
        if (columns < 1)
            return fp_error("%s: expected at least one column, got %d", out_path, columns);
        if (max_size < 1)
            return fp_error("%s: expected a largest sheet side of at least 1 pixel, got %d",
                            out_path, max_size);
        int rows = (count + columns - 1) / columns;
        std::vector<float> sheet;
        Pixels cell, first;
        int tw = 0, th = 0;   // the cells' size on the sheet
        int bits = 8;
        for (int i = 0; i < count; i++) {
            if (!paths[i] || !*paths[i])
                return fp_error("%s: image %d of the contact sheet has no file name",
                                out_path, i + 1);
            auto in = open_data(paths[i]);
            if (!in)
                return FP_ERR;
            if (read_channels(*in, paths[i], 0, in->spec().nchannels, cell) != FP_OK)
                return FP_ERR;
            in.reset();
            if (i == 0) {
                if (cell.nchannels != 1 && cell.nchannels != 3 && cell.nchannels != 4)
                    return fp_error("%s: %d channels; expected 1, 3 or 4 (gray, RGB, RGBA) "
                                    "for a contact sheet", paths[i], cell.nchannels);
                // Thumbnails: the sheet's longer side at most max_size pixels
                // (100 1080p frames made a 19200x10800 float image), never
                // enlarged; cells keep their aspect.
                double scale = std::min({ 1.0, (double)max_size / ((double)cell.width * columns),
                                          (double)max_size / ((double)cell.height * rows) });
                tw = std::max(1, (int)std::lround(cell.width * scale));
                th = std::max(1, (int)std::lround(cell.height * scale));
                first.width = cell.width;
                first.height = cell.height;
                first.nchannels = cell.nchannels;
                sheet.assign((size_t)tw * columns * th * rows * cell.nchannels, 0.0f);
            } else if (cell.width != first.width || cell.height != first.height ||
                       cell.nchannels != first.nchannels) {
                return fp_error("%s: %dx%d pixels, %d channel(s); expected %dx%d pixels, %d "
                                "channel(s) like %s (contact sheet cells share one size)",
                                paths[i], cell.width, cell.height, cell.nchannels,
                                first.width, first.height, first.nchannels, paths[0]);
            }
            if (cell.bits > bits)
                bits = 16;
            if (tw != cell.width || th != cell.height) {
                ImageSpec spec(cell.width, cell.height, cell.nchannels, TypeDesc::FLOAT);
                ImageBuf src(spec, cell.v.data()), dst;
                if (!ImageBufAlgo::resize(dst, src, "", 0.0f, ROI(0, tw, 0, th)))
                    return fp_error("%s: cannot scale %s to %dx%d for the contact sheet (%s)",
                                    out_path, paths[i], tw, th,
                                    one_line(dst.geterror()).c_str());
                // The filter rings a little past the display range.
                cell.v.assign((size_t)tw * th * cell.nchannels, 0.0f);
                if (!ImageBufAlgo::clamp(dst, dst, 0.0f, 1.0f) ||
                    !dst.get_pixels(ROI(0, tw, 0, th), TypeDesc::FLOAT, cell.v.data()))
                    return fp_error("%s: cannot scale %s to %dx%d for the contact sheet (%s)",
                                    out_path, paths[i], tw, th,
                                    one_line(dst.geterror()).c_str());
            }
            size_t row_len = (size_t)tw * cell.nchannels;
            size_t sheet_row = row_len * columns;
            size_t x0 = (size_t)(i % columns) * row_len, y0 = (size_t)(i / columns) * th;
            for (int y = 0; y < th; y++)
                memcpy(&sheet[(y0 + y) * sheet_row + x0], &cell.v[y * row_len],
                       row_len * sizeof(float));
        }
        return write_pixels(out_path, sheet.data(), tw * columns, th * rows, first.nchannels,
                            bits, false, true);
    });
}

const fp_oiio_module_t module = { FP_OIIO_ABI, PACKAGE_VERSION, read_channel, write_preview,
                                  tile_sheet };

}  // namespace

extern "C" {
__attribute__((visibility("default"))) extern const fp_oiio_abi_t fp_oiio_module_abi;
const fp_oiio_abi_t fp_oiio_module_abi = { FP_OIIO_ABI, PACKAGE_VERSION };
}

extern "C" __attribute__((visibility("default"))) const fp_oiio_module_t *
fp_oiio_module(fp_oiio_error_fn error, fp_oiio_warn_fn warn, fp_oiio_limits_fn limits)
{
    host_error = error;
    host_warn = warn;
    host_limits = limits;
    return &module;
}
