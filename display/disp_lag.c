/* disp_lag.c: the lag histogram (disp_lag.h). */
#include "display/disp_lag.h"

#include <string.h>

void disp_lag_reset(disp_lag *l)
{
    memset(l, 0, sizeof *l);
}

void disp_lag_add(disp_lag *l, double lag_ms, uint64_t weight)
{
    if (!weight) return;
    if (!(lag_ms > 0.0)) lag_ms = 0.0;
    size_t b = lag_ms >= DISP_LAG_BINS - 1 ? DISP_LAG_BINS - 1 : (size_t)lag_ms;
    l->bins[b] += weight;
    l->n += weight;
    if (lag_ms > l->max_ms) l->max_ms = lag_ms;
}

double disp_lag_quantile(const disp_lag *l, double q)
{
    if (!l->n) return 0.0;
    double want = q * (double)l->n;
    uint64_t acc = 0;
    for (size_t b = 0; b < DISP_LAG_BINS; b++) {
        acc += l->bins[b];
        /* the bin's upper edge: what a sample in it waited at most */
        if ((double)acc >= want && acc) return (double)(b + 1);
    }
    return (double)DISP_LAG_BINS;
}
