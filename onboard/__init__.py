"""Onboard agent: bridges the ground's MQTT contract (docs/protocol.md) to a flight controller.

This package must never import Django; it is installed on drones on its own.
"""

from .blas import one_thread

one_thread()  # before numpy is imported anywhere in the process (onboard/blas.py)

__version__ = "0.1.0"
