/* samples_check.c: helper of tests/e2e/render_samples_view.sh (built by it
 * with cc and libpng). Reads the samples-view frame VIEW.png and a frame
 * MASK.png of the same camera showing the scene without samples, and prints
 * the pixels in the sample colour (R >= 250, 190 <= G <= 235, B <= 40:
 * DISP_SAMPLE_COLOR at any exposure), how many lie on geometry and how many
 * on the background, and the geometry pixel count. Geometry is the bounding
 * rectangle of the mask's non-black pixels, widened by one pixel (a sample
 * jittered inside an edge pixel may hit geometry that misses the pixel
 * centre): right for a closed box seen from outside through its open side,
 * like cornell, whose unlit or mirror surfaces may be black.
 * Exit status 2 on unreadable input. */
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static unsigned char *load(const char *path, int *w, int *h)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path)) {
        fprintf(stderr, "%s: %s\n", path, im.message);
        return NULL;
    }
    im.format = PNG_FORMAT_RGB;
    unsigned char *px = malloc(PNG_IMAGE_SIZE(im));
    if (!px || !png_image_finish_read(&im, NULL, px, 0, NULL)) {
        fprintf(stderr, "%s: %s\n", path, px ? im.message : "out of memory");
        free(px);
        return NULL;
    }
    *w = (int)im.width;
    *h = (int)im.height;
    return px;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: samples_check VIEW.png MASK.png\n");
        return 2;
    }
    int w, h, mw, mh;
    unsigned char *v = load(argv[1], &w, &h), *m = load(argv[2], &mw, &mh);
    if (!v || !m) return 2;
    if (w != mw || h != mh) {
        fprintf(stderr, "%s is %dx%d, %s is %dx%d\n", argv[1], w, h, argv[2], mw, mh);
        return 2;
    }
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const unsigned char *q = m + 3 * ((size_t)y * w + x);
            if (!(q[0] || q[1] || q[2])) continue;
            if (x < x0) x0 = x;
            if (x > x1) x1 = x;
            if (y < y0) y0 = y;
            if (y > y1) y1 = y;
        }
    long geometry = x1 < 0 ? 0 : (long)(x1 - x0 + 1) * (y1 - y0 + 1);
    long dots = 0, on_geometry = 0, on_background = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const unsigned char *p = v + 3 * ((size_t)y * w + x);
            if (!(p[0] >= 250 && p[1] >= 190 && p[1] <= 235 && p[2] <= 40)) continue;
            dots++;
            if (x >= x0 - 1 && x <= x1 + 1 && y >= y0 - 1 && y <= y1 + 1) on_geometry++;
            else on_background++;
        }
    printf("metric: %ld sample-coloured pixels: %ld on geometry, %ld on background; geometry %ld of %d pixels\n", dots,
           on_geometry, on_background, geometry, w * h);
    printf("counts %ld %ld %ld %ld %d\n", dots, on_geometry, on_background, geometry, w * h);
    free(v);
    free(m);
    return 0;
}
