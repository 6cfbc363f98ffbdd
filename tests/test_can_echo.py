"""A transport that hands a node its own frames back (udp_multicast does) is not a second node."""

from __future__ import annotations

import dataclasses

import can
import pytest

from firmware_bridge.settings import load_can_config
from firmware_bridge.streamer import Streamer, make_tx
from gms_comp.config import default_config_path


@pytest.mark.parametrize("profile", ["cia402", "e2e"])
def test_own_echoes_are_not_foreign_but_another_nodes_frames_are(profile: str) -> None:
    cfg = dataclasses.replace(load_can_config(default_config_path()), profile=profile)
    channel = f"echo-{profile}"
    # receive_own_messages: the virtual bus behaves as udp_multicast does on one host
    with (
        can.Bus(interface="virtual", channel=channel, receive_own_messages=True) as ours,
        can.Bus(interface="virtual", channel=channel) as other,
    ):
        tx = make_tx(cfg)
        streamer = Streamer(cfg, ours, tx)
        for cycle in range(20):
            now_s = cycle * cfg.cycle_period_s
            # the drive's status: its cycle, and the session granted to this compensator
            tx.claim.time.observe(cycle, tx.claim.session, now_s)
            streamer.cycle(cycle, 0.1, now_s=now_s)
        streamer.drain_replies()
        assert streamer.frames_sent == 20
        assert streamer.foreign_frames == 0
        # another compensator sends our feedforward frame: counted
        own_id = next(iter(tx.exclusive_ids))
        other.send(can.Message(arbitration_id=own_id, data=b"\x55\x66\x77", is_extended_id=False))
        streamer.drain_replies()
        assert streamer.foreign_frames == 1
