/* fogpipe: the ZIP and ZIPS codecs of EXR chunks through libdeflate
 * instead of the zlib inside OpenEXR 3.1's C API (2-3x faster at the same
 * level, the same zlib format, so every EXR reader reads what it writes).
 * The pre-processing around the deflate stream is OpenEXR's own
 * (internal_zip.c): the chunk's bytes split into those at even and at odd
 * offsets, the two halves one after the other, then every byte but the
 * first replaced by its difference from the one before plus 128.
 * These run as the compress_fn / decompress_fn of the chunk workers'
 * pipelines (exr_write.c, exr_read.c); every other codec stays OpenEXR's. */
#include "exr_internal.h"
#include "fp_ctx.h"

#include <libdeflate.h>

#include <inttypes.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

/* The level unless the part's zip level is set: OpenEXR's own default
 * since it deflates with libdeflate (3.2 on, EXR_DEFAULT_ZLIB_COMPRESS_LEVEL
 * in its compression.c: "better trade off of speed vs size"), so fogpipe
 * writes what current OpenEXR writes.  OpenEXR 3.1's zlib used 6. */
#define FP_ZIP_DEFAULT_LEVEL 4

/* The current context's choice (src/base/fp_ctx.h). */
void fp_zip_set_enabled(int on)
{
    fp_ctx()->zip_off = !on;
}

int fp_zip_enabled(void)
{
    return !fp_ctx()->zip_off;
}

int fp_zip_is_zip(int compression)
{
    return compression == EXR_COMPRESSION_ZIP || compression == EXR_COMPRESSION_ZIPS;
}

void fp_zip_release(fp_zip_t *z)
{
    libdeflate_free_compressor(z->comp);
    libdeflate_free_decompressor(z->dec);
    free(z->scratch);
    memset(z, 0, sizeof *z);
}

static int grow_scratch(fp_zip_t *z, size_t n)
{
    if (z->scratch_cap >= n)
        return 0;
    uint8_t *s = malloc(n ? n : 1);
    if (!s)
        return -1;
    free(z->scratch);
    z->scratch = s;
    z->scratch_cap = n;
    return 0;
}

/* ------------------------------------------------------------ pre-processing */

void fp_zip_deconstruct(uint8_t *out, const uint8_t *raw, size_t n)
{
    size_t half = (n + 1) / 2, nodd = n / 2;
    uint8_t *t1 = out, *t2 = out + half;
    size_t i = 0;
    if (n == 0)
        return;
    /* out[k] = t[k] - t[k-1] + 128 over t = even bytes then odd bytes; the
     * odd half's first byte follows the even half's last (raw[2 half - 2]) */
#ifdef __SSE2__
    const __m128i lo = _mm_set1_epi16(0x00ff), bias = _mm_set1_epi8((char) 0x80);
    __m128i pe = _mm_setzero_si128();
    __m128i po = _mm_slli_si128(_mm_cvtsi32_si128(raw[2 * half - 2]), 15);
    for (; i + 16 <= nodd; i += 16) {
        __m128i a = _mm_loadu_si128((const __m128i *) (raw + 2 * i));
        __m128i b = _mm_loadu_si128((const __m128i *) (raw + 2 * i + 16));
        __m128i e = _mm_packus_epi16(_mm_and_si128(a, lo), _mm_and_si128(b, lo));
        __m128i o = _mm_packus_epi16(_mm_srli_epi16(a, 8), _mm_srli_epi16(b, 8));
        __m128i ep = _mm_or_si128(_mm_slli_si128(e, 1), _mm_srli_si128(pe, 15));
        __m128i opv = _mm_or_si128(_mm_slli_si128(o, 1), _mm_srli_si128(po, 15));
        _mm_storeu_si128((__m128i *) (t1 + i), _mm_add_epi8(_mm_sub_epi8(e, ep), bias));
        _mm_storeu_si128((__m128i *) (t2 + i), _mm_add_epi8(_mm_sub_epi8(o, opv), bias));
        pe = e;
        po = o;
    }
#endif
    for (size_t k = i; k < half; ++k)
        t1[k] = (uint8_t) (raw[2 * k] - (k ? raw[2 * k - 2] : 0) + 128);
    for (size_t k = i; k < nodd; ++k)
        t2[k] = (uint8_t) (raw[2 * k + 1] - (k ? raw[2 * k - 1] : raw[2 * half - 2]) + 128);
    out[0] = raw[0];
}

