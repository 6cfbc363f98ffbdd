"""Packaged configs (installed as ``gms_comp.configs``)."""
