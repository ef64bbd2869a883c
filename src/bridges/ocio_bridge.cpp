// fogpipe: extern "C" bridge to OpenColorIO 2.1 (see ocio_bridge.h).
// C++ stays in this file: every entry point catches everything, prints one
// line through fp_error() and returns a status.
#include "ocio_bridge.h"

#include <OpenColorIO/OpenColorIO.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <mutex>
#include <new>
#include <string>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

extern "C" {
#include "fp.h"
#include "install.h"
}

namespace OCIO = OCIO_NAMESPACE;

struct fp_ocio_t {
    OCIO::ConstConfigRcPtr config;
    std::string path;
};

struct fp_ocio_proc_t {
    OCIO::ConstProcessorRcPtr processor;
    OCIO::ConstCPUProcessorRcPtr cpu;
};

namespace {

// OpenColorIO's messages may span lines; ours are one line each.
std::string one_line(std::string s)
{
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '.'))
        s.pop_back();
    for (size_t i; (i = s.find('\n')) != std::string::npos;)
        s.replace(i, 1, "; ");
    return s.empty() ? "no reason given" : s;
}

template <typename F> int guarded(const char *where, const char *doing, F &&body)
{
    try {
        return body();
    } catch (const std::bad_alloc &) {
        return fp_error("%s: out of memory %s", where, doing);
    } catch (const std::exception &e) {
        return fp_error("%s: error %s (%s)", where, doing, one_line(e.what()).c_str());
    } catch (...) {
        return fp_error("%s: unexpected error %s", where, doing);
    }
}

int copy_out(const std::string &s, char *out, size_t n, const char *what)
{
    if (!out || n == 0 || s.size() >= n)
        return fp_error("%s: name too long (%zu bytes)", what, s.size());
    memcpy(out, s.c_str(), s.size() + 1);
    return FP_OK;
}

// "a, b, c, ..." of at most `max` names, for messages.
template <typename F> std::string some_names(int count, int max, F &&name_at)
{
    std::string s;
    for (int i = 0; i < count && i < max; i++)
        s += (i ? ", " : "") + std::string(name_at(i));
    if (count > max)
        s += ", ...";
    return s;
}

std::string space_list(const OCIO::ConstConfigRcPtr &cfg)
{
    int n = cfg->getNumColorSpaces();
    return some_names(n, 8, [&](int i) { return cfg->getColorSpaceNameByIndex(i); });
}

}  // namespace

extern "C" int fp_ocio_find_config(const char *explicit_path, char *path, size_t n,
                                   const char **origin)
{
    return guarded("OpenColorIO", "finding the config", [&]() -> int {
        if (explicit_path && *explicit_path) {
            *origin = "--ocio";
            return copy_out(explicit_path, path, n, "--ocio");
        }
        const char *env = getenv("OCIO");
        if (env && *env) {
            *origin = "$OCIO";
            return copy_out(env, path, n, "$OCIO");
        }
        char found[4096], tried[8192];
        if (fp_install_find("ocio/config.ocio", found, sizeof found, tried, sizeof tried) == 0) {
            *origin = "fogpipe's config";
            return copy_out(found, path, n, "fogpipe's OpenColorIO config");
        }
        return fp_error("no OpenColorIO config: neither --ocio nor $OCIO is set, and fogpipe's "
                        "own config is not installed (looked for ocio/config.ocio in %s; "
                        "expected `make install`)", tried);
    });
}

