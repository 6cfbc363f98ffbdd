"""Subcommands of the ``gms-comp`` CLI, one module each (see :mod:`gms_comp.app.cli`)."""
