"""``python -m cosserat_channel.cli``: the same as the ``cosserat-channel`` command."""

import sys

from . import main

sys.exit(main())
