// fogpipe: DWAA/DWAB through OpenEXR's C++ library (see exr_dwa.h).
// C++ stays in this file: every entry point catches everything, prints one
// line through fp_error() and returns a status.
#include "exr_dwa.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputPart.h>
#include <ImfMultiPartInputFile.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfStandardAttributes.h>
#include <ImfTiledInputPart.h>
#include <ImfTiledOutputPart.h>
#include <Iex.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <vector>

extern "C" {
#include "fp.h"
}

namespace {

const uint32_t kMagic = 20000630;

// ---------------------------------------------------------------- streams

// The image being read, served from memory (the pattern of OpenEXR's
// ImfCheckFile.cpp).  Reads past the end throw, as a file would.
class MemIStream : public Imf::IStream {
  public:
    MemIStream(const char *name, const char *data, uint64_t size)
        : Imf::IStream(name), data_(data), size_(size), pos_(0)
    {
    }
    bool isMemoryMapped() const override { return true; }
    bool read(char c[], int n) override
    {
        const char *p = take(n);
        if (n > 0 && !c)
            throw Iex::InputExc("read into no buffer");
        if (n > 0)
            std::memcpy(c, p, static_cast<size_t>(n));
        return pos_ < size_;
    }
    char *readMemoryMapped(int n) override { return const_cast<char *>(take(n)); }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override { pos_ = pos; }
    void clear() override {}

  private:
    const char *take(int n)
    {
        if (n < 0 || pos_ > size_ || static_cast<uint64_t>(n) > size_ - pos_)
            throw Iex::InputExc("unexpected end of file (the image is cut short)");
        const char *p = data_ + pos_;
        pos_ += static_cast<uint64_t>(n);
        return p;
    }
    const char *data_;
    uint64_t size_, pos_;
};

// The image being written, into a growable malloc'd buffer that C takes
// over whole (release); writes land anywhere (the library seeks back to
// write the offset tables).
class MemOStream : public Imf::OStream {
  public:
    explicit MemOStream(const char *name) : Imf::OStream(name) {}
    ~MemOStream() override { std::free(buf_); }
    MemOStream(const MemOStream &) = delete;
    MemOStream &operator=(const MemOStream &) = delete;
    void write(const char c[], int n) override
    {
        if (n < 0)
            throw Iex::ArgExc("negative write size");
        size_t end = static_cast<size_t>(pos_) + static_cast<size_t>(n);
        if (end > cap_) {
            size_t cap = cap_ ? cap_ : 65536;
            while (cap < end)
                cap *= 2;
            void *nb = std::realloc(buf_, cap);
            if (!nb)
                throw std::bad_alloc();
            buf_ = static_cast<char *>(nb);
            cap_ = cap;
        }
        if (pos_ > size_)
            std::memset(buf_ + size_, 0, static_cast<size_t>(pos_) - size_);
        std::memcpy(buf_ + pos_, c, static_cast<size_t>(n));
        pos_ = end;
        if (end > size_)
            size_ = end;
    }
    uint64_t tellp() override { return pos_; }
    void seekp(uint64_t pos) override { pos_ = pos; }
    // Hand the bytes to C (malloc'd; the stream is empty afterwards).
    void release(void **out, size_t *out_size)
    {
        if (!buf_ && !(buf_ = static_cast<char *>(std::malloc(1))))
            throw std::bad_alloc();
        *out = buf_;
        *out_size = size_;
        buf_ = nullptr;
        size_ = cap_ = 0;
        pos_ = 0;
    }

