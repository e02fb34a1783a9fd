"""``python -m server.cli``: the same command line as ``teleprog`` (tests and ``teleprog up`` start
their children this way)."""

import sys

from server.cli import main

sys.exit(main())