extern "C" int fp_ocio_open(const char *path, fp_ocio_t **out)
{
    *out = nullptr;
    return guarded(path, "reading the OpenColorIO config", [&]() -> int {
        // OpenColorIO logs warnings on stderr by itself; our messages are
        // the one line each error gets.
        OCIO::SetLoggingLevel(OCIO::LOGGING_LEVEL_NONE);
        struct stat st;
        if (stat(path, &st) != 0)
            return fp_error("%s: cannot open the OpenColorIO config (%s)", path,
                            strerror(errno));
        if (!S_ISREG(st.st_mode))
            return fp_error("%s: not a file, expected an OpenColorIO config (config.ocio)",
                            path);
        OCIO::ConstConfigRcPtr cfg;
        try {
            cfg = OCIO::Config::CreateFromFile(path);
            cfg->validate();
        } catch (const OCIO::Exception &e) {
            return fp_error("%s: not a valid OpenColorIO config (%s)", path,
                            one_line(e.what()).c_str());
        }
        if (cfg->getNumColorSpaces() < 1)
            return fp_error("%s: the OpenColorIO config has no color spaces", path);
        auto *c = new fp_ocio_t;
        c->config = cfg;
        c->path = path;
        *out = c;
        return FP_OK;
    });
}

extern "C" void fp_ocio_close(fp_ocio_t *c)
{
    delete c;
}

extern "C" const char *fp_ocio_path(const fp_ocio_t *c)
{
    return c->path.c_str();
}

extern "C" int fp_ocio_space(const fp_ocio_t *c, const char *name_or_role, const char *what,
                             char *name, size_t n)
{
    return guarded(c->path.c_str(), "looking up a color space", [&]() -> int {
        OCIO::ConstColorSpaceRcPtr cs;
        if (name_or_role && *name_or_role)
            cs = c->config->getColorSpace(name_or_role);
        if (!cs)
            return fp_usage_error("%s: no color space \"%s\" in the OpenColorIO config %s "
                                  "(expected a name, alias or role such as scene_linear; it "
                                  "has %s; see fogpipe --list-spaces)",
                                  what, name_or_role ? name_or_role : "", c->path.c_str(),
                                  space_list(c->config).c_str());
        return copy_out(cs->getName(), name, n, what);
    });
}

extern "C" int fp_ocio_role(const fp_ocio_t *c, const char *role, char *name, size_t n)
{
    try {
        if (!c->config->hasRole(role))
            return FP_ERR;
        OCIO::ConstColorSpaceRcPtr cs = c->config->getColorSpace(role);
        if (!cs || strlen(cs->getName()) >= n)
            return FP_ERR;
        strcpy(name, cs->getName());
        return FP_OK;
    } catch (...) {
        return FP_ERR;
    }
}

extern "C" int fp_ocio_is_data(const fp_ocio_t *c, const char *space)
{
    try {
        OCIO::ConstColorSpaceRcPtr cs = c->config->getColorSpace(space);
        return cs && cs->isData() ? 1 : 0;
    } catch (...) {
        return 0;
    }
}

extern "C" int fp_ocio_is_display_referred(const fp_ocio_t *c, const char *space)
{
    try {
        OCIO::ConstColorSpaceRcPtr cs = c->config->getColorSpace(space);
        return cs && cs->getReferenceSpaceType() == OCIO::REFERENCE_SPACE_DISPLAY ? 1 : 0;
    } catch (...) {
        return 0;
    }
}

extern "C" int fp_ocio_num_spaces(const fp_ocio_t *c)
{
    try {
        return c->config->getNumColorSpaces();
    } catch (...) {
        return 0;
    }
}

extern "C" const char *fp_ocio_space_name(const fp_ocio_t *c, int index)
{
    try {
        return c->config->getColorSpaceNameByIndex(index);
    } catch (...) {
        return "";
    }
}

