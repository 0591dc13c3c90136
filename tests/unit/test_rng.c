/* Unit tests of common/rng: PCG32 output, streams as a pure function of
 * (seed, ids), rough uniformity, and rng_below's range. */
#include <criterion/criterion.h>

#include <math.h>
#include <stdint.h>

#include "common/rng.h"

Test(rng, pcg32_reference_sequence)
{
    /* pcg32_srandom_r(42, 54) from the PCG reference implementation
     * (pcg32-demo), set up by hand: its first outputs are published. */
    ct_rng r;
    r.state = 0;
    r.inc = (54u << 1u) | 1u;
    rng_u32(&r);
    r.state += 42u;
    rng_u32(&r);
    const uint32_t want[6] = {0xa15c02b7u, 0x7b47f409u, 0xba1d3330u, 0x83d2f293u, 0xbfa4784bu, 0xcbed606eu};
    for (int i = 0; i < 6; i++) {
        uint32_t got = rng_u32(&r);
        cr_assert_eq(got, want[i], "output %d: 0x%08x, expected 0x%08x", i, got, want[i]);
    }
}

Test(rng, same_ids_same_stream)
{
    ct_rng a = rng_make(7, 123456789, 3, 2), b = rng_make(7, 123456789, 3, 2);
    for (int i = 0; i < 10000; i++) cr_assert_eq(rng_u32(&a), rng_u32(&b), "output %d differs", i);
}

/* Number of equal outputs among the first n of two streams. */
static int equal_outputs(ct_rng a, ct_rng b, int n)
{
    int eq = 0;
    for (int i = 0; i < n; i++) eq += rng_u32(&a) == rng_u32(&b);
    return eq;
}

Test(rng, different_ids_different_streams)
{
    ct_rng base = rng_make(1, 10, 20, 30);
    cr_assert_leq(equal_outputs(base, rng_make(2, 10, 20, 30), 1000), 1, "seed");
    cr_assert_leq(equal_outputs(base, rng_make(1, 11, 20, 30), 1000), 1, "id a");
    cr_assert_leq(equal_outputs(base, rng_make(1, 10, 21, 30), 1000), 1, "id b");
    cr_assert_leq(equal_outputs(base, rng_make(1, 10, 20, 31), 1000), 1, "id c");
    /* Swapped ids are different streams too (the ids are not just summed). */
    cr_assert_leq(equal_outputs(rng_make(1, 20, 10, 30), rng_make(1, 10, 20, 30), 1000), 1, "swap");
    /* No stream is a shifted copy of its neighbour: compare with offsets. */
    ct_rng a = rng_make(0, 0, 0, 0), b = rng_make(0, 1, 0, 0);
    uint32_t xa[64], xb[64];
    for (int i = 0; i < 64; i++) { xa[i] = rng_u32(&a); xb[i] = rng_u32(&b); }
    int hits = 0;
    for (int i = 0; i < 64; i++)
        for (int j = 0; j < 64; j++) hits += xa[i] == xb[j];
    cr_assert_leq(hits, 1);
}

Test(rng, neighbouring_streams_are_uncorrelated)
{
    /* The first float of 20000 consecutive request ids is uniform: mean 1/2,
     * variance 1/12, and the lag-1 correlation across ids is near 0. */
    int n = 20000;
    double s = 0, s2 = 0, lag = 0, prev = 0;
    for (int i = 0; i < n; i++) {
        ct_rng r = rng_make(99, (uint64_t)i, 0, 0);
        double x = rng_float(&r);
        s += x; s2 += x * x;
        if (i) lag += (x - 0.5) * (prev - 0.5);
        prev = x;
    }
    double mean = s / n, var = s2 / n - mean * mean;
    /* Standard error of the mean: sqrt(1/12 / n) = 0.002; allow 5 sigma. */
    cr_assert_float_eq(mean, 0.5, 0.01);
    cr_assert_float_eq(var, 1.0 / 12.0, 0.005);
    cr_assert_float_eq(lag / (n - 1) * 12.0, 0.0, 0.04);
}

Test(rng, float_uniformity_chi_square)
{
    ct_rng r = rng_make(5, 6, 7, 8);
    enum { BINS = 32, N = 320000 };
    int count[BINS] = {0};
    double dmin = 1, dmax = 0;
    for (int i = 0; i < N; i++) {
        float f = rng_float(&r);
        cr_assert(f >= 0.0f && f < 1.0f, "%g outside [0,1)", (double)f);
        count[(int)(f * BINS)]++;
        double d = rng_double(&r);
        cr_assert(d >= 0.0 && d < 1.0);
        if (d < dmin) dmin = d;
        if (d > dmax) dmax = d;
    }
    double chi2 = 0, expect = (double)N / BINS;
    for (int b = 0; b < BINS; b++) chi2 += (count[b] - expect) * (count[b] - expect) / expect;
    /* 31 degrees of freedom: P(chi2 > 61.1) = 0.001. */
    cr_assert_lt(chi2, 61.1, "chi-square %g", chi2);
    cr_assert_lt(dmin, 1e-4);
    cr_assert_gt(dmax, 1.0 - 1e-4);
}

Test(rng, below_range_and_uniformity)
{
    ct_rng r = rng_make(3, 1, 4, 1);
    const uint32_t ns[] = {1, 2, 3, 7, 10, 1000, 0x80000001u, 0xffffffffu};
    for (size_t k = 0; k < sizeof ns / sizeof ns[0]; k++)
        for (int i = 0; i < 20000; i++) {
            uint32_t x = rng_below(&r, ns[k]);
            cr_assert_lt(x, ns[k], "rng_below(%u) gave %u", ns[k], x);
        }
    /* n = 3: each value about a third of the time. */
    int c[3] = {0, 0, 0};
    for (int i = 0; i < 30000; i++) c[rng_below(&r, 3)]++;
    for (int v = 0; v < 3; v++) cr_assert(c[v] > 9500 && c[v] < 10500, "value %d: %d of 30000", v, c[v]);
    /* n = 2^33 / 3 is where modulo bias is worst: a plain x % n would give
     * the lower half [0, n/2) two thirds of the draws; unbiased, one half. */
    const uint32_t big = 0xaaaaaaabu;
    int lower = 0;
    for (int i = 0; i < 30000; i++) lower += rng_below(&r, big) < big / 2;
    cr_assert(lower > 14400 && lower < 15600, "%d of 30000 in the lower half", lower);
}
