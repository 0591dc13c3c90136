/* half.h: IEEE 754 binary16 ("half float") <-> float conversion, round to
 * nearest even, overflow to infinity, NaN kept a NaN (F16C quiets a
 * signalling one; every other value gives the same bits): the format of the
 * display's correction textures (GL_HALF_FLOAT), of TEX_PATCH texels and of
 * the master's texel store. With the F16C instructions (x86-64 since 2012;
 * the Makefile enables them there) one instruction each; elsewhere the same
 * bits by integer arithmetic. */
#ifndef CT_COMMON_HALF_H
#define CT_COMMON_HALF_H

#include <stdint.h>
#include <string.h>

#if defined(__F16C__)
#include <immintrin.h>
#endif

/* Largest finite half. */
#define HALF_MAX 65504.0f

/* Portable conversions (the reference the F16C path must match; tests). */
static inline uint16_t half_from_float_soft(float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000u;
    uint32_t exp = (x >> 23) & 0xffu;
    uint32_t man = x & 0x7fffffu;
    if (exp == 0xffu) /* inf or NaN (keep NaN a NaN) */
        return (uint16_t)(sign | 0x7c00u | (man ? 0x200u | (man >> 13) : 0u));
    int e = (int)exp - 127 + 15;
    if (e >= 31) return (uint16_t)(sign | 0x7c00u); /* overflow -> inf */
    if (e <= 0) {
        if (e < -10) return (uint16_t)sign; /* underflows to zero */
        /* Subnormal half: shift the mantissa with its implicit 1 into place
         * and round to nearest even. */
        man |= 0x800000u;
        uint32_t shift = (uint32_t)(14 - e);
        uint32_t h = man >> shift;
        uint32_t rem = man & ((1u << shift) - 1u);
        uint32_t halfway = 1u << (shift - 1);
        if (rem > halfway || (rem == halfway && (h & 1u))) h++;
        return (uint16_t)(sign | h);
    }
    uint32_t h = ((uint32_t)e << 10) | (man >> 13);
    uint32_t rem = man & 0x1fffu;
    if (rem > 0x1000u || (rem == 0x1000u && (h & 1u))) h++; /* may carry into inf: correct */
    return (uint16_t)(sign | h);
}

static inline float half_to_float_soft(uint16_t h)
{
    uint32_t sign = ((uint32_t)h & 0x8000u) << 16;
    uint32_t exp = (h >> 10) & 0x1fu;
    uint32_t man = h & 0x3ffu;
    uint32_t x;
    if (exp == 0) {
        if (man == 0) {
            x = sign;
        } else { /* subnormal: normalise */
            int e = -1;
            do {
                man <<= 1;
                e++;
            } while (!(man & 0x400u));
            x = sign | ((uint32_t)(127 - 15 - e) << 23) | ((man & 0x3ffu) << 13);
        }
    } else if (exp == 31) {
        x = sign | 0x7f800000u | (man << 13);
    } else {
        x = sign | ((exp - 15 + 127) << 23) | (man << 13);
    }
    float f;
    memcpy(&f, &x, 4);
    return f;
}

/* Half from a float. */
static inline uint16_t half_from_float(float f)
{
#if defined(__F16C__)
    return (uint16_t)_cvtss_sh(f, _MM_FROUND_TO_NEAREST_INT);
#else
    return half_from_float_soft(f);
#endif
}

/* Float from a half (exact). */
static inline float half_to_float(uint16_t h)
{
#if defined(__F16C__)
    return _cvtsh_ss(h);
#else
    return half_to_float_soft(h);
#endif
}

/* Whether half h is below zero (as half_to_float(h) < 0: -0 and NaNs are not). */
static inline int half_is_negative(uint16_t h)
{
    uint16_t a = h & 0x7fffu;
    return (h & 0x8000u) && a && a <= 0x7c00u;
}

/* Four halves at h[0..3] to four floats at f[0..3]. */
static inline void half4_to_float(const uint16_t *h, float *f)
{
#if defined(__F16C__)
    __m128i x = _mm_loadl_epi64((const __m128i *)(const void *)h);
    _mm_storeu_ps(f, _mm_cvtph_ps(x));
#else
    for (int i = 0; i < 4; i++) f[i] = half_to_float_soft(h[i]);
#endif
}

/* Four floats at f[0..3] to four halves at h[0..3]. */
static inline void float4_to_half(const float *f, uint16_t *h)
{
#if defined(__F16C__)
    __m128i x = _mm_cvtps_ph(_mm_loadu_ps(f), _MM_FROUND_TO_NEAREST_INT);
    _mm_storel_epi64((__m128i *)(void *)h, x);
#else
    for (int i = 0; i < 4; i++) h[i] = half_from_float_soft(f[i]);
#endif
}

#endif
