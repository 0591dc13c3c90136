/* The replay port (master/tport_replay.h) that feeds the saturation
 * benchmark: a request gets its recorded sample back, with the view's
 * epoch, whether the recording's ids are consecutive (looked up by index)
 * or not (binary search); a request the recording does not hold, or holds
 * at another image position, is an error naming it. */
#include <criterion/criterion.h>
#include <stdlib.h>
#include <string.h>

#include "master/tport_replay.h"

static ct_error err;

/* n recorded samples with ids first, first + step, ..., shuffled. */
static ct_sample *recording(size_t n, uint64_t first, uint64_t step)
{
    ct_sample *s = calloc(n, sizeof *s);
    for (size_t i = 0; i < n; i++) {
        s[i].request_id = first + i * step;
        s[i].px = (float)(i % 97) + 0.25f;
        s[i].py = (float)(i / 97) + 0.75f;
        s[i].l_hq = v3((float)i, 0.0f, 1.0f);
        s[i].epoch = 3;
    }
    for (size_t i = n - 1; i > 0; i--) {   /* a fixed shuffle: recordings come in answer order */
        size_t j = (i * 7919u) % (i + 1);
        ct_sample t = s[i];
        s[i] = s[j];
        s[j] = t;
    }
    return s;
}

static ct_request request_for(uint64_t first, uint64_t step, size_t i)
{
    return (ct_request){.id = first + i * step, .px = (float)(i % 97) + 0.25f, .py = (float)(i / 97) + 0.75f};
}

static void answers_by_id(uint64_t first, uint64_t step)
{
    enum { N = 5000 };
    ct_sample *rec = recording(N, first, step);
    tport *p;
    cr_assert_eq(tport_replay_new(rec, N, 2, &p, &err), 0, "%s", err.msg);
    free(rec);   /* the port keeps a copy */
    tport_view v = {.epoch = 9, .width = 97, .height = 64};
    const size_t pick[] = {0, 1, 2, 4998, 4999, 2500, 17};
    ct_request req[7];
    for (int k = 0; k < 7; k++) req[k] = request_for(first, step, pick[k]);
    cr_assert_eq(p->ops->submit(p, 1, 42, &v, req, 7, &err), 0, "%s", err.msg);
    tport_reply out;
    cr_assert_eq(p->ops->poll(p, &out, &err), 1);
    cr_assert_eq(out.lane, 1);
    cr_assert_eq(out.batch, 42);
    cr_assert_eq(out.n, 7);
    for (int k = 0; k < 7; k++) {
        cr_assert_eq(out.samples[k].request_id, req[k].id);
        cr_assert_eq(out.samples[k].l_hq.x, (float)pick[k], "request %d: the sample of another request", k);
        cr_assert_eq(out.samples[k].epoch, 9, "the view's epoch");
    }
    cr_assert_eq(p->ops->poll(p, &out, &err), 0, "one batch, one answer");
    /* an id outside the recording, and one inside it between two ids */
    ct_request bad = request_for(first, step, N);
    cr_assert_lt(p->ops->submit(p, 0, 43, &v, &bad, 1, &err), 0);
    cr_assert(strstr(err.msg, "not in the recording"), "%s", err.msg);
    if (step > 1) {
        bad = request_for(first, step, 10);
        bad.id += 1;
        cr_assert_lt(p->ops->submit(p, 0, 44, &v, &bad, 1, &err), 0);
    }
    bad = (ct_request){.id = first - 1};
    cr_assert_lt(p->ops->submit(p, 0, 45, &v, &bad, 1, &err), 0, "an id under the recording's first");
    /* the right id at another position */
    bad = request_for(first, step, 10);
    bad.px += 1.0f;
    cr_assert_lt(p->ops->submit(p, 0, 46, &v, &bad, 1, &err), 0);
    p->ops->close(p, 0.0);
}

Test(tport_replay, consecutive_ids_are_found_by_index)
{
    answers_by_id(1000, 1);
}

Test(tport_replay, gaps_in_the_ids_fall_back_to_the_search)
{
    answers_by_id(1000, 3);
}
