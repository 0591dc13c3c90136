/* disp_lag.h: the distribution of the display's lag, the time from a
 * sample's insertion at the master to the first presented frame that shows
 * it (docs/display.md, "Lag"). Each patch carries the master's clock of its
 * oldest change and the number of samples it carries; the display adds
 * them, weighted by the samples, when the frame that uploaded the patch is
 * presented. Measured from a patch's oldest change, a sample's lag is an
 * upper bound (a sample that joined the patch later waited less). A
 * histogram of 1 ms bins up to 60 s. Owns the disp_lag_ prefix. */
#ifndef CT_DISP_LAG_H
#define CT_DISP_LAG_H

#include <stdint.h>

#define DISP_LAG_BINS 60000   /* 1 ms each; later ones count in the last */

typedef struct disp_lag {
    uint64_t bins[DISP_LAG_BINS];
    uint64_t n;            /* samples counted */
    double max_ms;
} disp_lag;

/* Empties it. */
void disp_lag_reset(disp_lag *l);

/* Counts `weight` samples with this lag (negative lags, from clock
 * offset noise, count as 0). */
void disp_lag_add(disp_lag *l, double lag_ms, uint64_t weight);

/* The lag (ms) under which a fraction q of the counted samples lie; 0 when
 * none were counted. */
double disp_lag_quantile(const disp_lag *l, double q);

#endif
