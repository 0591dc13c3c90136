/* The window's view keys: debug views 1-5, P toggles passes, +/-/0
 * exposure, H/F1/? help, C camera, Esc quit; other keys are left alone;
 * presses queue from one poll to the next (display/gl_backend.h). */
#include <criterion/criterion.h>
#include <string.h>

#include "display/disp_keys.h"
#include "display/gl_backend.h"

Test(disp_keys, view_pass_and_exposure_keys)
{
    disp_render_opts o = {1, DISP_VIEW_FULL, 0.0f, false, false, DISP_KEPT_AUTO};
    const disp_view views[5] = {DISP_VIEW_FULL, DISP_VIEW_RADIOSITY, DISP_VIEW_CORRECTIONS,
                                DISP_VIEW_ASSIGNMENT, DISP_VIEW_SAMPLES};
    for (int k = 0; k < 5; k++) {
        cr_expect_eq(disp_keys_apply('1' + k, &o), DISP_KEY_CHANGED);
        cr_expect_eq(o.view, views[k], "key %c", '1' + k);
    }
    cr_expect_eq(disp_keys_apply('6', &o), DISP_KEY_NONE);
    cr_expect_eq(o.view, DISP_VIEW_SAMPLES);
    disp_keys_apply('P', &o);
    cr_expect_eq(o.passes, 3);
    disp_keys_apply('P', &o);
    cr_expect_eq(o.passes, 1);
    disp_keys_apply('+', &o);
    disp_keys_apply('+', &o);
    cr_expect_float_eq(o.exposure, 2 * DISP_EXPOSURE_STEP, 1e-6f);
    disp_keys_apply('-', &o);
    cr_expect_float_eq(o.exposure, DISP_EXPOSURE_STEP, 1e-6f);
    for (int i = 0; i < 400; i++) disp_keys_apply('+', &o);
    cr_expect_float_eq(o.exposure, DISP_EXPOSURE_MAX, 0, "exposure %g", (double)o.exposure);
    for (int i = 0; i < 800; i++) disp_keys_apply('-', &o);
    cr_expect_float_eq(o.exposure, -DISP_EXPOSURE_MAX, 0, "exposure %g", (double)o.exposure);
    disp_keys_apply('0', &o);
    cr_expect_float_eq(o.exposure, 0.0f, 0);
    cr_expect_eq(disp_keys_apply('H', &o), DISP_KEY_HELP);
    cr_expect_eq(disp_keys_apply(GL_KEY_F1, &o), DISP_KEY_HELP);
    cr_expect_eq(disp_keys_apply('C', &o), DISP_KEY_CAMERA);
    cr_expect_eq(disp_keys_apply(GL_KEY_ESCAPE, &o), DISP_KEY_QUIT);
    disp_render_opts before = o;
    cr_expect_eq(disp_keys_apply('W', &o), DISP_KEY_NONE, "camera keys are not view keys");
    cr_expect_eq(memcmp(&before, &o, sizeof o), 0);
}

/* Presses that outnumber one poll's gl_input wait for the next poll, in
 * order (they were dropped past 32); past the queue's capacity they are
 * dropped and counted. */
Test(disp_keys, presses_beyond_one_poll_wait_for_the_next)
{
    static gl_press_queue q;
    int n = 3 * GL_INPUT_MAX_PRESSES + 5;
    for (int i = 0; i < n; i++) cr_assert(gl_press_push(&q, i % 2 ? '+' : 'A' + i % 26));
    int seen = 0, polls = 0;
    for (;;) {
        gl_input in;
        memset(&in, 0, sizeof in);
        gl_press_take(&q, &in);
        if (in.npresses == 0) break;
        polls++;
        cr_assert_leq(in.npresses, GL_INPUT_MAX_PRESSES);
        for (int j = 0; j < in.npresses; j++, seen++)
            cr_assert_eq(in.presses[j], seen % 2 ? '+' : 'A' + seen % 26, "press %d out of order", seen);
    }
    cr_expect_eq(seen, n);
    cr_expect_eq(polls, 4);
    /* full: the surplus is counted, the queue keeps its oldest */
    for (int i = 0; i < GL_PRESS_QUEUE_CAP; i++) cr_assert(gl_press_push(&q, 'P'));
    cr_expect_not(gl_press_push(&q, 'Q'));
    cr_expect_eq(q.dropped, 1);
    gl_input in;
    memset(&in, 0, sizeof in);
    gl_press_take(&q, &in);
    cr_expect_eq(in.npresses, GL_INPUT_MAX_PRESSES);
    cr_expect_eq(in.presses[0], 'P');
    cr_expect(gl_press_push(&q, 'Q'), "room again after a poll");
}
