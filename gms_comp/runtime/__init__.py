"""runtime layer of gms-comp."""
