"""Default thresholds of the log checks, each with where its number comes from
(docs/references.md lists the works; docs/log-checks.md explains each check).

An organisation may override any of them (settings.LOGS_CHECK_THRESHOLDS, keyed by the
organisation's slug, "*" for every organisation); `merged` applies the overrides key by key.
"""

from __future__ import annotations

import copy
import math

DEFAULTS: dict[str, dict] = {
    # [PX4 Flight Review]: the Vibration Metrics plot of vehicle_imu_status
    # accel_vibration_metric is green below 0.5 g (4.905 m/s²), orange to 1 g, red above.
    # [ArduPilot Measuring Vibration]: VIBE below 30 m/s/s is normally acceptable, above
    # 60 m/s/s there are often problems with position or altitude hold.
    # Before April 2022 Flight Review plotted the delta velocity vibration (m/s, PX4 up
    # to v1.12) with its bands at 0.02 and 0.04 m/s.
    "vibration": {
        "px4": {"warning": 4.905, "fail": 9.81},
        "px4_delta_velocity": {"warning": 0.02, "fail": 0.04},
        "ardupilot": {"warning": 30.0, "fail": 60.0},
    },
    # [ArduPilot Measuring Vibration]: the clip counters increase each time an
    # accelerometer reaches its limit; any increase is worth a look. The fail level (new
    # clips in the flight) is our choice: a burst, not one odd sample.
    "clipping": {"warning": 0.0, "fail": 100.0},
    # [PX4 EKF2]: EKF2_REQ_NSATS defaults to 6 satellites for GPS use; [PX4 Flight Review]
    # jamming indicator "around or below 40", "80 or higher are too high". A fix lost
    # (fix type below 3D) or no GPS message for `outage_s` while armed is an outage;
    # the HDOP level and the outage length are our choice.
    "gps": {
        "min_satellites": 6.0,
        "jamming": {"warning": 40.0, "fail": 80.0},
        "max_hdop": 2.0,
        "outage_s": 1.0,
    },
    # [PX4 Battery Estimation]: BAT_V_EMPTY defaults to 3.5 V per cell (under load); so
    # does ArduCopter's default low-battery voltage (10.5 V, a 3S pack). Warning below it;
    # the fail level, 0.2 V lower where a LiPo's voltage falls steeply, is our choice.
    # A cell count is read from the log, else guessed from the first voltage at 4.25 V
    # per cell at most (a full LiPo cell is 4.2 V).
    "battery_sag": {"warning": 3.5, "fail": 3.3, "full_cell_v": 4.25},
    # Any RC loss while armed is a failure; a lost-frame rate over `lost_frames` a warning
    # (our choice).
    "rc_loss": {"lost_frames": 0.1},
    # [ArduPilot Motor Thrust Scaling / PX4 Flight Review]: motors spread far apart mean
    # an imbalanced vehicle; an output at its maximum for `saturated_s` has no control
    # margin left. Spread as a fraction of the output range; the levels are our choice.
    "motor_imbalance": {"warning": 0.10, "fail": 0.20, "saturated_s": 1.0, "limit": 0.98},
    # [PX4 EKF2] and [ArduPilot EKF]: a test ratio above 1 rejects the measurement; PX4's
    # guide asks for ratios below 0.5 most of the time.
    "estimator": {"warning": 0.5, "fail": 1.0},
    # Any failsafe while armed fails the check.
    "failsafe": {},
    # CPU load as a fraction of the processor; the levels are our choice.
    "cpu_load": {"warning": 0.8, "fail": 0.95},
    # Longest gap in the densest stream against its usual interval: more than `factor`
    # times it and over `min_gap_s` is a dropout (our choice), `fail_s` fails the check.
    "logging_dropouts": {"factor": 10.0, "min_gap_s": 0.1, "fail_s": 1.0},
}


class ThresholdError(ValueError):
    pass


def merged(*overrides: dict | None) -> dict[str, dict]:
    """The defaults with each override applied in turn; an override may only replace
    numbers the defaults have, with finite numbers."""
    out = copy.deepcopy(DEFAULTS)
    for override in overrides:
        if override:
            _apply(out, override, "")
    return out


def _apply(target: dict, override: dict, where: str) -> None:
    if not isinstance(override, dict):
        raise ThresholdError(f"{where or 'thresholds'}: expected an object")
    for key, value in override.items():
        name = f"{where}.{key}" if where else str(key)
        if key not in target:
            raise ThresholdError(f"{name}: no such threshold")
        if isinstance(target[key], dict):
            _apply(target[key], value, name)
        elif isinstance(value, bool) or not isinstance(value, int | float):
            raise ThresholdError(f"{name}: expected a number")
        elif not math.isfinite(value):
            raise ThresholdError(f"{name}: expected a finite number")
        else:
            target[key] = float(value)
