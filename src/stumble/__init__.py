"""stumble: trip and balance-recovery simulation on human models in MuJoCo."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("stumble")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"