void fp_zip_reconstruct(uint8_t *out, uint8_t *s, size_t n)
{
    size_t half = (n + 1) / 2, nodd = n / 2;
    size_t i = 0;
    if (n == 0)
        return;
    /* the running sum, s[k] += s[k-1] - 128; the first byte had no 128
     * added, so it is given one that the loop takes away again */
    s[0] = (uint8_t) (s[0] + 128);
    uint8_t prev = 0;
#ifdef __SSE2__
    const __m128i bias = _mm_set1_epi8((char) 0x80);
    __m128i vp = _mm_setzero_si128();
    for (; i + 16 <= n; i += 16) {
        __m128i d = _mm_add_epi8(_mm_loadu_si128((const __m128i *) (s + i)), bias);
        d = _mm_add_epi8(d, _mm_slli_si128(d, 1));
        d = _mm_add_epi8(d, _mm_slli_si128(d, 2));
        d = _mm_add_epi8(d, _mm_slli_si128(d, 4));
        d = _mm_add_epi8(d, _mm_slli_si128(d, 8));
        _mm_storeu_si128((__m128i *) (s + i), _mm_add_epi8(d, vp));
        /* the block's own sum in every lane (SSE2 has no byte shuffle),
         * added to the running one: one add from block to block */
        __m128i x = _mm_srli_si128(d, 15);
        x = _mm_unpacklo_epi8(x, x);
        x = _mm_shufflelo_epi16(x, 0);
        vp = _mm_add_epi8(vp, _mm_shuffle_epi32(x, 0));
    }
    prev = (uint8_t) _mm_cvtsi128_si32(vp);
#endif
    for (; i < n; ++i) {
        prev = (uint8_t) (prev + s[i] - 128);
        s[i] = prev;
    }
    /* even bytes from the first half, odd bytes from the second */
    const uint8_t *t1 = s, *t2 = s + half;
    i = 0;
#ifdef __SSE2__
    for (; i + 16 <= nodd; i += 16) {
        __m128i a = _mm_loadu_si128((const __m128i *) (t1 + i));
        __m128i b = _mm_loadu_si128((const __m128i *) (t2 + i));
        _mm_storeu_si128((__m128i *) (out + 2 * i), _mm_unpacklo_epi8(a, b));
        _mm_storeu_si128((__m128i *) (out + 2 * i + 16), _mm_unpackhi_epi8(a, b));
    }
#endif
    for (; i < nodd; ++i) {
        out[2 * i] = t1[i];
        out[2 * i + 1] = t2[i];
    }
    if (n & 1)
        out[n - 1] = t1[half - 1];
}

/* ------------------------------------------------------------ codec */

exr_result_t fp_zip_compress(exr_encode_pipeline_t *enc)
{
    fp_zip_t *z = enc->encoding_user_data;
    size_t n = (size_t) enc->packed_bytes;
    if (!z->comp) {
        int level = -1;
        exr_result_t rv = exr_get_zip_compression_level(enc->context, enc->part_index, &level);
        if (rv != EXR_ERR_SUCCESS)
            return rv;
        z->comp = libdeflate_alloc_compressor(level < 0 ? FP_ZIP_DEFAULT_LEVEL : level);
        if (!z->comp) {
            fp_exr_lib_error_handler(enc->context, EXR_ERR_OUT_OF_MEMORY,
                                     "cannot make a libdeflate compressor");
            return EXR_ERR_OUT_OF_MEMORY;
        }
    }
    /* Room for libdeflate's worst case (given less, it gives up a few
     * bytes short of the end), and for the chunk's bytes as they are when
     * deflate does not make them smaller; the pipeline frees it with its
     * free_fn (set with alloc_fn by the caller). */
    size_t cap = libdeflate_zlib_compress_bound(z->comp, n);
    if (cap < n)
        cap = n;
    if (!enc->compressed_buffer || enc->compressed_alloc_size < cap) {
        if (enc->compressed_buffer && enc->compressed_alloc_size > 0)
            enc->free_fn(EXR_TRANSCODE_BUFFER_COMPRESSED, enc->compressed_buffer);
        enc->compressed_alloc_size = 0;
        enc->compressed_buffer = enc->alloc_fn(EXR_TRANSCODE_BUFFER_COMPRESSED, cap);
        if (!enc->compressed_buffer) {
            fp_exr_lib_error_handler(enc->context, EXR_ERR_OUT_OF_MEMORY,
                                     "out of memory for a compressed chunk");
            return EXR_ERR_OUT_OF_MEMORY;
        }
        enc->compressed_alloc_size = cap;
    }
    if (grow_scratch(z, n) != 0) {
        fp_exr_lib_error_handler(enc->context, EXR_ERR_OUT_OF_MEMORY,
                                 "out of memory for a chunk's deflate input");
        return EXR_ERR_OUT_OF_MEMORY;
    }
    fp_zip_deconstruct(z->scratch, enc->packed_buffer, n);
    /* A chunk whose compressed size is not below its packed size is stored
     * as it is: readers take a chunk of the packed size as uncompressed.
     * (OpenEXR 3.1.5 keeps a compressed chunk of exactly the packed size,
     * which no reader can then tell from raw bytes; OpenEXR's C++ library
     * and later C cores store those raw, as here.) */
    size_t c = libdeflate_zlib_compress(z->comp, z->scratch, n, enc->compressed_buffer, cap);
    if (c == 0 || c >= n) {
        memcpy(enc->compressed_buffer, enc->packed_buffer, n);
        c = n;
    }
    enc->compressed_bytes = c;
    return EXR_ERR_SUCCESS;
}

