/* Test harness of the generated observer: whole runs in one call (ctypes calls per step
 * would cost more than the steps). */
#include "gms_observer.h"

static gms_state state;

int harness_init(void)
{
    gms_init(&state);
    return (int)sizeof(struct gms_table);
}

int harness_load(const struct gms_table *table)
{
    return gms_load(&state, table);
}

float harness_level(void)
{
    return state.level;
}

int harness_set_level(float scale)
{
    return gms_set_level(&state, scale);
}

/* gms_step along x, v; with drive currents (may be 0: no adaptation) gms_adapt after it. */
void harness_run(const float *x, const float *v, const float *drive_A, const float *inertial_A,
                 const float *measured_v, float *out, float *level, long n)
{
    long j;
    for (j = 0; j < n; ++j) {
        out[j] = gms_step(&state, x[j], v[j]);
        if (drive_A != 0) {
            gms_adapt(&state, drive_A[j], inertial_A[j], measured_v[j]);
        }
        if (level != 0) {
            level[j] = state.level;
        }
    }
}

/* Element i's deflection (x - base) + offset at position x, and its slip direction. */
float harness_deflection(int i, float x)
{
    return (x - state.base_m[i]) + state.offset_m[i];
}

float harness_slip(int i)
{
    return state.slip[i];
}
