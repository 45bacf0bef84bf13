"""Onboard agent: bridges the ground's MQTT contract (docs/protocol.md) to a flight controller.

This package must never import Django; it is installed on drones on its own.
"""

__version__ = "0.1.0"
