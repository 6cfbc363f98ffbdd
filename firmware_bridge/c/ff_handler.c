/* See ff_handler.h. Integer arithmetic only; no dynamic memory. */
#include "ff_handler.h"

#include <stdbool.h>

#include "gms_ff.h"

enum { MODE_COMMAND = 0, MODE_REQUEST = 1, MODE_RELEASE = 2, MODE_IN_DRIVE = 3 }; /* .Mode */
#define SESSION_TIMEOUT_FACTOR 10u /* firmware_bridge.freshness.SESSION_TIMEOUT_FACTOR */

struct ff_handler {
    struct ff_config cfg;
    /* dating and session, as firmware_bridge.freshness.DriveClock */
    uint16_t cycle;      /* the tick a frame judged now applies at */
    uint16_t last_cycle; /* the tick just run */
    uint8_t session;     /* held session, 0: none */
    bool has_last;
    uint16_t last_stamp; /* newest stamp taken in the held session */
    uint32_t idle_cycles;
    /* the value to apply, as firmware_bridge.supervisor.Supervisor */
    bool has_fresh;
    int16_t fresh_raw;
    bool fresh_in_drive;
    bool in_drive; /* the value applied is the level of the drive's own observer */
    int16_t output_raw;
    uint32_t cycles_since_fresh;
    bool link_lost;
    uint32_t counts[FF_VERDICT_COUNT];
};

size_t ff_handler_size(void) { return sizeof(struct ff_handler); }

static uint32_t inc_saturating(uint32_t value) { return value == UINT32_MAX ? value : value + 1u; }

static uint16_t crc16_update(uint16_t crc, uint8_t byte)
{
    crc ^= (uint16_t)((uint16_t)byte << 8);
    for (int bit = 0; bit < 8; bit++) {
        crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    }
    return crc;
}

uint16_t ff_crc16(const uint8_t *data, size_t size, uint16_t data_id)
{
    uint16_t crc = 0xFFFFu;
    for (size_t i = 0; i < size; i++) {
        crc = crc16_update(crc, data[i]);
    }
    crc = crc16_update(crc, (uint8_t)(data_id & 0xFFu));
    return crc16_update(crc, (uint8_t)(data_id >> 8));
}

void ff_init(struct ff_handler *h, const struct ff_config *cfg)
{
    *h = (struct ff_handler){0};
    h->cfg = *cfg;
    h->link_lost = true;
}

/* a - b modulo 2^16, as a signed number in [-32768, 32767] */
static int32_t stamp_diff(uint16_t a, uint16_t b) { return (int32_t)(int16_t)(uint16_t)(a - b); }

static void release(struct ff_handler *h)
{
    h->session = 0u;
    h->has_last = false;
}

/* firmware_bridge.freshness.DriveClock.judge */
static enum ff_verdict judge(struct ff_handler *h, uint16_t stamp, uint8_t session, uint8_t mode)
{
    int32_t age = stamp_diff(h->cycle, stamp);
    if (age < 0) {
        return FF_EARLY;
    }
    if ((uint32_t)age > h->cfg.max_age_cycles) {
        return FF_STALE;
    }
    if (session == 0u || (h->session != 0u && h->session != session)) {
        return FF_FOREIGN;
    }
    if (mode == MODE_REQUEST) {
        if (h->session == 0u) {
            h->session = session;
            h->has_last = false;
        }
        h->idle_cycles = 0u;
        return FF_GRANTED;
    }
    if (h->session == 0u) {
        return FF_FOREIGN;
    }
    if (h->has_last) {
        int32_t newer = stamp_diff(stamp, h->last_stamp);
        if (newer == 0) {
            return FF_DUPLICATE;
        }
        if (newer < 0) {
            return FF_OUT_OF_ORDER;
        }
    }
    if (mode == MODE_RELEASE) {
        release(h);
        return FF_RELEASED;
    }
    h->has_last = true;
    h->last_stamp = stamp;
    h->idle_cycles = 0u;
    return FF_ACCEPTED;
}

