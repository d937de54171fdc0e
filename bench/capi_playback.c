/* capi_playback: per-frame decode cost through the C library, one row per stream.
 *
 *   capi_playback A.anim [B.anim …]
 *
 * Columns (microseconds per frame, best of 3 runs each):
 *   bulk     ac_decode_all / frames
 *   player   an ac_player decoding frames 0..n-1 in order
 *   random   ac_decode_frame on a shared stream, frames in a scrambled order (each request
 *            lands in another packet whenever the stream has more than one)
 *   cold     ac_decode_frame of one frame on a freshly opened stream (open + decode)
 *   memcpy   copying one decoded frame
 * and random/player, the cost of random access relative to sequential playback.
 * Run by bench/capi_playback.sh, which builds it and makes the streams. */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "animcodec.h"

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void check(ac_status s, const char *what) {
    if (s != AC_OK) {
        fprintf(stderr, "capi_playback: %s: %s\n", what, ac_last_error());
        exit(1);
    }
}

/* A stride near n / golden ratio that is coprime with n: frames visited t, t + s, t + 2s, …
 * (mod n) cover every frame once, consecutive requests far apart (other packets). */
static size_t coprime_stride(size_t n) {
    if (n < 3) return 1;
    for (size_t s = (size_t)(n * 0.618) + 1;; s++) {
        size_t a = s, b = n;
        while (b) {
            size_t t = a % b;
            a = b;
            b = t;
        }
        if (a == 1) return s;
    }
}

int main(int argc, char **argv) {
    printf("| stream | codec | frames | vertices | packets (keyframes) | frames/packet | bulk µs | player µs | random µs | cold µs | "
           "memcpy µs | random/player |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int a = 1; a < argc; a++) {
        double best[5] = {1e30, 1e30, 1e30, 1e30, 1e30};
        ac_stream_info info;
        for (int run = 0; run < 3; run++) {
            ac_stream *s;
            check(ac_stream_open_file(argv[a], NULL, &s), argv[a]);
            check(ac_stream_get_info(s, &info), "info");
            size_t n = info.frames, v3 = info.vertices * 3;
            float *all = malloc(n * v3 * sizeof(float));
            float *one = malloc(v3 * sizeof(float));
            float *copy = malloc(v3 * sizeof(float));
            double t0 = now();
            check(ac_decode_all(s, all, n * v3), "all");
            double bulk = (now() - t0) / n;
            ac_player *p;
            check(ac_player_new(s, &p), "player");
            t0 = now();
            for (size_t t = 0; t < n; t++) check(ac_player_decode_frame(p, t, one, v3), "player frame");
            double player = (now() - t0) / n;
            ac_player_free(p);
            size_t stride = coprime_stride(n);
            t0 = now();
            for (size_t i = 0; i < n; i++) check(ac_decode_frame(s, (i * stride) % n, one, v3), "frame");
            double random = (now() - t0) / n;
            ac_stream_free(s);
            int cold_runs = 5;
            t0 = now();
            for (int i = 0; i < cold_runs; i++) {
                check(ac_stream_open_file(argv[a], NULL, &s), argv[a]);
                check(ac_decode_frame(s, (n / 2 + (size_t)i * 3) % n, one, v3), "cold frame");
                ac_stream_free(s);
            }
            double cold = (now() - t0) / cold_runs;
            int reps = 200;
            t0 = now();
            for (int i = 0; i < reps; i++) {
                memcpy(copy, all + (size_t)(i % (int)n) * v3, v3 * sizeof(float));
                __asm__ volatile("" : : "r"(copy) : "memory");
            }
            double mc = (now() - t0) / reps;
            double r[5] = {bulk, player, random, cold, mc};
            for (int k = 0; k < 5; k++)
                if (r[k] < best[k]) best[k] = r[k];
            free(all);
            free(one);
            free(copy);
        }
        const char *name = strrchr(argv[a], '/');
        printf("| %s | %s | %zu | %zu | %zu (%zu) | ≤ %zu | %.1f | %.1f | %.1f | %.1f | %.2f | %.2f |\n", name ? name + 1 : argv[a],
               info.codec, info.frames, info.vertices, info.packets, info.keyframes, info.max_packet_frames, best[0] * 1e6,
               best[1] * 1e6, best[2] * 1e6, best[3] * 1e6, best[4] * 1e6, best[2] / best[1]);
    }
    return 0;
}
