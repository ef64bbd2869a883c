/* fogpipe: OpenCL runtime.  Device choice, program build with an on-disk
 * binary cache, and one checked helper for kernel arguments.
 *
 * Kernels are embedded in the binary at build time (tools/embed-kernels.sh
 * writes fp_kernels.c from the kernels/ .cl files with their #include "..." lines
 * inlined), so an installed fogpipe needs no kernel files.
 *
 * Thread safety: an fp_cl_t is used by one thread at a time. */
#ifndef FP_CLRT_H
#define FP_CLRT_H

#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <stdio.h>

typedef struct fp_cl_t fp_cl_t;

/* Embedded kernel sources, generated into fp_kernels.c. */
typedef struct fp_kernel_source_t {
    const char *name;     /* stage name: "integrate" for kernels/integrate.cl */
    const char *source;   /* with its #include "..." lines inlined */
} fp_kernel_source_t;
extern const fp_kernel_source_t fp_kernel_sources[];
extern const int fp_kernel_source_count;

/* Print every platform and device, one per line, numbered as --device N
 * takes them: "N: <device name> [<platform>, <type>, driver <version>]"
 * (" (not available)" appended for such a device).  FP_ERR with a message
 * when there is no platform or no device. */
int fp_cl_list_devices(FILE *out);

/* Open a device.  `spec` is "N" (index as listed), or a case-insensitive
 * substring of the device or platform name; NULL means $FOGPIPE_DEVICE,
 * else the first GPU, else the first device (PoCL's "pthread" CPU device
 * on a machine without one).  The platform vendor is matched too, so that
 * "pocl" finds PoCL ("Portable Computing Language" by "The pocl project").
 * Devices reporting CL_DEVICE_AVAILABLE false are skipped by the default
 * choice and refused when named.  A spec that matches nothing returns
 * FP_EUSAGE; other failures FP_ERR.  The queue is in order. */
int fp_cl_open(const char *spec, fp_cl_t **out);
void fp_cl_close(fp_cl_t *cl);

cl_context fp_cl_context(const fp_cl_t *cl);
cl_command_queue fp_cl_queue(const fp_cl_t *cl);
cl_device_id fp_cl_device(const fp_cl_t *cl);
/* "<device name> (<platform name>, driver <version>)" */
const char *fp_cl_device_label(const fp_cl_t *cl);

/* Build (or load from the cache) the program of an embedded stage with the
 * given build options.  The cache lives in $FOGPIPE_CACHE_DIR, else
 * $XDG_CACHE_HOME/fogpipe, else ~/.cache/fogpipe; FOGPIPE_CACHE_DIR=off
 * disables it.  The key hashes the inlined source, the options, the device
 * name and version, the driver version and the platform version.  Programs
 * are also kept in memory for the life of `cl`: the returned program is
 * owned by `cl`.  The build log is printed on failure.
 *
 * `options` (NULL = "") are passed to clBuildProgram exactly as given:
 * nothing is added, so callers name the language version they need
 * ("-cl-std=CL1.2", which PoCL and NVIDIA both accept).
 *
 * Cache files are "<sha256 key>.bin": magic, key, payload size and the
 * payload's SHA-256 ahead of the driver's binary, so a truncated or corrupt
 * file is ignored and rewritten; a binary the driver rejects falls back to
 * the source.  Files are written to a temporary name and renamed, so
 * concurrent fogpipe processes sharing the cache only see whole files.
 * An unusable cache directory is a warning, never an error. */
int fp_cl_program(fp_cl_t *cl, const char *stage, const char *options,
                  cl_program *out);

/* Create a kernel from a program; message names the kernel on failure. */
int fp_cl_kernel(cl_program prog, const char *name, cl_kernel *out);

/* The one checked helper for kernel arguments: message names kernel and
 * argument index on failure. */
int fp_cl_arg(cl_kernel k, cl_uint index, size_t size, const void *value);
#define FP_CL_ARG(k, i, v) fp_cl_arg((k), (i), sizeof(v), &(v))

/* Check a CL status: prints "OpenCL error <name> (<code>) in <what>" and
 * returns FP_ERR when err != CL_SUCCESS. */
int fp_cl_check(cl_int err, const char *what);
const char *fp_cl_error_name(cl_int err);

/* Round `n` up to a multiple of `m`. */
static inline size_t fp_cl_round_up(size_t n, size_t m) { return (n + m - 1) / m * m; }

#endif
