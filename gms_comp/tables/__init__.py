"""tables layer of gms-comp."""
