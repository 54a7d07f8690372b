"""``python -m cosserat_channel.paper -o DIR``: the ``paper`` command."""

import sys

if __name__ == "__main__":  # only as a command: documentation tools import every module
    from . import main

    sys.exit(main())
