/* OSMesa backend: Mesa's off-screen software context, GL 3.3 core through
 * OSMesaCreateContextAttribs. The context renders into a client buffer that
 * corrtex never reads: all drawing goes to the compositor's FBOs. */
#include "display/gl_load.h"

#include <GL/osmesa.h>
#include <stdlib.h>

#include "display/gl_backend_impl.h"

typedef struct osm_state {
    OSMesaContext ctx;
    unsigned char *buffer;
} osm_state;

static gl_proc getproc(const char *name)
{
    return (gl_proc)OSMesaGetProcAddress(name);
}

static void osm_close(gl_backend *b)
{
    osm_state *s = b->state;
    if (!s) return;
    if (s->ctx) {
        OSMesaMakeCurrent(NULL, NULL, GL_UNSIGNED_BYTE, 0, 0);
        OSMesaDestroyContext(s->ctx);
    }
    free(s->buffer);
    free(s);
    b->state = NULL;
}

static const gl_backend_ops osm_ops = {NULL, NULL, NULL, osm_close};

int gl_backend_open_osmesa(gl_backend *b, ct_error *err)
{
    osm_state *s = calloc(1, sizeof *s);
    if (!s) return ct_fail(err, CT_ENOMEM, "osmesa: out of memory");
    b->state = s;
    b->ops = &osm_ops;
    const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA,
                           OSMESA_DEPTH_BITS, 24,
                           OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION, 3,
                           OSMESA_CONTEXT_MINOR_VERSION, 3,
                           0};
    s->ctx = OSMesaCreateContextAttribs(attribs, NULL);
    if (!s->ctx) {
        osm_close(b);
        return ct_fail(err, CT_ESYS, "osmesa: OSMesaCreateContextAttribs failed for GL 3.3 core");
    }
    /* A 1x1 colour buffer: the window-system framebuffer is never drawn to. */
    s->buffer = calloc(4, 1);
    if (!s->buffer || !OSMesaMakeCurrent(s->ctx, s->buffer, GL_UNSIGNED_BYTE, 1, 1)) {
        osm_close(b);
        return ct_fail(err, CT_ESYS, "osmesa: OSMesaMakeCurrent failed");
    }
    int rc = gl_load(getproc, "osmesa", err);
    if (rc) osm_close(b);
    return rc;
}
