"""cosserat-channel: the frictional Cosserat model of granular channel flow, solved fast.

The physics is Mohan, Nott & Rao, "A frictional Cosserat model for the flow of granular
materials through a vertical channel". See ``README.md`` for the set-up commands.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cosserat-channel")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
