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
 * Freshness has a second rule in firmware_bridge/freshness.py, by the frame's
 * reception stamp: a drive refuses a frame whose (apply time - reception time)
 * / period - transport exceeds max_age_cycles, transport being 1 for a drive on
 * its own clock. This handler needs no clock for it: ff_on_frame runs at the
 * reception and the frame is applied by the very next ff_tick (the cycle ISR),
 * or never (has_fresh is cleared there), so apply - reception <= 1 period and the
 * rule holds for any max_age_cycles >= 0. The Python emulator needs the check
 * because its thread may run a cycle late against the bus timestamps, and a
 * CiA 402 RPDO may wait in the window for a SYNC that comes late.
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
};

struct ff_handler;

/* Size of struct ff_handler, for callers that allocate it opaquely. */
size_t ff_handler_size(void);

void ff_init(struct ff_handler *h, const struct ff_config *cfg);

/* Check one received FfCommand frame; returns an enum ff_verdict. */
int ff_on_frame(struct ff_handler *h, const uint8_t *data, size_t size);

/* One drive cycle: returns the feedforward to apply, in 0.1 mA. */
int16_t ff_tick(struct ff_handler *h);

/* Number of frames with the given verdict so far. */
uint32_t ff_count(const struct ff_handler *h, int verdict);

/* CRC-16/CCITT-FALSE over data, then the data ID low byte and high byte. */
uint16_t ff_crc16(const uint8_t *data, size_t size, uint16_t data_id);

#endif
