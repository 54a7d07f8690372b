"""``python -m cosserat_channel.cli``: the same as the ``cosserat-channel`` command."""

import sys

from . import main

if __name__ == "__main__":  # importing this module (a documentation tool does) runs nothing
    sys.exit(main())
