// fogpipe fuzz harness: the outside judge of an EXR input (tests/fuzz/fuzz.py).
//
//   exr_judge exr FILE     OpenEXR's own check (exrcheck -m -t -c: every
//                           read path of the C++ library, then the core
//                           library's, except for DWA files: see has_dwa;
//                           ImfCheckFile.h)
//
// (Images other than EXR are judged by tests/fuzz/image_judge.cpp: it links
// OpenImageIO, whose 260 libraries cost a quarter of a second a start.)
//
// Exit 0: the library accepts the file; 1: it rejects it (the reason on
// stdout, one line); 2: usage.  The harness asks only when fogpipe exited 0,
// so a file the libraries reject but fogpipe accepted is caught; a file they
// accept with garbled pixels is not (fogpipe cannot know better either).
//
// -m and -t are exrcheck's: headers whose images are too large to read in
// a fuzzing run are checked as far as the library does without reading all
// their pixels; the size-limit suite judges those sizes itself.
#include <ImfCheckFile.h>
#include <ImfHeader.h>
#include <ImfMultiPartInputFile.h>

#include <cstdio>
#include <cstring>
#include <exception>

namespace {

// OpenEXR 3.1's core library has no DWA codec (its check rejects every
// DWAA/DWAB file): such files are judged by the C++ library's read paths
// alone.  A header the C++ library cannot read is rejected by those anyway.
bool has_dwa(const char *path)
{
    try {
        Imf::MultiPartInputFile f(path);
        for (int p = 0; p < f.parts(); p++) {
            Imf::Compression c = f.header(p).compression();
            if (c == Imf::DWAA_COMPRESSION || c == Imf::DWAB_COMPRESSION)
                return true;
        }
    } catch (...) {
    }
    return false;
}

int judge_exr(const char *path)
{
    try {
        if (Imf::checkOpenEXRFile(path, true, true, !has_dwa(path))) {
            std::printf("OpenEXR's check rejects it\n");
            return 1;
        }
    } catch (const std::exception &e) {
        std::printf("OpenEXR's check threw: %s\n", e.what());
        return 1;
    }
    return 0;
}

}  // namespace

int main(int argc, char **argv)
{
    if (argc != 3) {
        std::fprintf(stderr, "usage: exr_judge exr FILE\n");
        return 2;
    }
    if (!std::strcmp(argv[1], "exr"))
        return judge_exr(argv[2]);
    std::fprintf(stderr, "usage: exr_judge exr FILE\n");
    return 2;
}
