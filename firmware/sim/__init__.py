"""Software-in-the-loop dRonin flight controller (UAVTalk over a pty or TCP).

`start_simulator(...)` runs one as a subprocess; `vehicle.Vehicle` is the pure model.
"""

from firmware.sim.launcher import SimulatorError, SimulatorProcess, start_simulator

__all__ = ["SimulatorError", "SimulatorProcess", "start_simulator"]
