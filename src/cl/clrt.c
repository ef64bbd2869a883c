#include "clrt.h"
#include "clcache.h"
#include "fp.h"

#include <ctype.h>
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* ocl-icd returns this from clGetPlatformIDs when no ICD is installed;
 * cl_ext.h names it, but we do not need the rest of that header. */
#define FP_CL_PLATFORM_NOT_FOUND_KHR (-1001)

/* ------------------------------------------------------------------ types */

typedef struct fp_cl_prog_t {
    char *stage;
    char *options;
    cl_program prog;
    struct fp_cl_prog_t *next;
} fp_cl_prog_t;

struct fp_cl_t {
    cl_platform_id platform;
    cl_device_id device;
    cl_context ctx;
    cl_command_queue queue;
    /* What the cached binaries depend on besides source and options. */
    char *dev_name, *dev_version, *driver_version, *plat_name, *plat_version;
    char *label;
    fp_cl_prog_t *progs;   /* programs built so far, per (stage, options) */
};

/* One entry of the global device numbering shared by --list-devices and
 * --device N. */
typedef struct dev_entry_t {
    cl_platform_id platform;
    cl_device_id device;
} dev_entry_t;

/* ------------------------------------------------------------ error names */

const char *fp_cl_error_name(cl_int err)
{
#define FP_E(x) case x: return #x;
    switch (err) {
    FP_E(CL_SUCCESS)
    FP_E(CL_DEVICE_NOT_FOUND)
    FP_E(CL_DEVICE_NOT_AVAILABLE)
    FP_E(CL_COMPILER_NOT_AVAILABLE)
    FP_E(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    FP_E(CL_OUT_OF_RESOURCES)
    FP_E(CL_OUT_OF_HOST_MEMORY)
    FP_E(CL_PROFILING_INFO_NOT_AVAILABLE)
    FP_E(CL_MEM_COPY_OVERLAP)
    FP_E(CL_IMAGE_FORMAT_MISMATCH)
    FP_E(CL_IMAGE_FORMAT_NOT_SUPPORTED)
    FP_E(CL_BUILD_PROGRAM_FAILURE)
    FP_E(CL_MAP_FAILURE)
    FP_E(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    FP_E(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    FP_E(CL_COMPILE_PROGRAM_FAILURE)
    FP_E(CL_LINKER_NOT_AVAILABLE)
    FP_E(CL_LINK_PROGRAM_FAILURE)
    FP_E(CL_DEVICE_PARTITION_FAILED)
    FP_E(CL_KERNEL_ARG_INFO_NOT_AVAILABLE)
    FP_E(CL_INVALID_VALUE)
    FP_E(CL_INVALID_DEVICE_TYPE)
    FP_E(CL_INVALID_PLATFORM)
    FP_E(CL_INVALID_DEVICE)
    FP_E(CL_INVALID_CONTEXT)
    FP_E(CL_INVALID_QUEUE_PROPERTIES)
    FP_E(CL_INVALID_COMMAND_QUEUE)
    FP_E(CL_INVALID_HOST_PTR)
    FP_E(CL_INVALID_MEM_OBJECT)
    FP_E(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    FP_E(CL_INVALID_IMAGE_SIZE)
    FP_E(CL_INVALID_SAMPLER)
    FP_E(CL_INVALID_BINARY)
    FP_E(CL_INVALID_BUILD_OPTIONS)
    FP_E(CL_INVALID_PROGRAM)
    FP_E(CL_INVALID_PROGRAM_EXECUTABLE)
    FP_E(CL_INVALID_KERNEL_NAME)
    FP_E(CL_INVALID_KERNEL_DEFINITION)
    FP_E(CL_INVALID_KERNEL)
    FP_E(CL_INVALID_ARG_INDEX)
    FP_E(CL_INVALID_ARG_VALUE)
    FP_E(CL_INVALID_ARG_SIZE)
    FP_E(CL_INVALID_KERNEL_ARGS)
    FP_E(CL_INVALID_WORK_DIMENSION)
    FP_E(CL_INVALID_WORK_GROUP_SIZE)
    FP_E(CL_INVALID_WORK_ITEM_SIZE)
    FP_E(CL_INVALID_GLOBAL_OFFSET)
    FP_E(CL_INVALID_EVENT_WAIT_LIST)
    FP_E(CL_INVALID_EVENT)
    FP_E(CL_INVALID_OPERATION)
    FP_E(CL_INVALID_GL_OBJECT)
    FP_E(CL_INVALID_BUFFER_SIZE)
    FP_E(CL_INVALID_MIP_LEVEL)
    FP_E(CL_INVALID_GLOBAL_WORK_SIZE)
    FP_E(CL_INVALID_PROPERTY)
    FP_E(CL_INVALID_IMAGE_DESCRIPTOR)
    FP_E(CL_INVALID_COMPILER_OPTIONS)
    FP_E(CL_INVALID_LINKER_OPTIONS)
    FP_E(CL_INVALID_DEVICE_PARTITION_COUNT)
    case FP_CL_PLATFORM_NOT_FOUND_KHR: return "CL_PLATFORM_NOT_FOUND_KHR";
    default: return "unknown OpenCL error";
    }
#undef FP_E
}

int fp_cl_check(cl_int err, const char *what)
{
    if (err == CL_SUCCESS)
        return FP_OK;
    return fp_error("OpenCL error %s (%d) in %s", fp_cl_error_name(err), (int)err, what);
}

/* ---------------------------------------------------------------- helpers */

/* Trim in place: some drivers pad names with spaces. */
static char *trim(char *s)
{
    char *b = s;
    while (isspace((unsigned char)*b))
        b++;
    size_t n = strlen(b);
    while (n > 0 && isspace((unsigned char)b[n - 1]))
        b[--n] = '\0';
    memmove(s, b, n + 1);
    return s;
}

/* A string-valued info query, malloc'ed and trimmed; NULL after a message. */
/* One OpenCL info query: clGetDeviceInfo or clGetPlatformInfo on obj. */
typedef cl_int (*info_query_fn)(void *obj, cl_uint what, size_t n, void *v, size_t *ret);

static cl_int device_query(void *obj, cl_uint what, size_t n, void *v, size_t *ret)
{
    return clGetDeviceInfo((cl_device_id)obj, what, n, v, ret);
}

static cl_int platform_query(void *obj, cl_uint what, size_t n, void *v, size_t *ret)
{
    return clGetPlatformInfo((cl_platform_id)obj, what, n, v, ret);
}

/* A string property, trimmed, malloc'd; NULL (with the error said) on failure. */
static char *info_str(info_query_fn query, void *obj, cl_uint what, const char *name)
{
    size_t n = 0;
    char *s = NULL;
    if (fp_cl_check(query(obj, what, 0, NULL, &n), name))
        return NULL;
    if (!(s = calloc(n + 1, 1))) {
        fp_error("out of memory");
        return NULL;
    }
    if (fp_cl_check(query(obj, what, n, s, NULL), name)) {
        free(s);
        return NULL;
    }
    trim(s);
    return s;
}

static char *device_str(cl_device_id d, cl_device_info what, const char *name)
{
    return info_str(device_query, (void *)d, what, name);
}

static char *platform_str(cl_platform_id p, cl_platform_info what, const char *name)
{
    return info_str(platform_query, (void *)p, what, name);
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}

static int contains_ci(const char *hay, const char *needle)
{
    size_t n = strlen(needle);
    if (n == 0)
        return 1;
    for (; *hay; hay++)
        if (strncasecmp(hay, needle, n) == 0)
            return 1;
    return 0;
}

/* ---------------------------------------------------------------- devices */

/* Every device of every platform, in the order --list-devices numbers
 * them.  A platform whose devices cannot be queried is skipped with a
 * warning so that one broken ICD does not hide the others. */
static int enumerate(dev_entry_t **out, size_t *count)
{
    int rc = FP_ERR;
    cl_uint np = 0;
    cl_platform_id *plats = NULL;
    dev_entry_t *list = NULL;
    cl_device_id *devs = NULL;
    size_t n = 0;

    *out = NULL;
    *count = 0;
    cl_int err = clGetPlatformIDs(0, NULL, &np);
    if (err == FP_CL_PLATFORM_NOT_FOUND_KHR || (err == CL_SUCCESS && np == 0)) {
        rc = fp_error("no OpenCL platform found (install pocl-opencl-icd for the CPU, "
                      "or the GPU driver's OpenCL ICD)");
        goto out;
    }
    if (fp_cl_check(err, "listing OpenCL platforms"))
        goto out;
    if (!(plats = calloc(np, sizeof *plats))) {
        fp_error("out of memory");
        goto out;
    }
    if (fp_cl_check(clGetPlatformIDs(np, plats, NULL), "listing OpenCL platforms"))
        goto out;
    for (cl_uint p = 0; p < np; p++) {
        cl_uint nd = 0;
        err = clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, 0, NULL, &nd);
        if (err == CL_DEVICE_NOT_FOUND || (err == CL_SUCCESS && nd == 0))
            continue;
        if (err != CL_SUCCESS) {
            fp_warn("OpenCL platform %u: cannot list devices: %s (%d); skipped", (unsigned)p,
                    fp_cl_error_name(err), (int)err);
            continue;
        }
        free(devs);
        if (!(devs = calloc(nd, sizeof *devs))) {
            fp_error("out of memory");
            goto out;
        }
        err = clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, nd, devs, NULL);
        if (err != CL_SUCCESS) {
            fp_warn("OpenCL platform %u: cannot list devices: %s (%d); skipped", (unsigned)p,
                    fp_cl_error_name(err), (int)err);
            continue;
        }
        dev_entry_t *grown = realloc(list, (n + nd) * sizeof *list);
        if (!grown) {
            fp_error("out of memory");
            goto out;
        }
        list = grown;
        for (cl_uint d = 0; d < nd; d++) {
            list[n].platform = plats[p];
            list[n].device = devs[d];
            n++;
        }
    }
    if (n == 0) {
        rc = fp_error("no OpenCL device found (%u platform%s, no devices)", (unsigned)np,
                      np == 1 ? "" : "s");
        goto out;
    }
    *out = list;
    *count = n;
    list = NULL;
    rc = FP_OK;
out:
    free(devs);
    free(list);
    free(plats);
    return rc;
}

static const char *type_name(cl_device_type t)
{
    if (t & CL_DEVICE_TYPE_GPU)
        return "GPU";
    if (t & CL_DEVICE_TYPE_CPU)
        return "CPU";
    if (t & CL_DEVICE_TYPE_ACCELERATOR)
        return "accelerator";
    if (t & CL_DEVICE_TYPE_CUSTOM)
        return "custom";
    return "other";
}

static cl_device_type device_type(cl_device_id d)
{
    cl_device_type t = 0;
    if (clGetDeviceInfo(d, CL_DEVICE_TYPE, sizeof t, &t, NULL) != CL_SUCCESS)
        t = 0;
    return t;
}

static int device_available(cl_device_id d)
{
    cl_bool a = CL_FALSE;
    if (clGetDeviceInfo(d, CL_DEVICE_AVAILABLE, sizeof a, &a, NULL) != CL_SUCCESS)
        return 0;
    return a == CL_TRUE;
}

int fp_cl_list_devices(FILE *out)
{
    int rc = FP_ERR;
    dev_entry_t *list = NULL;
    size_t n = 0;
    char *name = NULL, *plat = NULL, *driver = NULL;

    if (enumerate(&list, &n))
        goto out;
    for (size_t i = 0; i < n; i++) {
        if (!(name = device_str(list[i].device, CL_DEVICE_NAME, "device name")) ||
            !(plat = platform_str(list[i].platform, CL_PLATFORM_NAME, "platform name")) ||
            !(driver = device_str(list[i].device, CL_DRIVER_VERSION, "driver version")))
            goto out;
        fprintf(out, "%zu: %s [%s, %s, driver %s]%s\n", i, name, plat,
                type_name(device_type(list[i].device)), driver,
                device_available(list[i].device) ? "" : " (not available)");
        free(name);
        free(plat);
        free(driver);
        name = plat = driver = NULL;
    }
    rc = FP_OK;
out:
    free(name);
    free(plat);
    free(driver);
    free(list);
    return rc;
}

/* Pick the index of `spec` in `list`, or the default device for NULL. */
static int choose(const dev_entry_t *list, size_t n, const char *spec, int from_env,
                  size_t *idx)
{
    int rc = FP_ERR;
    char *name = NULL, *plat = NULL, *vendor = NULL;

    if (!spec) {
        /* The first available GPU, else the first available device, else 0. */
        size_t first = n;
        for (size_t i = 0; i < n; i++) {
            if (!device_available(list[i].device))
                continue;
            if (device_type(list[i].device) & CL_DEVICE_TYPE_GPU) {
                *idx = i;
                return FP_OK;
            }
            if (first == n)
                first = i;
        }
        *idx = first < n ? first : 0;
        return FP_OK;
    }

    if (spec[strspn(spec, "0123456789")] == '\0') {
        errno = 0;
        unsigned long long v = strtoull(spec, NULL, 10);
        if (errno || v >= n)
            return fp_usage_error("OpenCL device %s%s not found: there %s %zu device%s, "
                                  "numbered from 0 (see fogpipe --list-devices)",
                                  from_env ? "FOGPIPE_DEVICE=" : "", spec,
                                  n == 1 ? "is" : "are", n, n == 1 ? "" : "s");
        *idx = (size_t)v;
        return FP_OK;
    }

    /* Substring of the device name, the platform name or the platform
     * vendor: PoCL's platform is "Portable Computing Language" by "The pocl
     * project", so "pocl" needs the vendor. */
    for (size_t i = 0; i < n; i++) {
        if (!(name = device_str(list[i].device, CL_DEVICE_NAME, "device name")) ||
            !(plat = platform_str(list[i].platform, CL_PLATFORM_NAME, "platform name")) ||
            !(vendor = platform_str(list[i].platform, CL_PLATFORM_VENDOR, "platform vendor")))
            goto out;
        if (contains_ci(name, spec) || contains_ci(plat, spec) || contains_ci(vendor, spec)) {
            *idx = i;
            rc = FP_OK;
            goto out;
        }
        free(name);
        free(plat);
        free(vendor);
        name = plat = vendor = NULL;
    }
    rc = fp_usage_error("no OpenCL device matches %s\"%s\" (see fogpipe --list-devices for "
                        "names and numbers)", from_env ? "FOGPIPE_DEVICE=" : "", spec);
out:
    free(name);
    free(plat);
    free(vendor);
    return rc;
}

int fp_cl_open(const char *spec, fp_cl_t **out)
{
    int rc = FP_ERR;
    dev_entry_t *list = NULL;
    size_t n = 0, idx = 0;
    fp_cl_t *cl = NULL;
    cl_int err;

    *out = NULL;
    int from_env = !spec;
    if (!spec)
        spec = getenv("FOGPIPE_DEVICE");
    if (spec && !*spec)
        spec = NULL;
    if (enumerate(&list, &n))
        goto out;
    if ((rc = choose(list, n, spec, from_env, &idx)))
        goto out;
    rc = FP_ERR;
    if (!(cl = calloc(1, sizeof *cl))) {
        fp_error("out of memory");
        goto out;
    }
    cl->platform = list[idx].platform;
    cl->device = list[idx].device;
    if (!(cl->dev_name = device_str(cl->device, CL_DEVICE_NAME, "device name")) ||
        !(cl->dev_version = device_str(cl->device, CL_DEVICE_VERSION, "device version")) ||
        !(cl->driver_version = device_str(cl->device, CL_DRIVER_VERSION, "driver version")) ||
        !(cl->plat_name = platform_str(cl->platform, CL_PLATFORM_NAME, "platform name")) ||
        !(cl->plat_version = platform_str(cl->platform, CL_PLATFORM_VERSION,
                                          "platform version")))
        goto out;
    if (!(cl->label = fp_cl_xasprintf("%s (%s, driver %s)", cl->dev_name, cl->plat_name,
                                cl->driver_version))) {
        fp_error("out of memory");
        goto out;
    }
    if (!device_available(cl->device)) {
        fp_error("OpenCL device %zu, %s, is not available (see fogpipe --list-devices)", idx,
                 cl->label);
        goto out;
    }
    cl_context_properties props[] = {
        CL_CONTEXT_PLATFORM, (cl_context_properties)cl->platform, 0
    };
    cl->ctx = clCreateContext(props, 1, &cl->device, NULL, NULL, &err);
    if (fp_cl_check(err, "creating the OpenCL context"))
        goto out;
    /* In order: the pipeline relies on enqueue order, not on events. */
    cl->queue = clCreateCommandQueue(cl->ctx, cl->device, 0, &err);
    if (fp_cl_check(err, "creating the OpenCL command queue"))
        goto out;
    *out = cl;
    cl = NULL;
    rc = FP_OK;
out:
    fp_cl_close(cl);
    free(list);
    return rc;
}

void fp_cl_close(fp_cl_t *cl)
{
    if (!cl)
        return;
    if (cl->queue)
        clFinish(cl->queue);
    for (fp_cl_prog_t *p = cl->progs, *next; p; p = next) {
        next = p->next;
        clReleaseProgram(p->prog);
        free(p->stage);
        free(p->options);
        free(p);
    }
    if (cl->queue)
        clReleaseCommandQueue(cl->queue);
    if (cl->ctx)
        clReleaseContext(cl->ctx);
    free(cl->dev_name);
    free(cl->dev_version);
    free(cl->driver_version);
    free(cl->plat_name);
    free(cl->plat_version);
    free(cl->label);
    free(cl);
}

cl_context fp_cl_context(const fp_cl_t *cl) { return cl->ctx; }
cl_command_queue fp_cl_queue(const fp_cl_t *cl) { return cl->queue; }
cl_device_id fp_cl_device(const fp_cl_t *cl) { return cl->device; }
const char *fp_cl_device_label(const fp_cl_t *cl) { return cl->label; }

/* ---------------------------------------------------------------- programs */

static void print_build_log(const fp_cl_t *cl, cl_program prog, const char *stage,
                            cl_int err)
{
    size_t n = 0;
    char *log = NULL;
    fp_error("OpenCL program \"%s\" failed to build on %s: %s (%d); build log:", stage,
             cl->label, fp_cl_error_name(err), (int)err);
    if (clGetProgramBuildInfo(prog, cl->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &n) ==
            CL_SUCCESS &&
        (log = calloc(n + 1, 1)) &&
        clGetProgramBuildInfo(prog, cl->device, CL_PROGRAM_BUILD_LOG, n, log, NULL) ==
            CL_SUCCESS) {
        trim(log);
        fp_emit(FP_MSG_ERROR, *log ? log : "(empty build log)", *log ? strlen(log) : 17);
        fp_emit(FP_MSG_ERROR, "\n", 1);
    } else {
        fp_emit(FP_MSG_ERROR, "(no build log)\n", 15);
    }
    free(log);
}

/* Build from a cached binary; CL_SUCCESS or an error after which the
 * caller builds from source (no message: the fallback is routine when a
 * driver update changes what it accepts). */
static cl_int build_binary(fp_cl_t *cl, const unsigned char *bin, size_t size,
                           const char *options, cl_program *out)
{
    cl_int err, status = CL_SUCCESS;
    *out = clCreateProgramWithBinary(cl->ctx, 1, &cl->device, &size, &bin, &status, &err);
    if (err == CL_SUCCESS && status != CL_SUCCESS)
        err = status;
    if (err == CL_SUCCESS)
        err = clBuildProgram(*out, 1, &cl->device, options, NULL, NULL);
    if (err != CL_SUCCESS) {
        if (*out)
            clReleaseProgram(*out);
        *out = NULL;
    }
    return err;
}

/* The program's binary for cl->device, malloc'ed; NULL when the driver
 * gives none (the program is then simply not cached). */
static unsigned char *program_binary(const fp_cl_t *cl, cl_program prog, size_t *size)
{
    cl_uint ndev = 0;
    size_t *sizes = NULL;
    unsigned char **bins = NULL, *bin = NULL;
    cl_device_id *devs = NULL;

    *size = 0;
    if (clGetProgramInfo(prog, CL_PROGRAM_NUM_DEVICES, sizeof ndev, &ndev, NULL) !=
            CL_SUCCESS || ndev == 0)
        goto out;
    if (!(sizes = calloc(ndev, sizeof *sizes)) || !(bins = calloc(ndev, sizeof *bins)) ||
        !(devs = calloc(ndev, sizeof *devs)))
        goto out;
    if (clGetProgramInfo(prog, CL_PROGRAM_DEVICES, ndev * sizeof *devs, devs, NULL) !=
            CL_SUCCESS ||
        clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, ndev * sizeof *sizes, sizes, NULL) !=
            CL_SUCCESS)
        goto out;
    for (cl_uint i = 0; i < ndev; i++)
        if (sizes[i] && !(bins[i] = malloc(sizes[i])))
            goto out;
    if (clGetProgramInfo(prog, CL_PROGRAM_BINARIES, ndev * sizeof *bins, bins, NULL) !=
        CL_SUCCESS)
        goto out;
    for (cl_uint i = 0; i < ndev; i++)
        if (devs[i] == cl->device && sizes[i]) {
            bin = bins[i];
            bins[i] = NULL;
            *size = sizes[i];
            break;
        }
out:
    if (bins)
        for (cl_uint i = 0; i < ndev; i++)
            free(bins[i]);
    free(bins);
    free(sizes);
    free(devs);
    return bin;
}

int fp_cl_program(fp_cl_t *cl, const char *stage, const char *options, cl_program *out)
{
    int rc = FP_ERR;
    const char *source = NULL;
    char *dir = NULL, *path = NULL;
    unsigned char key[FP_KEY_LEN], *bin = NULL;
    char hex[2 * FP_KEY_LEN + 1];
    size_t size = 0;
    cl_program prog = NULL;
    fp_cl_prog_t *memo = NULL;
    cl_int err;

    *out = NULL;
    if (!options)
        options = "";
    for (fp_cl_prog_t *p = cl->progs; p; p = p->next)
        if (strcmp(p->stage, stage) == 0 && strcmp(p->options, options) == 0) {
            *out = p->prog;
            return FP_OK;
        }
    for (int i = 0; i < fp_kernel_source_count; i++)
        if (strcmp(fp_kernel_sources[i].name, stage) == 0)
            source = fp_kernel_sources[i].source;
    if (!source) {
        fp_error("no embedded OpenCL source for stage \"%s\" (kernels/%s.cl missing from "
                 "the build?)", stage, stage);
        goto out;
    }

    fp_sha256_t s;
    fp_sha256_init(&s);
    fp_sha256_field(&s, FP_CACHE_KEY_VERSION);
    fp_sha256_field(&s, source);
    fp_sha256_field(&s, options);
    fp_sha256_field(&s, cl->dev_name);
    fp_sha256_field(&s, cl->dev_version);
    fp_sha256_field(&s, cl->driver_version);
    fp_sha256_field(&s, cl->plat_name);
    fp_sha256_field(&s, cl->plat_version);
    fp_sha256_final(&s, key);
    fp_clcache_key_hex(key, hex);

    double t0 = now_ms();
    if ((dir = fp_clcache_dir())) {
        if (!(path = fp_cl_xasprintf("%s/%s.bin", dir, hex))) {
            fp_error("out of memory");
            goto out;
        }
        fp_clcache_read(path, key, &bin, &size);
        if (bin) {
            err = build_binary(cl, bin, size, options, &prog);
            if (err == CL_SUCCESS)
                fp_info("loaded OpenCL program \"%s\" from the cache %s in %.0f ms", stage,
                        path, now_ms() - t0);
            else
                fp_info("cached OpenCL program %s rejected by the driver (%s); rebuilding",
                        path, fp_cl_error_name(err));
            free(bin);
            bin = NULL;
        }
    }

    if (!prog) {
        t0 = now_ms();
        size_t len = strlen(source);
        prog = clCreateProgramWithSource(cl->ctx, 1, &source, &len, &err);
        if (fp_cl_check(err, "creating an OpenCL program"))
            goto out;
        err = clBuildProgram(prog, 1, &cl->device, options, NULL, NULL);
        if (err != CL_SUCCESS) {
            print_build_log(cl, prog, stage, err);
            goto out;
        }
        fp_info("built OpenCL program \"%s\" for %s in %.0f ms", stage, cl->label,
                now_ms() - t0);
        if (path && (bin = program_binary(cl, prog, &size)))
            fp_clcache_write(dir, path, key, hex, bin, size);
    }

    if (!(memo = calloc(1, sizeof *memo)) || !(memo->stage = fp_cl_xstrdup(stage)) ||
        !(memo->options = fp_cl_xstrdup(options))) {
        fp_error("out of memory");
        goto out;
    }
    memo->prog = prog;
    memo->next = cl->progs;
    cl->progs = memo;
    memo = NULL;
    *out = prog;
    prog = NULL;
    rc = FP_OK;
out:
    if (memo) {
        free(memo->stage);
        free(memo->options);
        free(memo);
    }
    if (prog)
        clReleaseProgram(prog);
    free(bin);
    free(path);
    free(dir);
    return rc;
}

/* ---------------------------------------------------------------- kernels */

int fp_cl_kernel(cl_program prog, const char *name, cl_kernel *out)
{
    cl_int err;
    char what[256];
    *out = clCreateKernel(prog, name, &err);
    if (err == CL_SUCCESS)
        return FP_OK;
    *out = NULL;
    snprintf(what, sizeof what, "creating kernel \"%s\"", name);
    return fp_cl_check(err, what);
}

int fp_cl_arg(cl_kernel k, cl_uint index, size_t size, const void *value)
{
    cl_int err = clSetKernelArg(k, index, size, value);
    if (err == CL_SUCCESS)
        return FP_OK;
    char name[128] = "?", what[256];
    if (clGetKernelInfo(k, CL_KERNEL_FUNCTION_NAME, sizeof name, name, NULL) != CL_SUCCESS)
        strcpy(name, "?");
    snprintf(what, sizeof what, "argument %u (%zu bytes) of kernel \"%s\"", (unsigned)index,
             size, name);
    return fp_cl_check(err, what);
}