  private:
    char *buf_ = nullptr;
    size_t size_ = 0, cap_ = 0;
    uint64_t pos_ = 0;
};

// ---------------------------------------------------------------- helpers

int64_t floordiv(int64_t a, int64_t b)
{
    int64_t q = a / b;
    if ((a % b) != 0 && ((a < 0) != (b < 0)))
        q--;
    return q;
}

// Samples of a channel with sampling s over [lo, hi): OpenEXR samples at
// multiples of s (as src/exrio.c counts them).
int64_t sampled_count(int64_t lo, int64_t hi, int s)
{
    return hi <= lo ? 0 : floordiv(hi - 1, s) - floordiv(lo - 1, s);
}

bool is_dwa(Imf::Compression c)
{
    return c == Imf::DWAA_COMPRESSION || c == Imf::DWAB_COMPRESSION;
}

// Parts the C library must not decode: DWA, which it lacks, and B44/B44A,
// whose 3.1 decoder misreads float channels in files the C++ library
// wrote (oiiotool's all-float B44 comes back with inf and swapped values;
// tests/dwa.sh).  Once the C++ library decodes an image, it decodes these
// parts of it.
bool needs_cxx(int c)
{
    return c == Imf::DWAA_COMPRESSION || c == Imf::DWAB_COMPRESSION ||
           c == Imf::B44_COMPRESSION || c == Imf::B44A_COMPRESSION;
}

bool part_is_tiled(const Imf::Header &h)
{
    return h.hasType() ? Imf::isTiled(h.type()) : h.hasTileDescription();
}

bool part_is_deep(const Imf::Header &h)
{
    return h.hasType() && Imf::isDeepData(h.type());
}

// The header less its tile description.  (Header::erase of OpenEXR 3.1
// leaks the attribute it removes.)
Imf::Header without_tiles(const Imf::Header &h)
{
    Imf::Header n; // its defaults are all overwritten: h has every one
    for (Imf::Header::ConstIterator it = h.begin(); it != h.end(); ++it)
        if (std::strcmp(it.name(), "tiles") != 0)
            n.insert(it.name(), it.attribute());
    return n;
}

// Decode a part's level 0 into planes (one per channel, sub-sampled
// channels at their own resolution) and encode it into `out`'s part p.
void transcode_pixels(Imf::MultiPartInputFile &in, Imf::MultiPartOutputFile &out,
                      int p)
{
    const Imf::Header &h = in.header(p);
    const Imath::Box2i &dw = h.dataWindow();
    std::vector<std::vector<char>> planes;
    Imf::FrameBuffer fb;
    for (Imf::ChannelList::ConstIterator it = h.channels().begin();
         it != h.channels().end(); ++it) {
        const Imf::Channel &c = it.channel();
        size_t bpe = c.type == Imf::HALF ? 2 : 4;
        int xs = c.xSampling > 0 ? c.xSampling : 1;
        int ys = c.ySampling > 0 ? c.ySampling : 1;
        int64_t sw = sampled_count(dw.min.x, int64_t(dw.max.x) + 1, xs);
        int64_t sh = sampled_count(dw.min.y, int64_t(dw.max.y) + 1, ys);
        planes.emplace_back(static_cast<size_t>(sw * sh) * bpe + 1);
        size_t xstride = bpe, ystride = static_cast<size_t>(sw) * bpe;
        // The library addresses sample (x, y) at base + (x/xs)*xstride +
        // (y/ys)*ystride; the plane's first sample is the first multiple of
        // the sampling inside the window.
        int64_t x0 = floordiv(int64_t(dw.min.x) + xs - 1, xs);
        int64_t y0 = floordiv(int64_t(dw.min.y) + ys - 1, ys);
        char *base = planes.back().data() -
                     (x0 * static_cast<int64_t>(xstride) + y0 * static_cast<int64_t>(ystride));
        fb.insert(it.name(), Imf::Slice(c.type, base, xstride, ystride, xs, ys));
    }
    Imf::InputPart ip(in, p);
    ip.setFrameBuffer(fb);
    if (h.lineOrder() == Imf::DECREASING_Y) {
        // The C++ reader takes a decreasing part's chunks one after the
        // other from the file, so they must lie there in decreasing order;
        // OpenEXR 3.1's C writer stores them increasing (the offset table
        // is right).  Line by line upwards, the reader seeks to each chunk
        // through the offset table (a chunk read once serves its lines).
        for (int y = dw.min.y; y <= dw.max.y; ++y)
            ip.readPixels(y);
    } else {
        ip.readPixels(dw.min.y, dw.max.y);
    }
    Imf::OutputPart op(out, p);
    op.setFrameBuffer(fb);
    op.writePixels(dw.max.y - dw.min.y + 1);
}

// A part whose header is unchanged: its chunks are copied as they are
// (not tiled parts of a multipart input: OpenEXR 3.1 reads their raw tiles
// into a null buffer; decode_image decodes those).
// Not for decreasing line order: copying reads the chunks in file order,
// which a C-written decreasing part does not have (see transcode_pixels).
void copy_chunks(Imf::MultiPartInputFile &in, Imf::MultiPartOutputFile &out,
                 int p)
{
    const Imf::Header &h = in.header(p);
    if (!part_is_tiled(h) && h.lineOrder() == Imf::DECREASING_Y) {
        transcode_pixels(in, out, p);
    } else if (part_is_tiled(h)) {
        Imf::TiledInputPart ip(in, p);
        Imf::TiledOutputPart op(out, p);
        op.copyPixels(ip);
    } else {
        Imf::InputPart ip(in, p);
        Imf::OutputPart op(out, p);
        op.copyPixels(ip);
    }
}

// OpenEXR's messages may span lines; ours are one line each.
std::string one_line(std::string s)
{
    while (!s.empty() && (s.back() == '\n' || s.back() == ' '))
        s.pop_back();
    for (char &c : s)
        if (c == '\n' || c == '\r')
            c = ' ';
    return s.empty() ? "no reason given" : s;
}

// Runs an entry point's body; no exception gets past this.
template <typename F>
int guarded(const char *where, long frame, const char *doing, F &&body)
{
    try {
        return body();
    } catch (const std::bad_alloc &) {
        return fp_error("%s: frame %ld: out of memory %s", where, frame, doing);
    } catch (const std::exception &e) {
        return fp_error("%s: frame %ld: cannot %s (%s)", where, frame, doing,
                        one_line(e.what()).c_str());
    } catch (...) {
        return fp_error("%s: frame %ld: cannot %s (unexpected error)", where,
                        frame, doing);
    }
}

uint32_t rd_u32(const unsigned char *p)
{
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 |
           uint32_t(p[3]) << 24;
}

} // namespace

