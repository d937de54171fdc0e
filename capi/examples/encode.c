/* encode: writes a stream from C with ac_encode, then decodes it back and measures its error.
 *
 *   encode OUT.anim
 *
 * The animation is made here: a 24 × 16 grid waving over 30 frames (two triangles per cell).
 * It is encoded three ways: quant-delta searching for the target kg=0.5 (the stream written to
 * OUT.anim), quant-delta with fixed parameters ("bits=10 block=8"), and with an unknown
 * parameter (which must fail with its message in ac_last_error). Each stream is opened from
 * memory and decoded with ac_decode_all; its KG error (100 × |A − B| / |A − per-frame
 * centroid of A|) is printed. Exit status 0 when every check holds. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <animcodec.h>

#define COLS 24
#define ROWS 16
#define FRAMES 30
#define VERTS (COLS * ROWS)
#define TRIS (2 * (COLS - 1) * (ROWS - 1))

static float positions[FRAMES * VERTS * 3];
static uint32_t triangles[TRIS * 3];

static void make_animation(void) {
    for (int t = 0; t < FRAMES; t++)
        for (int r = 0; r < ROWS; r++)
            for (int c = 0; c < COLS; c++) {
                float *p = positions + ((size_t)t * VERTS + (size_t)r * COLS + (size_t)c) * 3;
                p[0] = (float)c * 0.1f;
                p[1] = (float)r * 0.1f;
                p[2] = 0.3f * sinf(0.4f * (float)c - 0.25f * (float)t) * (float)c / COLS;
            }
    size_t k = 0;
    for (int r = 0; r + 1 < ROWS; r++)
        for (int c = 0; c + 1 < COLS; c++) {
            uint32_t a = (uint32_t)(r * COLS + c), b = a + 1, d = a + COLS, e = d + 1;
            uint32_t tri[6] = {a, b, e, a, e, d};
            memcpy(triangles + k, tri, sizeof tri);
            k += 6;
        }
}

/* KG of `decoded` against the animation, or a negative value when the stream does not decode. */
static double kg_of(const ac_buffer *stream) {
    ac_stream *s;
    if (ac_stream_open_memory(stream->data, stream->size, NULL, &s) != AC_OK) {
        fprintf(stderr, "encode: open: %s\n", ac_last_error());
        return -1;
    }
    ac_stream_info info;
    float *decoded = malloc(sizeof positions);
    double num = 0, den = 0;
    if (!decoded || ac_stream_get_info(s, &info) != AC_OK || info.frames != FRAMES || info.vertices != VERTS ||
        ac_decode_all(s, decoded, FRAMES * VERTS * 3) != AC_OK) {
        fprintf(stderr, "encode: decode: %s\n", ac_last_error());
        free(decoded);
        ac_stream_free(s);
        return -1;
    }
    for (int t = 0; t < FRAMES; t++) {
        double centre[3] = {0, 0, 0};
        const float *a = positions + (size_t)t * VERTS * 3, *b = decoded + (size_t)t * VERTS * 3;
        for (int i = 0; i < VERTS * 3; i++) centre[i % 3] += a[i] / (double)VERTS;
        for (int i = 0; i < VERTS * 3; i++) {
            num += ((double)a[i] - b[i]) * ((double)a[i] - b[i]);
            den += ((double)a[i] - centre[i % 3]) * ((double)a[i] - centre[i % 3]);
        }
    }
    free(decoded);
    ac_stream_free(s);
    return 100.0 * sqrt(num / den);
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: encode OUT.anim\n");
        return 2;
    }
    make_animation();
    int ok = 1;

    ac_buffer stream = {NULL, 0};
    if (ac_encode(positions, FRAMES, VERTS, triangles, TRIS, 30.0f, "quant-delta", NULL, "kg=0.5", &stream) != AC_OK) {
        fprintf(stderr, "encode: ac_encode (target): %s\n", ac_last_error());
        return 1;
    }
    double kg = kg_of(&stream);
    printf("target kg=0.5: %zu bytes, kg %.4f\n", stream.size, kg);
    ok &= kg >= 0 && kg <= 0.5;
    FILE *f = fopen(argv[1], "wb");
    ok &= f && fwrite(stream.data, 1, stream.size, f) == stream.size;
    if (f) ok &= fclose(f) == 0;
    ac_buffer_free(&stream);
    ok &= stream.data == NULL && stream.size == 0;
    ac_buffer_free(&stream); /* a freed buffer may be freed again */

    if (ac_encode(positions, FRAMES, VERTS, triangles, TRIS, 30.0f, "quant-delta", "bits=10 block=8", NULL, &stream) !=
        AC_OK) {
        fprintf(stderr, "encode: ac_encode (params): %s\n", ac_last_error());
        return 1;
    }
    kg = kg_of(&stream);
    printf("bits=10 block=8: %zu bytes, kg %.4f\n", stream.size, kg);
    ok &= kg >= 0 && kg <= 1.0;
    ac_buffer_free(&stream);

    ac_status bad = ac_encode(positions, FRAMES, VERTS, triangles, TRIS, 30.0f, "quant-delta", "nonsense=3", NULL, &stream);
    printf("nonsense=3: %s: %s\n", ac_status_name(bad), ac_last_error());
    ok &= bad == AC_ERR_INVALID_ARGUMENT && strstr(ac_last_error(), "nonsense") != NULL && stream.data == NULL;
    return ok ? 0 : 1;
}
