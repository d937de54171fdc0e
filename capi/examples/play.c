/* play IN.anim OUT.pc2: opens an animcodec stream, prints its header, decodes every frame with
 * ac_decode_frame (random access; frames in order reuse the packet the library keeps) and
 * writes them as a PC2 point cache ("POINTCACHE2", the layout `animcodec decode` writes).
 *
 * Build: cc play.c $(pkg-config --cflags --libs animcodec) -o play   (capi/README.md)
 * Exit status: 0 on success, 1 on any failure (with the library's message on stderr). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "animcodec.h"

static int fail(const char *what) {
    fprintf(stderr, "play: %s: %s\n", what, ac_last_error());
    return 1;
}

/* Little-endian writes, whatever the host's byte order. */
static int put_u32(FILE *f, uint32_t v) {
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16), (unsigned char)(v >> 24)};
    return fwrite(b, 1, 4, f) == 4;
}

static int put_f32(FILE *f, float x) {
    uint32_t v;
    memcpy(&v, &x, 4);
    return put_u32(f, v);
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: play IN.anim OUT.pc2\n");
        return 2;
    }
    ac_stream *stream = NULL;
    if (ac_stream_open_file(argv[1], NULL, &stream) != AC_OK) return fail("open");
    ac_stream_info info;
    if (ac_stream_get_info(stream, &info) != AC_OK) return fail("info");
    printf("%s: codec %s (%s) v%u, container v%u, %zu frames x %zu vertices, %zu triangles, %g fps, "
           "%llu bytes, %zu packets (%zu keyframes, at most %zu frames each)\n",
           argv[1], info.codec, info.fourcc, info.codec_version, info.container_version, info.frames,
           info.vertices, info.triangles, (double)info.frame_rate, (unsigned long long)info.stream_bytes,
           info.packets, info.keyframes, info.max_packet_frames);

    size_t n_idx = info.triangles * 3;
    uint32_t *triangles = malloc((n_idx ? n_idx : 1) * sizeof *triangles);
    if (!triangles) return 1;
    if (ac_copy_triangles(stream, triangles, n_idx) != AC_OK) return fail("triangles");
    free(triangles);

    FILE *out = fopen(argv[2], "wb");
    if (!out) {
        perror(argv[2]);
        return 1;
    }
    /* PC2 header: signature, version 1, vertices, start frame 0.0, sample rate 1.0, frames. */
    int ok = fwrite("POINTCACHE2\0", 1, 12, out) == 12 && put_u32(out, 1) && put_u32(out, (uint32_t)info.vertices)
             && put_f32(out, 0.0f) && put_f32(out, 1.0f) && put_u32(out, (uint32_t)info.frames);
    size_t n = info.vertices * 3;
    float *xyz = malloc((n ? n : 1) * sizeof *xyz);
    if (!xyz) return 1;
    for (size_t t = 0; ok && t < info.frames; t++) {
        if (ac_decode_frame(stream, t, xyz, n) != AC_OK) {
            fclose(out);
            remove(argv[2]);
            return fail("decode");
        }
        for (size_t i = 0; ok && i < n; i++) ok = put_f32(out, xyz[i]);
    }
    free(xyz);
    ac_stream_free(stream);
    if (fclose(out) != 0 || !ok) {
        perror(argv[2]);
        remove(argv[2]);
        return 1;
    }
    return 0;
}