extern "C" int fp_dwa_probe(const void *buf, size_t size)
{
    const unsigned char *b = static_cast<const unsigned char *>(buf);
    if (!b || size < 8 || rd_u32(b) != kMagic)
        return 0;
    bool multipart = (rd_u32(b + 4) & 0x1000) != 0;
    size_t pos = 8;
    int verdict = 0;
    // Headers: attributes "name\0type\0" size value, each header ending
    // with an empty name; a multipart file's list ends with an empty header.
    for (;;) {
        bool empty = true;
        int comp = -1;
        bool nonhalf = false;
        for (;;) {
            const unsigned char *name = b + pos;
            const void *nul = pos < size ? std::memchr(name, 0, size - pos) : nullptr;
            if (!nul)
                return 0;
            size_t nl = static_cast<const unsigned char *>(nul) - name;
            pos += nl + 1;
            if (nl == 0)
                break;
            empty = false;
            const unsigned char *type = b + pos;
            nul = pos < size ? std::memchr(type, 0, size - pos) : nullptr;
            if (!nul)
                return 0;
            pos += static_cast<size_t>(static_cast<const unsigned char *>(nul) - type) + 1;
            if (size - pos < 4)
                return 0;
            uint32_t as = rd_u32(b + pos);
            pos += 4;
            if (as > size - pos)
                return 0;
            if (nl == 11 && std::memcmp(name, "compression", 11) == 0 && as == 1)
                comp = b[pos];
            if (nl == 8 && std::memcmp(name, "channels", 8) == 0) {
                // entries "name\0" type(4) pLinear(1) reserved(3) xs(4) ys(4)
                size_t q = pos, end = pos + as;
                while (q < end && b[q] != 0) {
                    const void *z = std::memchr(b + q, 0, end - q);
                    if (!z)
                        return 0;
                    q = static_cast<size_t>(static_cast<const unsigned char *>(z) - b) + 1;
                    if (end - q < 16)
                        return 0;
                    if (rd_u32(b + q) != 1) // not HALF
                        nonhalf = true;
                    q += 16;
                }
            }
            pos += as;
        }
        if (comp == Imf::DWAA_COMPRESSION || comp == Imf::DWAB_COMPRESSION)
            return FP_DWA_REQUIRED;
        if ((comp == Imf::B44_COMPRESSION || comp == Imf::B44A_COMPRESSION) && nonhalf)
            verdict = FP_DWA_PREFERRED;
        if (!multipart || empty)
            return verdict;
    }
}

