"""``python -m gms_comp``: the ``gms-comp`` command line."""

import sys

try:
    from gms_comp.app.cli import main
except KeyboardInterrupt:  # Ctrl-C while the interpreter imports the CLI
    sys.unraisablehook = lambda _unraisable: None  # as cli.quiet_finalizers
    print("gms-comp: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
