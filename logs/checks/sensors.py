"""Checks of what the sensors saw: vibration, accelerometer clipping, GPS quality and the
estimator's innovation test ratios. Each takes a LogView and its thresholds."""

from __future__ import annotations

import numpy as np

from logs.checks.base import (
    FAIL,
    PASS,
    WARNING,
    LogView,
    Result,
    grade,
    not_checked,
    window_around,
    worst,
)
from logs.checks.signals import first_time, held, px4_accel_vibration, timed_runs

# Consecutive records a test ratio must hold before it counts: one record over the line
# at a reset or a takeoff is not a failing estimator (our choice).
HELD_RECORDS = 3


def _armed_values(view: LogView, path: str) -> tuple[np.ndarray, np.ndarray]:
    t, v = view.read(path)
    keep = view.armed_at(t) & np.isfinite(v)
    return t[keep], v[keep]


def _peak_result(
    name: str,
    view: LogView,
    curves: list[tuple[str, np.ndarray, np.ndarray]],
    threshold: dict[str, float],
    unit: str,
    what: str,
) -> Result:
    """Grade the highest value of several curves; t is where the level reached is first
    crossed (the peak's own time when all pass)."""
    curves = [c for c in curves if len(c[1])]
    if not curves:
        return not_checked(name, f"no {what} samples while armed")
    peak_path, peak_t, peak_v = max(curves, key=lambda c: float(np.max(c[2])))
    value = float(np.max(peak_v))
    status = grade(value, threshold)
    if status == PASS:
        t = float(peak_t[int(np.argmax(peak_v))])
    else:
        limit = threshold["fail" if status == FAIL else "warning"]
        t = min(x for x in (first_time(ct, cv > limit) for _, ct, cv in curves) if x is not None)
    series = [peak_path, *[p for p, _, _ in curves if p != peak_path]][:6]
    reason = f"highest {what} {value:.3g} {unit} at {t:.1f} s" + (
        "" if status == PASS else f" (over {threshold['fail' if status == FAIL else 'warning']:g})"
    )
    return Result(
        name,
        status,
        value,
        unit,
        dict(threshold),
        t,
        reason,
        series=series,
        window=window_around(view, t),
    )


# --- vibration ---

# (store path, times, values) of one curve a figure is read from.
Curve = tuple[str, np.ndarray, np.ndarray]


def vibration(view: LogView, thresholds: dict) -> Result:
    """PX4: vehicle_imu_status.accel_vibration_metric as Flight Review plots it, else the
    estimator's older vibe[2], else the metric recomputed from sensor_combined;
    ArduPilot VIBE; MAVLink VIBRATION."""
    name = "vibration"
    levels = thresholds["vibration"]
    flavour = view.autopilot()
    found = (
        _imu_status_vibration(name, view, levels)
        or _estimator_vibration(name, view, levels)
        or _recomputed_vibration(name, view, levels)
        or _vibration_levels(name, view, levels, flavour)
        or _sampled_vibration(name, view, levels)
    )
    return found or not_checked(
        name,
        "no vehicle_imu_status, estimator_status, sensor_combined, vehicle_acceleration, "
        "VIBE, VIBRATION, Accels or Imu linear_acceleration",
    )


# PX4's metric is computed on every IMU sample (hundreds per second); from fewer than
# this many accelerations a second the change between samples is the flight's motion,
# not the airframe's vibration (our choice: a propeller's vibration lies well above 50 Hz,
# so the samples must be at least twice that, the Nyquist rate).
MIN_ACCEL_RATE_HZ = 100.0


def _sampled_vibration(name: str, view: LogView, levels: dict) -> Result | None:
    """PX4's metric recomputed from dRonin Accels (x, y, z in m/s²) or a ROS
    sensor_msgs/Imu's linear_acceleration, when recorded fast enough."""
    sources = [(x, [f"{x}/{f}" for f in ("x", "y", "z")]) for x in view.instances("Accels")]
    axes = [f"linear_acceleration/{a}" for a in ("x", "y", "z")]
    sources += [(x, [f"{x}/{a}" for a in axes]) for x in view.layers_with(*axes)]
    for layer, paths in sources:
        if not all(p in view.store.index["series"] for p in paths):
            continue
        t, _ = view.read(paths[0])
        dt = np.diff(t)
        rate = 1.0 / float(np.median(dt[dt > 0])) if (dt > 0).any() else 0.0
        if rate < MIN_ACCEL_RATE_HZ:
            return not_checked(
                name,
                f"{layer} recorded at {rate:.3g} Hz, too slow for vibration "
                f"(needs {MIN_ACCEL_RATE_HZ:g} Hz)",
            )
        return _recomputed(name, view, layer, paths, levels["px4"])
    return None


