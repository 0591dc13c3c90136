/* Half floats (common/half.h): the instruction path (F16C, when the build
 * has it) gives the same bits as the portable integer code, for every half
 * and for floats around every rounding boundary. */
#include <criterion/criterion.h>
#include <math.h>
#include <string.h>

#include "common/half.h"
#include "common/rng.h"

static float from_bits(uint32_t x)
{
    float f;
    memcpy(&f, &x, 4);
    return f;
}

Test(half, every_half_converts_exactly_both_ways)
{
    for (uint32_t h = 0; h < 65536; h++) {
        float f = half_to_float((uint16_t)h), g = half_to_float_soft((uint16_t)h);
        if (isnan(g)) {
            /* a NaN stays a NaN (F16C quiets a signalling one) */
            cr_assert(isnan(f), "half 0x%04x", h);
            continue;
        }
        cr_assert_eq(memcmp(&f, &g, 4), 0, "half 0x%04x: %a vs %a", h, (double)f, (double)g);
        cr_assert_eq(half_from_float(f), h, "half 0x%04x -> %a -> 0x%04x", h, (double)f, half_from_float(f));
    }
}

Test(half, rounding_matches_the_portable_code)
{
    /* every float halfway and next to halfway between two halves, plus
     * random bit patterns (NaNs, subnormals, overflow included) */
    for (uint32_t h = 0; h < 0x7c00u; h++) {
        float a = half_to_float_soft((uint16_t)h), b = half_to_float_soft((uint16_t)(h + 1));
        float mid = a + (b - a) * 0.5f;
        uint32_t mb;
        memcpy(&mb, &mid, 4);
        for (int d = -1; d <= 1; d++) {
            float f = from_bits(mb + (uint32_t)d);
            cr_assert_eq(half_from_float(f), half_from_float_soft(f), "%a", (double)f);
            cr_assert_eq(half_from_float(-f), half_from_float_soft(-f), "%a", (double)-f);
        }
    }
    ct_rng r = rng_make(3, 0, 0, 0);
    for (int i = 0; i < 1000000; i++) {
        float f = from_bits(rng_u32(&r));
        uint16_t a = half_from_float(f), b = half_from_float_soft(f);
        if (isnan(f)) {
            cr_assert((a & 0x7c00u) == 0x7c00u && (a & 0x3ffu), "%a: 0x%04x is no NaN", (double)f, a);
            continue;
        }
        cr_assert_eq(a, b, "%a: 0x%04x vs 0x%04x", (double)f, a, b);
    }
}

Test(half, four_at_a_time_equals_one_at_a_time)
{
    const float f[4] = {0.1f, -3.5f, 65519.0f, 1e-6f};
    uint16_t h[4];
    float back[4];
    float4_to_half(f, h);
    half4_to_float(h, back);
    for (int i = 0; i < 4; i++) {
        cr_assert_eq(h[i], half_from_float(f[i]));
        cr_assert_eq(back[i], half_to_float(h[i]));
    }
}

Test(half, negative_means_below_zero)
{
    for (uint32_t h = 0; h < 65536; h++) {
        float f = half_to_float_soft((uint16_t)h);
        cr_assert_eq(half_is_negative((uint16_t)h), f < 0.0f, "half 0x%04x (%g)", h, (double)f);
    }
}
