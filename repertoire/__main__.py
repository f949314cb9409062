"""``python -m repertoire``: the command line (:mod:`repertoire.cli`)."""

import sys

try:
    from repertoire.cli import main

    code = main()
except KeyboardInterrupt:  # Ctrl-C before the command took it over (start-up imports)
    print("interrupted", file=sys.stderr)
    code = 130

from repertoire.interrupts import exit_process  # noqa: E402  (after: see the except)

exit_process(code)