def _imu_status_vibration(name: str, view: LogView, levels: dict) -> Result | None:
    """PX4's vehicle_imu_status.accel_vibration_metric, graded in its schema's unit."""
    curves: list[Curve] = []
    old_schema = False
    for layer in view.instances("vehicle_imu_status"):
        p = view.path(layer, "accel_vibration_metric")
        if p:
            curves.append((p, *_armed_values(view, p)))
            # PX4 up to v1.12 (the schema with gyro_coning_vibration) kept the metric on
            # the delta velocity, in m/s; later versions on the acceleration, in m/s².
            old_schema = old_schema or bool(view.path(layer, "gyro_coning_vibration"))
    if not curves:
        return None
    if old_schema:
        return _peak_result(
            name, view, curves, levels["px4_delta_velocity"], "m/s", "delta velocity vibration"
        )
    return _peak_result(name, view, curves, levels["px4"], "m/s²", "accel vibration metric")


def _estimator_vibration(name: str, view: LogView, levels: dict) -> Result | None:
    """PX4's older estimator_status.vibe[2], the delta velocity vibration in m/s."""
    for layer in view.instances("estimator_status"):
        p = view.path(layer, "vibe[2]")
        if p:
            return _peak_result(
                name,
                view,
                [(p, *_armed_values(view, p))],
                levels["px4_delta_velocity"],
                "m/s",
                "delta velocity vibration",
            )
    return None


def _recomputed_vibration(name: str, view: LogView, levels: dict) -> Result | None:
    """PX4's metric from the first logged three-axis accelerations."""
    # PX4's raw accelerations, else the filtered ones (vehicle_acceleration).
    for topic, field in (
        ("sensor_combined", "accelerometer_m_s2"),
        ("vehicle_acceleration", "xyz"),
    ):
        for layer in view.instances(topic):
            paths = [view.path(layer, f"{field}[{i}]") for i in range(3)]
            if all(paths):
                found = [p for p in paths if p]
                return _recomputed(name, view, topic, found, levels["px4"])
    return None


def _vibration_levels(name: str, view: LogView, levels: dict, flavour: str) -> Result | None:
    """ArduPilot's VIBE levels, else MAVLink VIBRATION, graded by who made the log."""
    for topic, fields in (
        ("VIBE", ("VibeX", "VibeY", "VibeZ")),
        ("VIBRATION", ("vibration_x", "vibration_y", "vibration_z")),
    ):
        if topic == "VIBRATION" and flavour == "px4":
            # PX4 sends accel_vibration_metric as vibration_x (its mavlink VIBRATION stream).
            fields = ("vibration_x",)
        curves = _armed_curves(view, topic, fields)
        if curves:
            level = levels["px4" if flavour == "px4" else "ardupilot"]
            return _peak_result(name, view, curves, level, "m/s²", "vibration level")
    return None


def _armed_curves(view: LogView, topic: str, fields: tuple[str, ...]) -> list[Curve]:
    """The armed samples of each of `fields` in every instance of `topic`."""
    curves: list[Curve] = []
    for layer in view.instances(topic):
        for f in fields:
            p = view.path(layer, f)
            if p:
                curves.append((p, *_armed_values(view, p)))
    return curves


def _recomputed(
    name: str, view: LogView, topic: str, paths: list[str], level: dict[str, float]
) -> Result:
    """PX4's vibration metric recomputed from logged accelerations (m/s²)."""
    t, ax = view.read(paths[0])
    ay, az = view.read(paths[1])[1], view.read(paths[2])[1]
    if len(t) < 2:
        return not_checked(name, f"too few {topic} samples")
    metric = px4_accel_vibration(ax, ay, az)
    keep = view.armed_at(t)
    result = _peak_result(
        name,
        view,
        [(paths[2], t[keep], metric[keep])],
        level,
        "m/s²",
        f"accel vibration (recomputed from {topic})",
    )
    result.series = list(paths)
    return result


# --- clipping ---

