/*
 * Firmware-side receiver of the gms-comp feedforward frame (profile "e2e").
 *
 * Frame layout, scaling and data IDs come from firmware_bridge/gms_ff.dbc; the
 * pack/unpack code (gms_ff.h, gms_ff.c) is generated from it with
 *     cantools generate_c_source gms_ff.dbc
 * This file adds what the generator does not: the CRC, the range checks, the
 * dating of each frame by the drive's own cycle, the session, and the watchdog that
 * ramps the feedforward to zero when frames stop. The rules are
 * firmware_bridge/freshness.py (DriveClock), firmware_bridge/profiles/e2e/receiver.py
 * (E2eReceiver) and firmware_bridge/supervisor.py (Supervisor), exactly; the tests
 * feed both the same random sequences.
 *
 * Dating: the drive counts its control ticks (16 bits) and publishes the tick just run
 * in DriveStatus.Cycle (ff_last_cycle). A compensator stamps each frame with the tick it
 * is meant to apply at, from that published cycle and the time passed since: a frame
 * stamped s is fresh at tick n if 0 <= n - s <= max_age_cycles (modulo 2^16, boundary
 * included); n - s < 0 is early. A delay can only make a frame look older: there is no
 * counter to anchor, nothing to re-anchor.
 *
 * Session: the handler takes commands from one compensator at a time, whose id it
 * announces in DriveStatus.Session (ff_session): it grants the first fresh request
 * (Mode 1) while it holds none, refuses frames of any other session (foreign), and
 * releases the session on a fresh release frame (Mode 2) or when no granted request or
 * accepted command of it has come for more than 10 x timeout_cycles.
 */
#ifndef FF_HANDLER_H
#define FF_HANDLER_H

#include <stddef.h>
#include <stdint.h>

/* Same order as firmware_bridge.supervisor.Verdict. */
enum ff_verdict {
    FF_ACCEPTED = 0, /* a command of the held session, applied at the next tick */
    FF_GRANTED,      /* a request: the session is (or already was) the sender's */
    FF_RELEASED,     /* the held session's end, asked by its compensator */
    FF_CORRUPT,      /* wrong length, CRC mismatch or a field outside the DBC range */
    FF_DUPLICATE,    /* the same stamp as the last command taken */
    FF_OUT_OF_ORDER, /* older than the last command taken */
    FF_STALE,        /* older than max_age_cycles by the drive's cycle */
    FF_EARLY,        /* dated in the drive's future */
    FF_FOREIGN,      /* of another session than the one held (or none granted) */
    FF_VERDICT_COUNT
};

/* Same values as the DBC's DriveStatus.State. */
enum ff_state { FF_WAITING = 0, FF_ACTIVE, FF_HOLD, FF_FALLBACK };

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

/* Check one received FfCommand frame against the next tick; returns an enum ff_verdict. */
int ff_on_frame(struct ff_handler *h, const uint8_t *data, size_t size);

/* One drive tick: returns the feedforward to apply, in 0.1 mA. */
int16_t ff_tick(struct ff_handler *h);

/* For DriveStatus after a tick: the cycle just run, the session held (0: none), the state. */
uint16_t ff_last_cycle(const struct ff_handler *h);
uint8_t ff_session(const struct ff_handler *h);
int ff_state(const struct ff_handler *h);

/* 1 while the value ff_tick returns is the friction level of the drive's own observer
 * (Mode 3, 0.1 mA = 1e-4 of the level: the firmware runs its observer, scaled by it,
 * instead of adding the value as a current), 0 while it is a current (Mode 0). */
int ff_in_drive(const struct ff_handler *h);

/* Number of frames with the given verdict so far. */
uint32_t ff_count(const struct ff_handler *h, int verdict);

/* CRC-16/CCITT-FALSE over data, then the data ID low byte and high byte. */
uint16_t ff_crc16(const uint8_t *data, size_t size, uint16_t data_id);

#endif
