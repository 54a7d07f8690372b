"""``python -m cosserat_channel.cli``: the same as the ``cosserat-channel`` command."""

from . import console

if __name__ == "__main__":  # importing this module (a documentation tool does) runs nothing
    console()