exr_result_t fp_zip_decompress(exr_decode_pipeline_t *dec)
{
    fp_zip_t *z = dec->decoding_user_data;
    size_t in_n = (size_t) dec->chunk.packed_size;
    size_t out_n = (size_t) dec->chunk.unpacked_size;
    char msg[160];
    if (in_n == 0)
        return EXR_ERR_SUCCESS;
    if (in_n == out_n) {
        /* stored raw (see fp_zip_compress) */
        if (dec->unpacked_buffer != dec->packed_buffer)
            memcpy(dec->unpacked_buffer, dec->packed_buffer, out_n);
        return EXR_ERR_SUCCESS;
    }
    if (!z->dec && !(z->dec = libdeflate_alloc_decompressor())) {
        fp_exr_lib_error_handler(dec->context, EXR_ERR_OUT_OF_MEMORY,
                                 "cannot make a libdeflate decompressor");
        return EXR_ERR_OUT_OF_MEMORY;
    }
    if (grow_scratch(z, out_n) != 0) {
        fp_exr_lib_error_handler(dec->context, EXR_ERR_OUT_OF_MEMORY,
                                 "out of memory for an inflated chunk");
        return EXR_ERR_OUT_OF_MEMORY;
    }
    /* the stream must fill the chunk exactly (OpenEXR: outSize ==
     * uncompressed_size, else a corrupt chunk) */
    if (libdeflate_zlib_decompress(z->dec, dec->packed_buffer, in_n, z->scratch, out_n, NULL) !=
        LIBDEFLATE_SUCCESS) {
        /* OpenEXR's own words for it (default_decompress_chunk) */
        snprintf(msg, sizeof msg, "Unable to decompress image data %" PRIu64 " -> %" PRIu64,
                 (uint64_t) in_n, (uint64_t) out_n);
        fp_exr_lib_error_handler(dec->context, EXR_ERR_CORRUPT_CHUNK, msg);
        return EXR_ERR_CORRUPT_CHUNK;
    }
    fp_zip_reconstruct(dec->unpacked_buffer, z->scratch, out_n);
    return EXR_ERR_SUCCESS;
}

static void *zip_alloc(exr_transcoding_pipeline_buffer_id_t id, size_t n)
{
    (void) id;
    return malloc(n);
}

static void zip_free(exr_transcoding_pipeline_buffer_id_t id, void *p)
{
    (void) id;
    free(p);
}

void fp_zip_use_encoder(exr_encode_pipeline_t *enc, fp_zip_t *z)
{
    enc->alloc_fn = zip_alloc;
    enc->free_fn = zip_free;
    enc->compress_fn = fp_zip_compress;
    enc->encoding_user_data = z;
}

void fp_zip_use_decoder(exr_decode_pipeline_t *dec, fp_zip_t *z)
{
    dec->decompress_fn = fp_zip_decompress;
    dec->decoding_user_data = z;
}
