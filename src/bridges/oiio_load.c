/* fogpipe: the OpenImageIO bridge's functions (src/bridges/oiio_bridge.h), loading
 * the module fogpipe_oiio.so the first time one is called.
 *
 * The module is looked for where src/base/install.h says (the build tree's
 * .libs from the build tree, beside the installed program or library,
 * the configured $(pkglibdir)); the first that passes its checks, loads and
 * is of this build (FP_OIIO_ABI and PACKAGE_VERSION) wins. */
#define _GNU_SOURCE
#include "config.h"

#include <dlfcn.h>
#include <elf.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <link.h>
#include <stdint.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fp.h"
#include "fp_limits.h"
#include "install.h"
#include "oiio_bridge.h"

#define MODULE_NAME "fogpipe_oiio.so"
#define FP_BIG_ENDIAN (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__)

static pthread_once_t once = PTHREAD_ONCE_INIT;
static const fp_oiio_module_t *mod;
static char tried[8192]; /* the places looked in */
static char why[8192];   /* why a module that is there did not load */

static void append(char *buf, size_t size, const char *text)
{
    size_t used = strlen(buf);
    snprintf(buf + used, size - used, "%s%s", used ? ", " : "", text);
}

#if UINTPTR_MAX > 0xffffffffu
#define ELF_CLASS ELFCLASS64
typedef Elf64_Ehdr ehdr_t;
typedef Elf64_Phdr phdr_t;
typedef Elf64_Shdr shdr_t;
typedef Elf64_Sym sym_t;
#else
#define ELF_CLASS ELFCLASS32
typedef Elf32_Ehdr ehdr_t;
typedef Elf32_Phdr phdr_t;
typedef Elf32_Shdr shdr_t;
typedef Elf32_Sym sym_t;
#endif

/* The host's ELF machine (its own executable's header), 0 if unknown. */
static int host_machine(void)
{
    ehdr_t e;
    int fd = open("/proc/self/exe", O_RDONLY | O_CLOEXEC);
    ssize_t got = fd >= 0 ? pread(fd, &e, sizeof e, 0) : -1;
    if (fd >= 0)
        close(fd);
    if (got != (ssize_t)sizeof e || memcmp(e.e_ident, ELFMAG, SELFMAG) != 0)
        return 0;
    return e.e_machine;
}

/* [off, off + len) inside a file of `size` bytes, without overflow. */
static int inside(uint64_t off, uint64_t len, uint64_t size)
{
    return off <= size && len <= size - off;
}

/* Reads `len` bytes at `off` into a malloc'd buffer; NULL on failure. */
static void *read_at(int fd, uint64_t off, size_t len)
{
    unsigned char *b = malloc(len ? len : 1);
    size_t got = 0;
    while (b && got < len) {
        ssize_t r = pread(fd, b + got, len - got, (off_t)(off + got));
        if (r <= 0) {
            free(b);
            return NULL;
        }
        got += (size_t)r;
    }
    return b;
}

int fp_oiio_module_check(const char *path, char *reason, size_t n)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        snprintf(reason, n, "%s: cannot open (%s)", path, strerror(errno));
        return -1;
    }
    struct stat st;
    ehdr_t e;
    phdr_t *ph = NULL;
    shdr_t *sh = NULL;
    const char *bad = NULL;
    uint64_t size = 0;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
        bad = "not a regular file";
    else if ((size = (uint64_t)st.st_size) < sizeof e || pread(fd, &e, sizeof e, 0) != (ssize_t)sizeof e)
        bad = "too short for an ELF header (a cut file)";
    else if (memcmp(e.e_ident, ELFMAG, SELFMAG) != 0)
        bad = "not an ELF file";
    else if (e.e_ident[EI_CLASS] != ELF_CLASS)
        bad = ELF_CLASS == ELFCLASS64 ? "not a 64-bit ELF file" : "not a 32-bit ELF file";
    else if (e.e_ident[EI_DATA] != (FP_BIG_ENDIAN ? ELFDATA2MSB : ELFDATA2LSB))
        bad = "an ELF file of the other byte order";
    else if (e.e_type != ET_DYN)
        bad = "not a shared object";
    else if (host_machine() && e.e_machine != host_machine())
        bad = "an ELF file for another machine";
    else if (e.e_phentsize != sizeof *ph || e.e_phnum == 0 ||
             !inside(e.e_phoff, (uint64_t)e.e_phnum * sizeof *ph, size) ||
             !(ph = read_at(fd, e.e_phoff, (size_t)e.e_phnum * sizeof *ph)))
        bad = "a cut or damaged file (its program headers lie past its end)";
    else if (e.e_shoff && (e.e_shentsize != sizeof *sh ||
                           !inside(e.e_shoff, (uint64_t)e.e_shnum * sizeof *sh, size) ||
                           !(sh = read_at(fd, e.e_shoff, (size_t)e.e_shnum * sizeof *sh))))
        bad = "a cut or damaged file (its section headers lie past its end)";
    for (int i = 0; !bad && i < e.e_phnum; i++)
        if (!inside(ph[i].p_offset, ph[i].p_filesz, size))
            bad = "a cut file (a segment ends past its end)";
    for (int i = 0; !bad && sh && i < e.e_shnum; i++)
        if (sh[i].sh_type != SHT_NOBITS && !inside(sh[i].sh_offset, sh[i].sh_size, size))
            bad = "a cut file (a section ends past its end)";
    free(ph);
    free(sh);
    close(fd);
    if (bad)
        snprintf(reason, n, "%s: %s", path, bad);
    return bad ? -1 : 0;
}

