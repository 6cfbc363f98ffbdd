"""measured layer of gms-comp."""
