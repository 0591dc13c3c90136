/* bitrow.h: rows of bits in 64-bit words, set by ranges and read back as
 * runs of set bits: the tile maps of texels changed but not yet sent
 * (master/ctex_dirty.h) or not yet uploaded (display/disp_inbox.h). Bits
 * past a row's last used column are never set. Owns the bitrow_ prefix. */
#ifndef CT_COMMON_BITROW_H
#define CT_COMMON_BITROW_H

#include <stdbool.h>
#include <stdint.h>

/* Words for a row of n bits. */
static inline int bitrow_words(int n)
{
    return (n + 63) >> 6;
}

/* Sets bits a..b (inclusive, a <= b). */
static inline void bitrow_set(uint64_t *row, int a, int b)
{
    int wa = a >> 6, wb = b >> 6;
    uint64_t ma = ~0ull << (a & 63), mb = ~0ull >> (63 - (b & 63));
    if (wa == wb) {
        row[wa] |= ma & mb;
        return;
    }
    row[wa] |= ma;
    for (int w = wa + 1; w < wb; w++) row[w] = ~0ull;
    row[wb] |= mb;
}

/* Clears bits a .. a + n - 1. */
static inline void bitrow_clear(uint64_t *row, int a, int n)
{
    for (int i = a; i < a + n; i++) row[i >> 6] &= ~(1ull << (i & 63));
}

/* Whether any bit of a row of `words` words is set. */
static inline bool bitrow_any(const uint64_t *row, int words)
{
    for (int w = 0; w < words; w++)
        if (row[w]) return true;
    return false;
}

/* The first run of set bits at or after bit `from` of a row of n bits:
 * its first bit, and its length in *len (0 when there is none). */
static inline int bitrow_next_run(const uint64_t *row, int n, int from, int *len)
{
    *len = 0;
    const int words = bitrow_words(n);
    if (from >= n) return 0;
    int w = from >> 6;
    uint64_t x = row[w] & (~0ull << (from & 63));
    while (!x) {
        if (++w == words) return 0;
        x = row[w];
    }
    const int a = (w << 6) + __builtin_ctzll(x);
    int b;
    uint64_t y = ~row[w] & (~0ull << (a & 63));
    while (!y && ++w < words) y = ~row[w];
    b = y ? (w << 6) + __builtin_ctzll(y) : n;
    if (b > n) b = n;
    *len = b - a;
    return a;
}

#endif
