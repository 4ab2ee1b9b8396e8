"""stumble: trip and balance-recovery simulation on human models in MuJoCo."""

import os
from importlib.metadata import PackageNotFoundError, version

# OpenBLAS's idle threads spin for a while after each call before they sleep. Where two
# processes share two cores (DAgger's training, ``dagger.SetPool``) that spinning takes
# the core the other process computes on, and two processes train no faster than one.
# Sleeping at once (2^4 cycles, OpenBLAS's own setting, read when NumPy first loads it;
# a value already set is kept) changes when its threads run, not what they compute.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

try:
    __version__ = version("stumble")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"
