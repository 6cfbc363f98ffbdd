"""The formats ``gms-comp stream --log`` writes a frame log in, chosen by suffix.

python-can's ``Logger`` picks its writer from the file's suffix; these are the writers it
has without extra packages (``.mf4`` needs asammdf). The command checks the suffix when
its arguments are parsed, so a log name it cannot write is refused before the stream.
"""

from __future__ import annotations

#: Suffixes of a frame log (python-can writers: ASCII, BLF, CSV, SQLite, candump, TRC, text).
LOG_SUFFIXES = (".asc", ".blf", ".csv", ".db", ".log", ".trc", ".txt")