extern "C" int fp_ocio_display_view(const fp_ocio_t *c, const char *display, const char *view,
                                    char *d, size_t dn, char *v, size_t vn)
{
    return guarded(c->path.c_str(), "looking up the display", [&]() -> int {
        const auto &cfg = c->config;
        int nd = cfg->getNumDisplays();
        auto display_at = [&](int i) { return cfg->getDisplay(i); };
        std::string dname;
        if (!display || !*display) {
            dname = cfg->getDefaultDisplay();
            if (dname.empty())
                return fp_error("%s: the OpenColorIO config has no display (expected one for "
                                "--preview)", c->path.c_str());
        } else {
            for (int i = 0; i < nd; i++)
                if (strcasecmp(display_at(i), display) == 0)
                    dname = display_at(i);
            if (dname.empty())
                return fp_usage_error("--display: no display \"%s\" in the OpenColorIO config "
                                      "%s (expected one of: %s)", display, c->path.c_str(),
                                      some_names(nd, 12, display_at).c_str());
        }
        int nv = cfg->getNumViews(dname.c_str());
        auto view_at = [&](int i) { return cfg->getView(dname.c_str(), i); };
        std::string vname;
        if (!view || !*view) {
            vname = cfg->getDefaultView(dname.c_str());
            if (vname.empty())
                return fp_error("%s: display \"%s\" has no view (expected one for --preview)",
                                c->path.c_str(), dname.c_str());
        } else {
            for (int i = 0; i < nv; i++)
                if (strcasecmp(view_at(i), view) == 0)
                    vname = view_at(i);
            if (vname.empty())
                return fp_usage_error("--view: display \"%s\" of the OpenColorIO config %s has "
                                      "no view \"%s\" (expected one of: %s)", dname.c_str(),
                                      c->path.c_str(), view, some_names(nv, 12, view_at).c_str());
        }
        if (copy_out(dname, d, dn, "--display") || copy_out(vname, v, vn, "--view"))
            return FP_ERR;
        return FP_OK;
    });
}

namespace {

template <typename G>
int make_proc(const fp_ocio_t *c, const std::string &what, fp_ocio_proc_t **out, G &&get)
{
    *out = nullptr;
    return guarded(c->path.c_str(), what.c_str(), [&]() -> int {
        OCIO::ConstProcessorRcPtr p = get();
        auto *r = new fp_ocio_proc_t;
        r->processor = p;
        r->cpu = p->getDefaultCPUProcessor();
        *out = r;
        return FP_OK;
    });
}

}  // namespace

extern "C" int fp_ocio_processor(const fp_ocio_t *c, const char *src, const char *dst,
                                 fp_ocio_proc_t **out)
{
    return make_proc(c, std::string("converting from \"") + src + "\" to \"" + dst + "\"", out,
                     [&]() { return c->config->getProcessor(src, dst); });
}

extern "C" int fp_ocio_display_processor(const fp_ocio_t *c, const char *src, const char *display,
                                         const char *view, fp_ocio_proc_t **out)
{
    return make_proc(c,
                     std::string("converting from \"") + src + "\" to display \"" + display +
                         "\", view \"" + view + "\"",
                     out, [&]() {
                         auto t = OCIO::DisplayViewTransform::Create();
                         t->setSrc(src);
                         t->setDisplay(display);
                         t->setView(view);
                         return c->config->getProcessor(t);
                     });
}

extern "C" int fp_ocio_is_noop(const fp_ocio_proc_t *p)
{
    return p->processor->isNoOp() ? 1 : 0;
}

extern "C" void fp_ocio_apply(const fp_ocio_proc_t *p, float *pixels, size_t npix, int stride)
{
    // Rows of at most 2^20 pixels; OpenColorIO walks a packed image of three
    // channels with an x stride, so alpha (and any other float of a pixel)
    // stays as it is.
    const size_t chunk = 1 << 20;
    for (size_t i = 0; i < npix; i += chunk) {
        size_t m = npix - i < chunk ? npix - i : chunk;
        OCIO::PackedImageDesc img(pixels + i * stride, (long)m, 1, 3, OCIO::BIT_DEPTH_F32,
                                  sizeof(float), (ptrdiff_t)(stride * sizeof(float)),
                                  (ptrdiff_t)(m * stride * sizeof(float)));
        p->cpu->apply(img);
    }
}