static enum ff_verdict classify(struct ff_handler *h, const uint8_t *data, size_t size)
{
    struct gms_ff_ff_command_t msg;

    if (size != GMS_FF_FF_COMMAND_LENGTH || gms_ff_ff_command_unpack(&msg, data, size) != 0) {
        return FF_CORRUPT;
    }
    if (msg.crc != ff_crc16(&data[2], size - 2u, h->cfg.data_id)) {
        return FF_CORRUPT;
    }
    /* the generated unpack does no range check: the firmware must */
    if (!gms_ff_ff_command_current_is_in_range(msg.current)
        || !gms_ff_ff_command_session_is_in_range(msg.session)
        || !gms_ff_ff_command_mode_is_in_range(msg.mode)) {
        return FF_CORRUPT;
    }
    enum ff_verdict verdict = judge(h, msg.cycle, msg.session, msg.mode);
    if (verdict == FF_ACCEPTED) {
        h->has_fresh = true;
        h->fresh_raw = msg.current;
        h->fresh_in_drive = msg.mode == MODE_IN_DRIVE;
    } else if (verdict == FF_RELEASED) {
        h->has_fresh = false;
        h->link_lost = true; /* Supervisor.end: ramp to zero from the next tick */
    }
    return verdict;
}

int ff_on_frame(struct ff_handler *h, const uint8_t *data, size_t size)
{
    enum ff_verdict verdict = classify(h, data, size);
    h->counts[verdict] = inc_saturating(h->counts[verdict]);
    return (int)verdict;
}

static int16_t saturate(int16_t value, int16_t limit)
{
    return value > limit ? limit : (value < -limit ? (int16_t)-limit : value);
}

static int16_t toward_zero(int16_t value, int32_t step)
{
    if (value > 0) {
        return (int16_t)(value > step ? value - step : 0);
    }
    return (int16_t)(-value > step ? value + step : 0);
}

int16_t ff_tick(struct ff_handler *h)
{
    if (h->has_fresh) {
        h->cycles_since_fresh = 0;
        h->link_lost = false;
        h->output_raw = saturate(h->fresh_raw, h->cfg.limit_raw);
        h->in_drive = h->fresh_in_drive;
    } else {
        h->cycles_since_fresh = inc_saturating(h->cycles_since_fresh);
        if (h->cycles_since_fresh > h->cfg.timeout_cycles) {
            h->link_lost = true;
        }
        if (h->link_lost) {
            int32_t step = ((int32_t)h->cfg.limit_raw + (int32_t)h->cfg.ramp_cycles - 1)
                           / (int32_t)h->cfg.ramp_cycles;
            h->output_raw = toward_zero(h->output_raw, step);
        }
    }
    h->has_fresh = false;
    h->last_cycle = h->cycle;
    h->cycle = (uint16_t)(h->cycle + 1u);
    h->idle_cycles = inc_saturating(h->idle_cycles);
    if (h->session != 0u && h->idle_cycles > SESSION_TIMEOUT_FACTOR * h->cfg.timeout_cycles) {
        release(h); /* a compensator gone without a word: a new request is needed */
    }
    return h->output_raw;
}

uint16_t ff_last_cycle(const struct ff_handler *h) { return h->last_cycle; }

uint8_t ff_session(const struct ff_handler *h) { return h->session; }

int ff_in_drive(const struct ff_handler *h) { return h->in_drive ? 1 : 0; }

int ff_state(const struct ff_handler *h)
{
    if (h->link_lost) {
        return h->output_raw != 0 ? FF_FALLBACK : FF_WAITING;
    }
    return h->cycles_since_fresh == 0u ? FF_ACTIVE : FF_HOLD;
}

uint32_t ff_count(const struct ff_handler *h, int verdict)
{
    return (verdict >= 0 && verdict < FF_VERDICT_COUNT) ? h->counts[verdict] : 0u;
}