_CLIP_COUNTERS = (
    # (topic, fields, cumulative): PX4 totals per axis; sensor_accel counts per sample
    # period; ArduPilot and MAVLink keep a running count per accelerometer.
    ("vehicle_imu_status", ("accel_clipping[0]", "accel_clipping[1]", "accel_clipping[2]"), True),
    ("sensor_accel", ("clip_counter[0]", "clip_counter[1]", "clip_counter[2]"), False),
    ("VIBE", ("Clip0", "Clip1", "Clip2", "Clip"), True),
    ("VIBRATION", ("clipping_0", "clipping_1", "clipping_2"), True),
)


def _clip_events(view: LogView, topic: str, fields: tuple, cumulative: bool) -> tuple:
    """(times, counts, paths) of the new clips each counter of `topic` shows while armed."""
    events_t, events_n, paths = [], [], []
    for layer in view.instances(topic):
        for f in fields:
            p = view.path(layer, f)
            if not p:
                continue
            t, v = view.read(p)
            if not len(t):
                continue
            paths.append(p)
            if cumulative:
                # A counter that goes down restarted (a reboot): only rises count.
                new = np.concatenate([[0.0], np.clip(np.diff(v), 0, None)])
            else:
                new = np.clip(v, 0, None)
            new = np.where(view.armed_at(t) & np.isfinite(new), new, 0.0)
            hit = new > 0
            events_t.append(t[hit])
            events_n.append(new[hit])
    return events_t, events_n, paths


def clipping(view: LogView, thresholds: dict) -> Result:
    """New clips counted while armed, from the first set of counters the log has."""
    name = "clipping"
    level = thresholds["clipping"]
    for topic, fields, cumulative in _CLIP_COUNTERS:
        events_t, events_n, paths = _clip_events(view, topic, fields, cumulative)
        if not paths:
            continue
        if not events_t or not sum(len(x) for x in events_t):
            return Result(
                name,
                PASS,
                0.0,
                "clips",
                dict(level),
                None,
                f"no clipping counted in {topic}",
                series=paths[:6],
                window=window_around(view, None),
            )
        t = np.concatenate(events_t)
        n = np.concatenate(events_n)
        order = np.argsort(t, kind="stable")
        t, total = t[order], np.cumsum(n[order])
        value = float(total[-1])
        status = grade(value, level)
        limit = level["fail"] if status == FAIL else level["warning"]
        at = float(t[np.flatnonzero(total > limit)[0]])
        return Result(
            name,
            status,
            value,
            "clips",
            dict(level),
            at,
            f"{value:.0f} accelerometer clips in {topic}, the first at {float(t[0]):.1f} s",
            series=paths[:6],
            window=window_around(view, at),
        )
    return not_checked(
        name,
        "no vehicle_imu_status, sensor_accel, VIBE or VIBRATION (dRonin Accels and ROS Imu "
        "record no clipping count)",
    )


# --- GPS ---

GpsRow = tuple[str, str, str | None, tuple[str, float] | None, str | None]
_GPS: tuple[GpsRow, ...] = (
    # topic, fix field, satellites field, hdop field (and its scale), jamming field
    ("vehicle_gps_position", "fix_type", "satellites_used", ("hdop", 1.0), "jamming_indicator"),
    ("sensor_gps", "fix_type", "satellites_used", ("hdop", 1.0), "jamming_indicator"),
    ("GPS", "Status", "NSats", ("HDop", 1.0), None),
    # MAVLink GPS_RAW_INT.eph is HDOP x 100 (UINT16_MAX when unknown).
    ("GPS_RAW_INT", "fix_type", "satellites_visible", ("eph", 0.01), None),
    # dRonin GPSPosition (gpsposition.xml): Status is an enumeration, read by its labels.
    ("GPSPosition", "Status", "Satellites", ("HDOP", 1.0), None),
)
FIX_3D = 3  # GPS_FIX_TYPE_3D_FIX (MAVLink), PX4 fix_type 3, ArduPilot GPS status 3
# dRonin GPSPosition.Status options in the order of the fix types above.
DRONIN_FIX = {"NoGPS": 0.0, "NoFix": 1.0, "Fix2D": 2.0, "Fix3D": 3.0, "Diff3D": 4.0}
# ROS sensor_msgs/NavSatFix: status.status is STATUS_NO_FIX (-1), STATUS_FIX (0),
# STATUS_SBAS_FIX (1) or STATUS_GBAS_FIX (2); a fix carries a 3D position (latitude,
# longitude, altitude), so any status from 0 up counts as a 3D fix.
NAVSATFIX_FIELDS = ("status/status", "latitude", "longitude", "altitude")