extern "C" void fp_ocio_apply_planar(const fp_ocio_proc_t *p, float *r, float *g, float *b,
                                     size_t npix)
{
    const size_t chunk = 1 << 20;
    for (size_t i = 0; i < npix; i += chunk) {
        size_t m = npix - i < chunk ? npix - i : chunk;
        OCIO::PlanarImageDesc img(r + i, g + i, b + i, nullptr, (long)m, 1);
        p->cpu->apply(img);
    }
}

extern "C" void fp_ocio_proc_free(fp_ocio_proc_t *p)
{
    delete p;
}

extern "C" int fp_ocio_matrix(const fp_ocio_t *c, const char *src, const char *dst, double m[9])
{
    try {
        auto cpu = c->config->getProcessor(src, dst)->getDefaultCPUProcessor();
        for (int k = 0; k < 3; k++) {
            float e[3] = { 0.0f, 0.0f, 0.0f };
            e[k] = 1.0f;
            cpu->applyRGB(e);
            for (int i = 0; i < 3; i++)
                m[i * 3 + k] = e[i];
        }
        // A curve shows at zero, mid grey, small, large or negative values.
        static const float probes[][3] = { { 0.0f, 0.0f, 0.0f },      { 0.18f, 0.18f, 0.18f },
                                           { 4.0f, 0.5f, 0.01f },     { 0.001f, 0.002f, 0.0005f },
                                           { -0.1f, 0.3f, 16.0f } };
        for (const auto &pr : probes) {
            float v[3] = { pr[0], pr[1], pr[2] };
            cpu->applyRGB(v);
            for (int i = 0; i < 3; i++) {
                double want = m[i * 3] * pr[0] + m[i * 3 + 1] * pr[1] + m[i * 3 + 2] * pr[2];
                double scale = std::fabs(pr[0]) + std::fabs(pr[1]) + std::fabs(pr[2]);
                if (!(std::fabs(v[i] - want) <= 1e-4 * (scale + 1e-3)))
                    return 1;
            }
        }
        return 0;
    } catch (...) {
        return -1;
    }
}

extern "C" int fp_ocio_print(const fp_ocio_t *c, FILE *out)
{
    return guarded(c->path.c_str(), "listing the config", [&]() -> int {
        const auto &cfg = c->config;
        fprintf(out, "OpenColorIO config: %s\n", c->path.c_str());
        fprintf(out, "color spaces (name [aliases] family, encoding):\n");
        for (int i = 0; i < cfg->getNumColorSpaces(); i++) {
            auto cs = cfg->getColorSpace(cfg->getColorSpaceNameByIndex(i));
            if (!cs)
                continue;
            std::string aliases;
            for (size_t a = 0; a < cs->getNumAliases(); a++)
                aliases += (a ? ", " : "") + std::string(cs->getAlias(a));
            fprintf(out, "  %s%s%s%s  %s%s%s%s\n", cs->getName(), aliases.empty() ? "" : " [",
                    aliases.c_str(), aliases.empty() ? "" : "]", cs->getFamily(),
                    *cs->getEncoding() ? ", " : "", cs->getEncoding(),
                    cs->isData() ? " (data)"
                    : cs->getReferenceSpaceType() == OCIO::REFERENCE_SPACE_DISPLAY
                        ? " (display-referred)" : "");
        }
        fprintf(out, "roles:\n");
        for (int i = 0; i < cfg->getNumRoles(); i++)
            fprintf(out, "  %s: %s\n", cfg->getRoleName(i), cfg->getRoleColorSpace(i));
        fprintf(out, "displays: views (--display, --view; default display %s):\n",
                cfg->getDefaultDisplay());
        for (int i = 0; i < cfg->getNumDisplays(); i++) {
            const char *d = cfg->getDisplay(i);
            fprintf(out, "  %s (default view %s):", d, cfg->getDefaultView(d));
            for (int k = 0; k < cfg->getNumViews(d); k++)
                fprintf(out, "%s %s", k ? "," : "", cfg->getView(d, k));
            fprintf(out, "\n");
        }
        return FP_OK;
    });
}
