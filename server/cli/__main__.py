"""``python -m server.cli``: the same command line as ``teleprog`` (tests and ``teleprog up`` start
their children this way)."""

import sys

from server.cli import main

if __name__ == "__main__":  # not when a spawned worker process imports it again
    sys.exit(main())
