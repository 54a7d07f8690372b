"""``python -m cosserat_channel.paper -o DIR``: the ``paper`` command."""

import sys

from . import main

sys.exit(main())
