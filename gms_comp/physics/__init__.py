"""physics layer of gms-comp."""