def gps(view: LogView, thresholds: dict) -> Result:
    """Outages (fix below 3D, or no GPS record for outage_s) once a fix was had and while
    armed, too few satellites, a high HDOP and jamming."""
    name = "gps"
    level = thresholds["gps"]
    for row in _GPS:
        topic, fix_f = row[0], row[1]
        layers = [x for x in view.instances(topic) if view.path(x, fix_f)]
        if layers:
            return _gps_receiver(name, view, level, layers[0], row)
    for layer in view.layers_with(*NAVSATFIX_FIELDS):
        return _gps_receiver(name, view, level, layer, (layer, "status/status", None, None, None))
    return not_checked(
        name, "no vehicle_gps_position, GPS, GPS_RAW_INT, GPSPosition or NavSatFix status"
    )


def _fix_types(view: LogView, topic: str, fix_f: str, path: str) -> tuple[np.ndarray, np.ndarray]:
    """The fix as a fix type (3 a 3D fix) whatever the log recorded."""
    if topic == "GPSPosition":
        return view.labelled(path, DRONIN_FIX)
    t, v = view.read(path)
    if fix_f == NAVSATFIX_FIELDS[0]:
        return t, np.where(np.isfinite(v), np.where(v >= 0, float(FIX_3D), 1.0), np.nan)
    return t, v


def _gps_receiver(name: str, view: LogView, level: dict, layer: str, row: GpsRow) -> Result:
    """The findings of one receiver (its _GPS row) from its first 3D fix on."""
    topic, fix_f, sats_f, hdop, jam_f = row
    fix_path = view.path(layer, fix_f)
    t, fix = _fix_types(view, topic, fix_f, fix_path)
    if len(t) < 2:
        return not_checked(name, f"too few {topic} samples")
    has_fix = fix >= FIX_3D
    if not has_fix.any():
        return not_checked(name, f"no 3D fix in {topic}")
    first_fix = float(t[np.argmax(has_fix)])
    outages = _gps_outages(name, t, view.armed_at(t) & (t >= first_fix), has_fix, level)
    series = [fix_path]
    sats_path = view.path(layer, sats_f) if sats_f else None
    satellites = None
    if sats_path:
        series.append(sats_path)
        satellites = _fewest_satellites(name, view, sats_path, first_fix, level)
    hdop_f, hdop_scale = hdop or ("", 1.0)
    hdop_path = view.path(layer, hdop_f) if hdop_f else None
    high_hdop = (
        _high_hdop(name, view, hdop_path, hdop_scale, first_fix, level) if hdop_path else None
    )
    if high_hdop:
        series.append(hdop_path)
    jam_path = view.path(layer, jam_f) if jam_f else None
    jamming = _jamming(name, view, jam_path, level["jamming"]) if jam_path else None
    if jamming:
        series.append(jam_path)
    findings = [r for r in (outages, satellites, high_hdop, jamming) if r is not None]
    if not findings:
        findings.append(Result(name, PASS, None, "", None, None, f"{topic} had a 3D fix"))
    result = worst(findings)
    if result.status == PASS:
        result.reason = f"no outage; {result.reason}"
    result.series = series
    result.window = window_around(view, result.t)
    return result


def _gps_outages(
    name: str, t: np.ndarray, armed: np.ndarray, has_fix: np.ndarray, level: dict
) -> Result | None:
    """A failure for every outage while armed after the first fix, at the first one."""
    # Fix lost.
    lost = timed_runs(t, armed & ~has_fix)
    # No record at all for outage_s (the receiver or its link went silent).
    gaps = np.flatnonzero((np.diff(t) >= level["outage_s"]) & armed[:-1])
    lost += [(float(t[i]), float(t[i + 1])) for i in gaps]
    lost.sort()
    if not lost:
        return None
    longest = max(b - a for a, b in lost)
    return Result(
        name,
        FAIL,
        longest,
        "s",
        {"outage_s": level["outage_s"]},
        lost[0][0],
        f"GPS outage at {lost[0][0]:.1f} s ({len(lost)} in all, longest {longest:.1f} s)",
    )