/* The module's version symbol, read before anything in the module is
 * called: NULL, and the reason in `line`, unless it is this build's. */
static const fp_oiio_abi_t *module_abi(void *h, const char *path, char *line, size_t n)
{
    const fp_oiio_abi_t *abi = dlsym(h, FP_OIIO_ABI_SYMBOL);
    Dl_info info;
    void *sym = NULL;
    if (!abi || !dladdr1(abi, &info, &sym, RTLD_DL_SYMENT) || !sym ||
        ELF64_ST_TYPE(((const sym_t *)sym)->st_info) != STT_OBJECT ||
        ((const sym_t *)sym)->st_size != sizeof *abi) {
        snprintf(line, n, "%s is not a fogpipe OpenImageIO module (no " FP_OIIO_ABI_SYMBOL
                 " data of %zu bytes)", path, sizeof *abi);
        return NULL;
    }
    if (abi->abi != FP_OIIO_ABI) {
        snprintf(line, n, "%s is of another fogpipe (module ABI %d, expected %d)", path,
                 abi->abi, FP_OIIO_ABI);
        return NULL;
    }
    if (strnlen(abi->version, sizeof abi->version) == sizeof abi->version ||
        strcmp(abi->version, PACKAGE_VERSION) != 0) {
        snprintf(line, n, "%s is not this fogpipe's (%.*s, expected %s)", path,
                 (int)sizeof abi->version, abi->version, PACKAGE_VERSION);
        return NULL;
    }
    return abi;
}

/* Load dir/MODULE_NAME if it is there and of this build; 1 if loaded. */
static int try_dir(const char *dir)
{
    char path[PATH_MAX + 64], real[PATH_MAX];
    snprintf(path, sizeof path, "%s/%s", dir, MODULE_NAME);
    /* A place that is there but not a directory (<bindir>/fogpipe, the
     * program) is none; each one is named once, however reached. */
    struct stat st;
    if (stat(dir, &st) == 0 && !S_ISDIR(st.st_mode))
        return 0;
    const char *name = realpath(dir, real) ? real : dir;
    if (!strstr(tried, name))
        append(tried, sizeof tried, name);
    if (access(path, F_OK) != 0)
        return 0;
    char line[PATH_MAX + 300];
    if (fp_oiio_module_check(path, line, sizeof line) != 0) {
        append(why, sizeof why, line);
        return 0;
    }
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *e = dlerror();
        append(why, sizeof why, e ? e : path);
        return 0;
    }
    if (!module_abi(h, path, line, sizeof line)) {
        append(why, sizeof why, line);
        dlclose(h);
        return 0;
    }
    fp_oiio_entry_fn entry;
    /* POSIX's way from a data pointer to a function pointer (dlsym(3)). */
    *(void **)&entry = dlsym(h, FP_OIIO_ENTRY);
    const fp_oiio_module_t *m = entry ? entry(fp_error, fp_warn, fp_image_limits_check) : NULL;
    if (!m || m->abi != FP_OIIO_ABI || strcmp(m->version, PACKAGE_VERSION) != 0) {
        snprintf(line, sizeof line, "%s is not this fogpipe's (%s, expected %s)", path,
                 m ? m->version : "no " FP_OIIO_ENTRY, PACKAGE_VERSION);
        append(why, sizeof why, line);
        dlclose(h);
        return 0;
    }
    mod = m;
    return 1;
}

static void load(void)
{
    const char *const *dirs;
    int n = fp_install_dirs(FP_INSTALL_MODULES, &dirs);
    for (int i = 0; i < n; i++)
        if (try_dir(dirs[i]))
            return;
}

static int need(const char *path, const char *what)
{
    pthread_once(&once, load);
    if (mod)
        return FP_OK;
    return fp_error("%s: %s needs fogpipe's OpenImageIO module %s, which %s%s (looked in %s)",
                    path && *path ? path : "(no file name)", what, MODULE_NAME,
                    why[0] ? "did not load: " : "is not installed", why, tried);
}

int fp_oiio_read_channel(const char *path, const char *channel, float **data, int *width,
                         int *height)
{
    int rc = need(path, "reading the image");
    return rc ? rc : mod->read_channel(path, channel, data, width, height);
}

int fp_oiio_write_preview(const char *path, const float *pixels, int width, int height,
                          int nchannels, int bits, int dither)
{
    int rc = need(path, "writing the image");
    return rc ? rc : mod->write_preview(path, pixels, width, height, nchannels, bits, dither);
}

int fp_oiio_tile_sheet(const char *const *paths, int count, int columns, int max_size,
                       const char *out_path)
{
    int rc = need(out_path, "making the contact sheet");
    return rc ? rc : mod->tile_sheet(paths, count, columns, max_size, out_path);
}
