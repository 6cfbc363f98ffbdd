/*
 * Firmware-side receiver of the gms-comp feedforward frame (profile "e2e").
 *
 * Frame layout, scaling and data IDs come from firmware_bridge/gms_ff.dbc; the
 * pack/unpack code (gms_ff.h, gms_ff.c) is generated from it with
 *     cantools generate_c_source gms_ff.dbc
 * This file adds what the generator does not: the CRC, the alive counter
 * checks, the dating of each frame by its counter (firmware_bridge/freshness.py:
 * stale = older than max_age_cycles, boundary included), the range check, and the watchdog that ramps the feedforward to zero
 * when frames stop. The rules match firmware_bridge/profiles/e2e/receiver.py (E2eReceiver) and
 * firmware_bridge/supervisor.py (Supervisor) exactly; the tests feed both the
 * same vectors.
 *
 * Freshness has a second rule in firmware_bridge/freshness.py, by time: a drive
 * refuses a frame whose (apply time - sent) / period - transport exceeds
 * max_age_cycles, transport being 1 for a drive on its own clock, and "sent" the
 * earliest the frame can have left: its reception, or its slot (the reception of
 * the earliest frame since the anchor, relative to its counter, advanced one
 * period per counter step) less a margin, whichever is earlier. The counter alone
 * cannot tell a frame that left just before the drive's tick of its cycle and was
 * held on the way from one that left just after it. ff_on_frame_at / ff_tick_at
 * take the controller's timer in microseconds (reception timestamp, start of the
 * cycle) and apply the rule; ff_on_frame / ff_tick date by the counter alone (the
 * frame is applied by the very next tick or never, so the reception part holds).
 */
#ifndef FF_HANDLER_H
#define FF_HANDLER_H

#include <stddef.h>
#include <stdint.h>

/* Same order as firmware_bridge.supervisor.Verdict. */
enum ff_verdict {
    FF_ACCEPTED = 0,
    FF_RESYNC,       /* intact frame taken as the new counter reference, not applied */
    FF_CORRUPT,      /* wrong length, CRC mismatch or value outside the DBC range */
    FF_DUPLICATE,    /* same counter as the last accepted frame */
    FF_OUT_OF_ORDER, /* counter older than the last accepted frame */
    FF_STALE,        /* older than max_age_cycles by its counter against the drive's cycles */
    FF_VERDICT_COUNT
};

struct ff_config {
    uint16_t data_id;        /* E2EDataId of FfCommand in the DBC */
    int16_t limit_raw;       /* largest magnitude applied, in 0.1 mA */
    uint32_t timeout_cycles; /* cycles without a fresh value before the link counts as lost */
    uint32_t ramp_cycles;    /* cycles a full-scale ramp to zero may take */
    uint32_t max_age_cycles; /* validity window: largest age (drive cycles) applied, inclusive */
    /* the rule by time (ff_on_frame_at, ff_tick_at); firmware_bridge.freshness */
    uint32_t cycle_us;         /* the drive cycle in microseconds of the timer */
    uint32_t transport_cycles; /* 1: a frame applies at the tick after its reception */
    uint32_t slot_margin_us;   /* SLOT_MARGIN_CYCLES (0.25) of a cycle, in microseconds */
};

struct ff_handler;

/* Size of struct ff_handler, for callers that allocate it opaquely. */
size_t ff_handler_size(void);

void ff_init(struct ff_handler *h, const struct ff_config *cfg);

/* Check one received FfCommand frame; returns an enum ff_verdict. */
int ff_on_frame(struct ff_handler *h, const uint8_t *data, size_t size);

/* Same, received at rx_us (the timer, microseconds, wrapping): dated by time too. */
int ff_on_frame_at(struct ff_handler *h, const uint8_t *data, size_t size, uint32_t rx_us);

/* One drive cycle: returns the feedforward to apply, in 0.1 mA. */
int16_t ff_tick(struct ff_handler *h);

/* Same, the cycle beginning at now_us: a frame from ff_on_frame_at too old by time is
 * refused (counted stale instead of accepted). */
int16_t ff_tick_at(struct ff_handler *h, uint32_t now_us);

/* Number of frames with the given verdict so far. */
uint32_t ff_count(const struct ff_handler *h, int verdict);

/* CRC-16/CCITT-FALSE over data, then the data ID low byte and high byte. */
uint16_t ff_crc16(const uint8_t *data, size_t size, uint16_t data_id);

#endif