namespace {

// fp_dwa_decode's work; throws on any failure, sets the outputs only when
// all is done.
void decode_image(const void *buf, size_t size, const char *w, void **out,
                  size_t *out_size, int **part_comp, int *num_parts)
{
    MemIStream is(w, static_cast<const char *>(buf), size);
    // A missing chunk must fail loudly, as on the C path.
    Imf::MultiPartInputFile in(is, Imf::globalThreadCount(), false);
    int np = in.parts();
    std::vector<Imf::Header> headers;
    std::vector<int> comp(static_cast<size_t>(np));
    std::vector<bool> plain(static_cast<size_t>(np));
    for (int p = 0; p < np; ++p) {
        Imf::Header h = in.header(p);
        if (part_is_deep(h))
            throw Iex::ArgExc("part " + std::to_string(p) + " holds deep data, which is "
                              "not supported (expected flat scanline or tiled images)");
        comp[static_cast<size_t>(p)] = static_cast<int>(h.compression());
        // Tiled parts are decoded too: OpenEXR 3.1's raw tile copy of a
        // multipart file reads into a null buffer (copy_chunks).
        plain[static_cast<size_t>(p)] = needs_cxx(h.compression()) || part_is_tiled(h);
        if (plain[static_cast<size_t>(p)]) {
            h.compression() = Imf::NO_COMPRESSION;
            if (part_is_tiled(h)) {
                // The C path reads level 0 of a tiled part and writes
                // scanlines: level 0 as scanlines is all it needs.
                h = without_tiles(h);
                if (h.hasType())
                    h.setType(Imf::SCANLINEIMAGE);
                if (h.lineOrder() == Imf::RANDOM_Y)
                    h.lineOrder() = Imf::INCREASING_Y;
            }
        }
        headers.push_back(h);
    }
    MemOStream os(w);
    {
        Imf::MultiPartOutputFile of(os, headers.data(), np, false,
                                    Imf::globalThreadCount());
        for (int p = 0; p < np; ++p) {
            if (plain[static_cast<size_t>(p)])
                transcode_pixels(in, of, p);
            else
                copy_chunks(in, of, p);
        }
    } // the offset tables are written when the file closes
    os.release(out, out_size);
    int *pc = static_cast<int *>(std::malloc(static_cast<size_t>(np) * sizeof(int)));
    if (!pc) {
        std::free(*out);
        *out = nullptr;
        *out_size = 0;
        throw std::bad_alloc();
    }
    for (int p = 0; p < np; ++p)
        pc[p] = comp[static_cast<size_t>(p)];
    *part_comp = pc;
    *num_parts = np;
}

} // namespace

extern "C" int fp_dwa_decode(const void *buf, size_t size, int verdict,
                             const char *where, long frame, void **out,
                             size_t *out_size, int **part_comp, int *num_parts)
{
    const char *w = where ? where : "<input>";
    *out = nullptr;
    *out_size = 0;
    *part_comp = nullptr;
    *num_parts = 0;
    // No fallback to the C decoder: for float B44 it is known to be wrong
    // (see needs_cxx), so what the C++ library refuses is an error.
    return guarded(w, frame,
                   verdict == FP_DWA_REQUIRED ? "decode DWA-compressed EXR"
                                              : "decode B44-compressed EXR",
                   [&]() -> int {
                       decode_image(buf, size, w, out, out_size, part_comp, num_parts);
                       return FP_OK;
                   });
}

extern "C" int fp_dwa_encode(const void *buf, size_t size, const int *part_comp,
                             int num_parts, float level, const char *where,
                             long frame, void **out, size_t *out_size)
{
    const char *w = where ? where : "<output>";
    *out = nullptr;
    *out_size = 0;
    return guarded(w, frame, "encode DWA-compressed EXR", [&]() -> int {
        MemIStream is(w, static_cast<const char *>(buf), size);
        Imf::MultiPartInputFile in(is, Imf::globalThreadCount(), false);
        int np = in.parts();
        if (np != num_parts)
            return fp_error("%s: frame %ld: cannot encode DWA-compressed EXR "
                            "(%d parts encoded, %d compressions given)",
                            w, frame, np, num_parts);
        std::vector<Imf::Header> headers;
        std::vector<bool> change(static_cast<size_t>(np), false);
        for (int p = 0; p < np; ++p) {
            Imf::Header h = in.header(p);
            Imf::Compression c = static_cast<Imf::Compression>(part_comp[p]);
            if (is_dwa(c) && c != h.compression()) {
                if (part_is_tiled(h))
                    return fp_error("%s: frame %ld: cannot encode part %d as DWA "
                                    "(tiled output is not supported)", w, frame, p);
                float lv = level;
                const Imf::FloatAttribute *a =
                    h.findTypedAttribute<Imf::FloatAttribute>("dwaCompressionLevel");
                if (lv < 0.0f)
                    lv = a ? a->value() : FP_DWA_DEFAULT_LEVEL;
                h.compression() = c;
                h.dwaCompressionLevel() = lv;
                h.insert("dwaCompressionLevel", Imf::FloatAttribute(lv));
                change[static_cast<size_t>(p)] = true;
            }
            headers.push_back(h);
        }
        MemOStream os(w);
        {
            Imf::MultiPartOutputFile of(os, headers.data(), np, false,
                                        Imf::globalThreadCount());
            for (int p = 0; p < np; ++p) {
                if (change[static_cast<size_t>(p)])
                    transcode_pixels(in, of, p);
                else
                    copy_chunks(in, of, p);
            }
        }
        os.release(out, out_size);
        return FP_OK;
    });
}