def _fewest_satellites(
    name: str, view: LogView, path: str, first_fix: float, level: dict
) -> Result | None:
    """The fewest satellites while armed after the first fix: a warning below
    min_satellites, else a pass at the lowest count."""
    ts, sats = view.read(path)
    ok = view.armed_at(ts) & (ts >= first_fix) & np.isfinite(sats)
    if not ok.any():
        return None
    low = float(np.min(sats[ok]))
    at = first_time(ts, ok & (sats < level["min_satellites"]))
    return Result(
        name,
        WARNING if at is not None else PASS,
        low,
        "satellites",
        {"min_satellites": level["min_satellites"]},
        at if at is not None else float(ts[ok][np.argmin(sats[ok])]),
        f"{low:.0f} satellites at least"
        + (f", below {level['min_satellites']:g} from {at:.1f} s" if at is not None else ""),
    )


def _high_hdop(
    name: str, view: LogView, path: str, scale: float, first_fix: float, level: dict
) -> Result | None:
    """A warning from the first HDOP over max_hdop while armed after the first fix."""
    th, hdop = view.read(path)
    # 65535 (UINT16_MAX) is an unknown HDOP.
    hdop = np.where(hdop >= 65535, np.nan, hdop) * scale
    ok = view.armed_at(th) & (th >= first_fix) & np.isfinite(hdop)
    at = first_time(th, ok & (hdop > level["max_hdop"]))
    if at is None:
        return None
    return Result(
        name,
        WARNING,
        float(np.nanmax(hdop[ok])),
        "HDOP",
        {"max_hdop": level["max_hdop"]},
        at,
        f"HDOP over {level['max_hdop']:g} from {at:.1f} s",
    )


def _jamming(name: str, view: LogView, path: str, level: dict[str, float]) -> Result | None:
    """The highest jamming indicator while armed graded against its levels, from the first
    time over the level reached; nothing when it stays under both."""
    tj, jam = _armed_values(view, path)
    if not len(tj):
        return None
    value = float(np.max(jam))
    status = grade(value, level)
    if status == PASS:
        return None
    limit = level["fail" if status == FAIL else "warning"]
    at = first_time(tj, jam > limit)
    return Result(
        name,
        status,
        value,
        "",
        dict(level),
        at,
        f"jamming indicator {value:.0f} (over {limit:g}) from {at:.1f} s",
    )


# --- estimator ---

_RATIOS = (
    # PX4 estimator_status test ratios; ArduPilot XKF4/NKF4 innovation test ratios (the
    # square root of the normalised innovation); MAVLink EKF_STATUS_REPORT (ArduPilot)
    # and ESTIMATOR_STATUS (PX4).
    (
        "estimator_status",
        (
            "vel_test_ratio",
            "pos_test_ratio",
            "hgt_test_ratio",
            "mag_test_ratio",
            "tas_test_ratio",
            "hagl_test_ratio",
        ),
    ),
    ("XKF4", ("SV", "SP", "SH", "SM", "SVT")),
    ("NKF4", ("SV", "SP", "SH", "SMX", "SVT")),
    (
        "EKF_STATUS_REPORT",
        (
            "velocity_variance",
            "pos_horiz_variance",
            "pos_vert_variance",
            "compass_variance",
            "terrain_alt_variance",
        ),
    ),
    (
        "ESTIMATOR_STATUS",
        ("vel_ratio", "pos_horiz_ratio", "pos_vert_ratio", "mag_ratio", "hagl_ratio", "tas_ratio"),
    ),
)


def estimator(view: LogView, thresholds: dict) -> Result:
    """The highest innovation test ratio held for HELD_RECORDS records while armed."""
    name = "estimator"
    for topic, fields in _RATIOS:
        curves = []
        for layer in view.instances(topic):
            for f in fields:
                p = view.path(layer, f)
                if p:
                    t, v = _armed_values(view, p)
                    curves.append((p, t, held(v, HELD_RECORDS)))
        if curves:
            result = _peak_result(
                name, view, curves, thresholds["estimator"], "", f"{topic} test ratio"
            )
            if result.status != "not_checked":
                peak = result.series[0]
                result.reason = result.reason.replace(
                    "test ratio", f"test ratio ({peak.split('/')[-1]})", 1
                )
            return result
    return not_checked(name, "no estimator_status, XKF4, NKF4 or EKF_STATUS_REPORT")
