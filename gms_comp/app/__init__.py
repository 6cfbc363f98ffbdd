"""app layer of gms-comp."""
