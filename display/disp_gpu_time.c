/* disp_gpu_time.c: GL timer queries per display stage (disp_gpu_time.h). */
#include "display/disp_gpu_time.h"

#include <stdbool.h>
#include <stdlib.h>

#include "display/gl_load.h"

/* Queries in flight at most: a GPU runs a frame or two behind the CPU, and
 * a frame has three stages; more pending than this means the GPU is far
 * behind, and timing it further would only grow the list. */
#define SLOTS 48

typedef struct slot {
    GLuint q;
    disp_gt_stage stage;
    bool busy;
    bool drop;           /* the first pair's: not counted */
} slot;

struct disp_gpu_time {
    slot s[SLOTS];
    int open;                        /* the slot between begin and end, -1 */
    bool began;                      /* a pair began: the ones after it count */
    uint64_t ns[DISP_GT_STAGES], n[DISP_GT_STAGES], untimed;
};

int disp_gpu_time_new(disp_gpu_time **out, ct_error *err)
{
    disp_gpu_time *t = calloc(1, sizeof *t);
    if (!t) return ct_fail(err, CT_ENOMEM, "out of memory for GPU timers");
    GLuint q[SLOTS];
    gl.GenQueries(SLOTS, q);
    for (int i = 0; i < SLOTS; i++) t->s[i].q = q[i];
    t->open = -1;
    /* Mesa (22.3, llvmpipe and OSMesa) answers the first elapsed time query
     * that holds any work with the host's uptime (its start was never
     * stamped): the first pair's result is not counted. (Spending a query
     * on a clear before any stage needs a framebuffer, which a surfaceless
     * context does not have.) */
    int rc = gl_check("creating timer queries", err);
    if (rc) {
        disp_gpu_time_free(t);
        return rc;
    }
    *out = t;
    return CT_OK;
}

void disp_gpu_time_begin(disp_gpu_time *t, disp_gt_stage s)
{
    if (!t || t->open >= 0) return;
    for (int i = 0; i < SLOTS; i++)
        if (!t->s[i].busy) {
            t->s[i].busy = true;
            t->s[i].stage = s;
            t->s[i].drop = !t->began;
            t->began = true;
            t->open = i;
            gl.BeginQuery(GL_TIME_ELAPSED, t->s[i].q);
            return;
        }
    t->untimed++;
}

void disp_gpu_time_end(disp_gpu_time *t)
{
    if (!t || t->open < 0) return;
    gl.EndQuery(GL_TIME_ELAPSED);
    t->open = -1;
}

/* Reads slot i's result when ready (or, with wait, once it is). */
static void collect(disp_gpu_time *t, int i, bool wait)
{
    slot *x = &t->s[i];
    if (!x->busy || i == t->open) return;
    GLint ready = 0;
    if (!wait) gl.GetQueryObjectiv(x->q, GL_QUERY_RESULT_AVAILABLE, &ready);
    if (!wait && !ready) return;
    GLuint64 ns = 0;
    gl.GetQueryObjectui64v(x->q, GL_QUERY_RESULT, &ns);
    x->busy = false;
    if (x->drop) return;
    /* (a later query answering as Mesa's first does: no stage takes a
     * minute) */
    if (ns > 60000000000ull) {
        t->untimed++;
        return;
    }
    t->ns[x->stage] += ns;
    t->n[x->stage]++;
}

void disp_gpu_time_poll(disp_gpu_time *t)
{
    if (!t) return;
    for (int i = 0; i < SLOTS; i++) collect(t, i, false);
}

void disp_gpu_time_totals(disp_gpu_time *t, double ms[DISP_GT_STAGES], uint64_t n[DISP_GT_STAGES],
                          uint64_t *untimed)
{
    if (t) {
        disp_gpu_time_end(t);
        gl.Finish();
        for (int i = 0; i < SLOTS; i++) collect(t, i, true);
    }
    for (int s = 0; s < DISP_GT_STAGES; s++) {
        ms[s] = t ? (double)t->ns[s] / 1e6 : 0.0;
        n[s] = t ? t->n[s] : 0;
    }
    *untimed = t ? t->untimed : 0;
}

void disp_gpu_time_free(disp_gpu_time *t)
{
    if (!t) return;
    GLuint q[SLOTS];
    for (int i = 0; i < SLOTS; i++) q[i] = t->s[i].q;
    gl.DeleteQueries(SLOTS, q);
    free(t);
}
