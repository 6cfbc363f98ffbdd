"""gms-comp: friction compensation for linear-motor axes with ball guides.

Layers, imports flowing one way: physics (``contact``, ``ball_model``,
``transient``) -> reduction (``reduction``, ``table``) -> runtime (``gms``,
``observer``) -> transport (``firmware_bridge``). ``sim`` holds the simulated
axis beside the real one.
"""

__version__ = "0.1.0"
