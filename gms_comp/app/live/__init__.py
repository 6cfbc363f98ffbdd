"""The compensator on a live CAN bus: the simulated machine, recording, following, commissioning."""
