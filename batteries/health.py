"""A pack's health from its flights: plain functions, no database.

- Cycles: equivalent full cycles, the discharge counted as a fraction of the pack's
  capacity and summed over flights, as the Smart Battery Data Specification counts
  CycleCount (a cycle is a discharge about equal to the design capacity) [SBS 1.1, CycleCount()].
  A flight's share is its state-of-charge drop; without one, its energy over the rated
  energy.
- Capacity: a flight that used `energy_wh` while its state of charge fell by `drop`
  shows a full pack holding `energy_wh / drop`. Health is the median of the last
  HEALTH_FLIGHTS such estimates over the rated energy (capacity state of health).
- Internal resistance: the voltage sag against the current step between two telemetry
  samples close in time, where the open-circuit voltage has not moved: R = −ΔV/ΔI, the
  pulse resistance of the Hybrid Pulse Power Characterization
  test [FreedomCAR 2003]; a flight's estimate is the median of its steps.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable

# Rated energy from a label in mAh: Wh = nominal volts × Ah [IATA LBGD]; a lithium-polymer
# cell's nominal voltage, used when only mAh and cells are known.
NOMINAL_CELL_V = 3.7
# A capacity estimate needs a drop this large: the state of charge comes in whole percent
# (MAVLink battery_remaining), so a 20 % drop is known to ±5 %.
MIN_SOC_DROP = 0.2
# Health is the median of this many of the newest capacity estimates.
HEALTH_FLIGHTS = 5
# A current step is used for the sag when at least this large (smaller ones drown in
# the voltage's resolution) and its two samples at most this far apart.
MIN_STEP_A = 2.0
MAX_STEP_S = 2.0
# Estimates outside this range are taken as telemetry glitches, not a pack.
MAX_RESISTANCE_OHM = 1.0
MAX_STEPS_KEPT = 10_000


def rated_energy_wh(capacity_mah: float | None, cells: int | None) -> float | None:
    """A pack's rated energy from its label's capacity and cell count (None if unknown)."""
    if not capacity_mah or not cells or capacity_mah <= 0 or cells <= 0:
        return None
    return round(capacity_mah / 1000.0 * cells * NOMINAL_CELL_V, 1)


def soc_drop(start: float | None, end: float | None) -> float | None:
    if start is None or end is None:
        return None
    return round(max(0.0, float(start) - float(end)), 4)


def flight_cycles(drop: float | None, energy_wh: float | None, rated_wh: float | None) -> float:
    """The flight's share of a full cycle (0 when nothing says how much was used)."""
    if drop is not None:
        return drop
    if energy_wh is not None and rated_wh:
        return max(0.0, energy_wh / rated_wh)
    return 0.0


def capacity_wh(energy_wh: float | None, drop: float | None) -> float | None:
    """What a full pack holds, from one flight (None when the drop is too small)."""
    if energy_wh is None or drop is None or drop < MIN_SOC_DROP or energy_wh <= 0:
        return None
    return energy_wh / drop


def health(capacities: Iterable[float], rated_wh: float | None) -> float | None:
    """Median capacity of the newest estimates (newest first) over the rated energy."""
    newest = [c for c in capacities if c is not None][:HEALTH_FLIGHTS]
    if not newest or not rated_wh:
        return None
    return round(statistics.median(newest) / rated_wh, 3)


def retirement(
    health_value: float | None, cycles: float, threshold: float, cycle_limit: float | None
) -> str:
    """Why the pack is retired under the organisation's rules ("" when it is not)."""
    reasons = []
    if health_value is not None and health_value < threshold:
        reasons.append(f"health {health_value:.0%} below {threshold:.0%}")
    if cycle_limit is not None and cycles > cycle_limit:
        reasons.append(f"{cycles:.1f} cycles above the limit of {cycle_limit:g}")
    return "; ".join(reasons)


class SagEstimator:
    """Feed (time, volts, amps) samples in time order; `result()` is the median −ΔV/ΔI
    of the current steps seen, or None when the flight had none."""

    def __init__(self) -> None:
        self._last: tuple[float, float, float] | None = None
        self._steps: list[float] = []

    def add(self, ts: float, voltage: float, current: float) -> None:
        last = self._last
        self._last = (ts, voltage, current)
        if last is None or not 0 < ts - last[0] <= MAX_STEP_S:
            return
        step = current - last[2]
        if abs(step) < MIN_STEP_A or len(self._steps) >= MAX_STEPS_KEPT:
            return
        resistance = -(voltage - last[1]) / step
        if math.isfinite(resistance) and 0 < resistance <= MAX_RESISTANCE_OHM:
            self._steps.append(resistance)

    def result(self) -> float | None:
        return round(statistics.median(self._steps), 4) if self._steps else None
