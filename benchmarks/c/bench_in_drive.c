/* Timing of the generated observer against a plain play operator of the same elements,
 * compiled the same way in one library (benchmarks/bench_in_drive.py). */
#define _POSIX_C_SOURCE 199309L
#include <time.h>

#include "gms_observer.h"

static gms_state state;
static float play_anchor[GMS_N];
static volatile float sink;

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

/* The plain play operator: a_i = clamp(a_i, x - r_i, x + r_i), F = sum k_i (x - a_i). */
static float play_step(float x)
{
    const struct gms_table *t = &gms_table_builtin;
    float force = 0.0f;
    int i;
    for (i = 0; i < GMS_N; ++i) {
        const float lo = x - t->width_m[i], hi = x + t->width_m[i];
        float a = play_anchor[i];
        a = a < lo ? lo : (a > hi ? hi : a);
        play_anchor[i] = a;
        force += t->stiffness_N_per_m[i] * (x - a);
    }
    return force;
}

double time_gms(const float *x, const float *v, long n)
{
    long j;
    float acc = 0.0f;
    double start;
    gms_init(&state);
    start = now_ns();
    for (j = 0; j < n; ++j) {
        acc += gms_step(&state, x[j], v[j]);
    }
    sink = acc;
    return (now_ns() - start) / (double)n;
}

double time_play(const float *x, long n)
{
    long j;
    int i;
    float acc = 0.0f;
    double start;
    for (i = 0; i < GMS_N; ++i) {
        play_anchor[i] = x[0];
    }
    start = now_ns();
    for (j = 0; j < n; ++j) {
        acc += play_step(x[j]);
    }
    sink = acc;
    return (now_ns() - start) / (double)n;
}
