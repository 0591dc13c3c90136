/* The window's view keys: debug views 1-5, P toggles passes, +/-/0
 * exposure, H/F1/? help, C camera, Esc quit; other keys are left alone. */
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
