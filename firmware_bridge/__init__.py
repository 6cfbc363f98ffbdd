"""CAN transport of the feedforward: CiA 402 and DBC/E2E profiles, streamer, drive emulator."""
