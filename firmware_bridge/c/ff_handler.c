/* See ff_handler.h. Integer arithmetic only; no dynamic memory. */
#include "ff_handler.h"

#include <stdbool.h>

#include "gms_ff.h"

#define COUNTER_MODULUS 256u
#define MAX_EARLY_CYCLES 64   /* COUNTER_MODULUS / 4, firmware_bridge.freshness */
#define REANCHOR_FRAMES 16u   /* firmware_bridge.freshness.REANCHOR_FRAMES */

struct ff_handler {
    struct ff_config cfg;
    /* frame dating, as firmware_bridge.freshness.FrameClock */
    bool anchored;
    uint8_t cycle;  /* drive cycles, modulo 256 */
    uint8_t offset; /* drive cycle minus counter of a frame of age 0 */
    bool has_last;
    uint8_t last_counter;
    uint32_t last_age; /* age of the last accepted frame, counted up without wrapping */
    uint8_t late_offset;
    uint8_t late_counter;
    uint32_t late_run;
    bool has_origin;
    uint32_t origin_us; /* slot of counter 0: earliest reception - counter x cycle */
    bool has_fresh;
    bool fresh_timed;
    uint32_t fresh_sent_us; /* earliest the fresh frame can have left */
    int16_t fresh_raw;
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

/* a difference of counters/cycles modulo 256, as a signed number in [-128, 127] */
static int32_t signed_diff(uint32_t value)
{
    value %= COUNTER_MODULUS;
    return value >= COUNTER_MODULUS / 2u ? (int32_t)value - (int32_t)COUNTER_MODULUS
                                         : (int32_t)value;
}

/* slot of the counter step nearest rx_us (the counter unwrapped by time) */
static uint32_t slot_us(const struct ff_handler *h, uint8_t counter, uint32_t rx_us)
{
    int64_t cycle = (int64_t)h->cfg.cycle_us;
    int64_t span = (int64_t)COUNTER_MODULUS * cycle;
    int64_t x = (int64_t)(int32_t)(rx_us - h->origin_us) - (int64_t)counter * cycle;
    int64_t shifted = x + span / 2;
    int64_t wraps = shifted >= 0 ? shifted / span : -((-shifted + span - 1) / span);
    return h->origin_us + (uint32_t)(((int64_t)counter + wraps * COUNTER_MODULUS) * cycle);
}

/* freshness.FrameClock._set_origin */
static void set_origin(struct ff_handler *h, uint8_t counter, const uint32_t *rx_us,
                       bool earlier_only)
{
    if (rx_us == NULL || h->cfg.cycle_us == 0u) {
        return;
    }
    if (!h->has_origin || !earlier_only) {
        h->origin_us = *rx_us - (uint32_t)counter * h->cfg.cycle_us;
        h->has_origin = true;
        return;
    }
    uint32_t slot = slot_us(h, counter, *rx_us);
    if ((int32_t)(*rx_us - slot) < 0) {
        h->origin_us -= slot - *rx_us;
    }
}

static void anchor(struct ff_handler *h, uint8_t counter, const uint32_t *rx_us)
{
    set_origin(h, counter, rx_us, false);
    h->anchored = true;
    h->offset = (uint8_t)(h->cycle - counter);
    h->has_last = true;
    h->last_counter = counter;
    h->last_age = 0u;
    h->late_run = 0u;
}

/* a frame outside the validity window; a steady run of them re-anchors */
static enum ff_verdict late(struct ff_handler *h, uint8_t counter, const uint32_t *rx_us)
{
    uint8_t offset = (uint8_t)(h->cycle - counter);
    bool steady = h->late_run > 0u && offset == h->late_offset
                  && (uint8_t)(counter - h->late_counter) == 1u;
    h->late_run = steady ? inc_saturating(h->late_run) : 1u;
    h->late_offset = offset;
    h->late_counter = counter;
    if (h->late_run >= REANCHOR_FRAMES) {
        anchor(h, counter, rx_us);
        return FF_RESYNC;
    }
    return FF_STALE;
}

/* firmware_bridge.freshness.FrameClock.judge */
static enum ff_verdict judge(struct ff_handler *h, uint8_t counter, const uint32_t *rx_us)
{
    if (!h->anchored) {
        anchor(h, counter, rx_us);
        return FF_RESYNC;
    }
    /* order against the last accepted frame while it is itself fresh; once it is
     * older than the window, any frame older still is stale by its age anyway */
    if (h->has_last && h->last_age <= h->cfg.max_age_cycles) {
        uint32_t delta = ((uint32_t)counter - h->last_counter) % COUNTER_MODULUS;
        if (delta == 0u) {
            return FF_DUPLICATE;
        }
        if (delta >= COUNTER_MODULUS / 2u) {
            return FF_OUT_OF_ORDER;
        }
    }
    /* age in drive cycles; fresh if age <= max_age_cycles (boundary included) */
    int32_t age = signed_diff((uint32_t)h->cycle - counter - h->offset);
    if (age > (int32_t)h->cfg.max_age_cycles || age < -MAX_EARLY_CYCLES) {
        return late(h, counter, rx_us);
    }
    if (age < 0) { /* the anchor came from a late frame: this one is earlier */
        h->offset = (uint8_t)(h->offset + age);
    }
    set_origin(h, counter, rx_us, true);
    h->late_run = 0u;
    h->has_last = true;
    h->last_counter = counter;
    h->last_age = age < 0 ? 0u : (uint32_t)age;
    return FF_ACCEPTED;
}

static enum ff_verdict classify(struct ff_handler *h, const uint8_t *data, size_t size,
                                const uint32_t *rx_us)
{
    struct gms_ff_ff_command_t msg;

    if (size != GMS_FF_FF_COMMAND_LENGTH || gms_ff_ff_command_unpack(&msg, data, size) != 0) {
        return FF_CORRUPT;
    }
    if (msg.crc != ff_crc16(&data[2], size - 2u, h->cfg.data_id)) {
        return FF_CORRUPT;
    }
    /* the generated unpack does no range check: the firmware must */
    if (!gms_ff_ff_command_current_is_in_range(msg.current)) {
        return FF_CORRUPT;
    }
    enum ff_verdict verdict = judge(h, msg.counter, rx_us);
    if (verdict == FF_ACCEPTED) {
        h->has_fresh = true;
        h->fresh_raw = msg.current;
        h->fresh_timed = rx_us != NULL && h->has_origin;
        if (h->fresh_timed) { /* freshness.FrameClock.sent_by */
            uint32_t early = slot_us(h, msg.counter, *rx_us) - h->cfg.slot_margin_us;
            h->fresh_sent_us = (int32_t)(early - *rx_us) < 0 ? early : *rx_us;
        }
    }
    return verdict;
}

static int on_frame(struct ff_handler *h, const uint8_t *data, size_t size,
                    const uint32_t *rx_us)
{
    enum ff_verdict verdict = classify(h, data, size, rx_us);
    h->counts[verdict] = inc_saturating(h->counts[verdict]);
    return (int)verdict;
}

int ff_on_frame(struct ff_handler *h, const uint8_t *data, size_t size)
{
    return on_frame(h, data, size, NULL);
}

int ff_on_frame_at(struct ff_handler *h, const uint8_t *data, size_t size, uint32_t rx_us)
{
    return on_frame(h, data, size, &rx_us);
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

/* the rule by time (freshness.FrameClock.outlived): too old to apply at now_us? */
static bool outlived(const struct ff_handler *h, uint32_t now_us)
{
    int64_t age_us = (int64_t)(int32_t)(now_us - h->fresh_sent_us);
    int64_t limit_us = ((int64_t)h->cfg.max_age_cycles + (int64_t)h->cfg.transport_cycles)
                       * (int64_t)h->cfg.cycle_us;
    return age_us > limit_us;
}

static int16_t tick(struct ff_handler *h, const uint32_t *now_us)
{
    bool was_lost = h->link_lost;

    if (h->has_fresh && h->fresh_timed && now_us != NULL && outlived(h, *now_us)) {
        h->counts[FF_ACCEPTED]--; /* accepted by the counter, refused by time: stale */
        h->counts[FF_STALE] = inc_saturating(h->counts[FF_STALE]);
        h->has_fresh = false;
    }

    if (h->has_fresh) {
        h->cycles_since_fresh = 0;
        h->link_lost = false;
        h->output_raw = saturate(h->fresh_raw, h->cfg.limit_raw);
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
    h->has_fresh = false; /* a frame is applied in the cycle after its reception or never
                           * (the reception part of the rule by time, see ff_handler.h) */
    h->fresh_timed = false;
    h->cycle = (uint8_t)(h->cycle + 1u);
    h->last_age = inc_saturating(h->last_age);
    if (h->link_lost && !was_lost) {
        h->has_last = false; /* any newer frame may follow an outage; the anchor stays */
    }
    return h->output_raw;
}

int16_t ff_tick(struct ff_handler *h) { return tick(h, NULL); }

int16_t ff_tick_at(struct ff_handler *h, uint32_t now_us) { return tick(h, &now_us); }

uint32_t ff_count(const struct ff_handler *h, int verdict)
{
    return (verdict >= 0 && verdict < FF_VERDICT_COUNT) ? h->counts[verdict] : 0u;
}
