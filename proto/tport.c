/* tport.c: the reply FIFO of the in-process tracer ports (tport.h). */
#include "proto/tport.h"

#include <stdlib.h>

int tport_fifo_push(tport_fifo *f, int lane, uint64_t batch, ct_sample *s, uint32_t n, ct_error *err)
{
    if (f->n == f->cap) {
        size_t cap = f->cap ? 2 * f->cap : 16;
        tport_reply *q = malloc(cap * sizeof *q);
        if (!q) {
            free(s);
            return ct_fail(err, CT_ENOMEM, "tracer port: out of memory queueing an answer");
        }
        for (size_t i = 0; i < f->n; i++) q[i] = f->q[(f->head + i) % f->cap];
        free(f->q);
        f->q = q;
        f->cap = cap;
        f->head = 0;
    }
    f->q[(f->head + f->n) % f->cap] = (tport_reply){.lane = lane, .batch = batch, .samples = s, .n = n};
    f->n++;
    return CT_OK;
}

int tport_fifo_pop(tport_fifo *f, tport_reply *out)
{
    free(f->last);
    f->last = NULL;
    if (!f->n) return 0;
    *out = f->q[f->head];
    f->head = (f->head + 1) % f->cap;
    f->n--;
    f->last = (ct_sample *)out->samples;
    return 1;
}

void tport_fifo_free(tport_fifo *f)
{
    for (size_t i = 0; i < f->n; i++) free((ct_sample *)f->q[(f->head + i) % f->cap].samples);
    free(f->q);
    free(f->last);
    f->q = NULL;
    f->last = NULL;
    f->n = f->cap = f->head = 0;
}
