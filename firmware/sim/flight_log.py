"""The simulated autopilot's own flight log, and MAVLink's log protocol to fetch it.

Like a real autopilot it logs from arming to disarming: the vehicle is sampled every
physics step and, at the disarm, the flight is written in the autopilot's own format —
PX4: a ULog [PX4 ULog file format] with vehicle_status, sensor_combined,
vehicle_gps_position, battery_status and vehicle_local_position; ArduPilot: a DataFlash
.bin [ArduPilot DataFlash logs] with FMT records and EV, IMU, GPS, BAT and POS, the
layouts of ArduCopter 4's. The writers are logs.synth's (the structure of each format,
tested against pyulog and pymavlink's readers).

The log protocol [MAVLink common]: LOG_REQUEST_LIST answered with one LOG_ENTRY per log
in the range (id, num_logs, last_log_num, time_utc, size); LOG_REQUEST_DATA (id, ofs,
count) queues that range, sent as LOG_DATA of up to 90 bytes, at most DATA_PER_TICK per
tick (a serial link's pace); LOG_REQUEST_END and LOG_ERASE stop what is queued (ERASE also
forgets the logs).
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

LOG_DATA_BYTES = 90
DATA_PER_TICK = 64
GRAVITY = 9.80665
# Accelerometer noise of a hovering multirotor's IMU (m/s², one sigma): the sensor the
# simulator models, drawn from a seeded generator so two runs log the same flight.
ACCEL_NOISE = 0.3
GYRO_NOISE = 0.01
SATELLITES = 14
HDOP = 0.8

Send = Callable[..., None]


class FlightRecorder:
    """Samples the vehicle while armed; `finish()` returns the flight's rows."""

    def __init__(self) -> None:
        self.rows: list[tuple] = []
        self._velocity: tuple[float, float, float] | None = None
        self._rng = np.random.default_rng(7)

    def sample(self, vehicle: Any, mode: str, dt: float) -> None:
        v = vehicle
        vel = tuple(v.velocity)
        previous = self._velocity or vel
        accel = [(a - b) / dt if dt > 0 else 0.0 for a, b in zip(vel, previous, strict=True)]
        self._velocity = vel
        lat, lon, alt = v.lla()
        self.rows.append(
            (
                v.time,
                *v.ned,
                *vel,
                accel[0] + self._rng.normal(0, ACCEL_NOISE),
                accel[1] + self._rng.normal(0, ACCEL_NOISE),
                accel[2] - GRAVITY + self._rng.normal(0, ACCEL_NOISE),
                lat,
                lon,
                alt,
                v.voltage,
                v.current_a,
                v.remaining,
                mode,
            )
        )

    def finish(self) -> list[tuple]:
        rows, self.rows, self._velocity = self.rows, [], None
        return rows


COLUMNS = (
    "t", "n", "e", "d", "vn", "ve", "vd", "ax", "ay", "az",
    "lat", "lon", "alt", "volt", "curr", "remaining", "mode",
)  # fmt: skip


def _columns(rows: list[tuple]) -> dict[str, np.ndarray]:
    table = {name: np.array([r[i] for r in rows]) for i, name in enumerate(COLUMNS)}
    table["us"] = np.round((table["t"] - table["t"][0] + 0.001) * 1e6).astype(np.uint64)
    return table


def _px4_topics(c: dict[str, np.ndarray], rng: np.random.Generator) -> dict[str, np.ndarray]:
    n = len(c["us"])

    def topic(fields: list[tuple[str, str]]) -> np.ndarray:
        arr = np.zeros(n, dtype=np.dtype([("timestamp", "<u8"), *fields]))
        arr["timestamp"] = c["us"]
        return arr

    status = topic([("arming_state", "u1"), ("nav_state", "u1"), ("failsafe", "?")])
    status["arming_state"] = 2  # ARMED: the log runs from arming to disarming
    status["nav_state"] = [PX4_NAV_STATES.get(m, 4) for m in c["mode"]]
    sensors = topic([("gyro_rad", "(3,)<f4"), ("accelerometer_m_s2", "(3,)<f4")])
    sensors["gyro_rad"] = rng.normal(0, GYRO_NOISE, size=(n, 3))
    sensors["accelerometer_m_s2"] = np.stack([c["ax"], c["ay"], c["az"]], axis=1)
    gps = topic(
        [("lat", "<i4"), ("lon", "<i4"), ("alt", "<i4"), ("hdop", "<f4"),
         ("fix_type", "u1"), ("satellites_used", "u1")]
    )  # fmt: skip
    gps["lat"], gps["lon"] = np.round(c["lat"] * 1e7), np.round(c["lon"] * 1e7)
    gps["alt"] = np.round(c["alt"] * 1000)
    gps["hdop"], gps["fix_type"], gps["satellites_used"] = HDOP, 3, SATELLITES
    battery = topic([("voltage_v", "<f4"), ("current_a", "<f4"), ("remaining", "<f4")])
    battery["voltage_v"], battery["current_a"] = c["volt"], c["curr"]
    battery["remaining"] = c["remaining"]
    local = topic([(k, "<f4") for k in ("x", "y", "z", "vx", "vy", "vz")])
    for key, column in zip(
        ("x", "y", "z", "vx", "vy", "vz"), ("n", "e", "d", "vn", "ve", "vd"), strict=True
    ):
        local[key] = c[column]
    return {
        "vehicle_status": status,
        "sensor_combined": sensors,
        "vehicle_gps_position": gps,
        "battery_status": battery,
        "vehicle_local_position": local,
    }


# PX4's vehicle_status.nav_state of the simulator's modes (PX4 v1.13 NAVIGATION_STATE_*).
PX4_NAV_STATES = {"GUIDED": 4, "TAKEOFF": 17, "LAND": 18, "RTL": 5, "AUTO": 3, "OFFBOARD": 14}


def _dataflash(c: dict[str, np.ndarray], rng: np.random.Generator) -> dict:
    from logs.synth import dataflash_dtype

    n = len(c["us"])

    def message(chars: str, columns: str) -> np.ndarray:
        arr = np.zeros(n, dtype=dataflash_dtype(chars, columns.split(",")))
        arr["TimeUS"] = c["us"]
        return arr

    events = np.zeros(2, dtype=dataflash_dtype("QB", ["TimeUS", "Id"]))
    events["TimeUS"] = [c["us"][0], c["us"][-1]]
    events["Id"] = [10, 11]  # ArduPilot LogEvent ARMED, DISARMED
    imu = message("Qffffff", "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    for axis in ("GyrX", "GyrY", "GyrZ"):
        imu[axis] = rng.normal(0, GYRO_NOISE, n)
    imu["AccX"], imu["AccY"], imu["AccZ"] = c["ax"], c["ay"], c["az"]
    gps = message("QBIHBcLLe", "TimeUS,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt")
    gps["Status"], gps["NSats"], gps["HDop"] = 3, SATELLITES, round(HDOP * 100)
    gps["Lat"], gps["Lng"] = np.round(c["lat"] * 1e7), np.round(c["lon"] * 1e7)
    gps["Alt"] = np.round(c["alt"] * 100)
    bat = message("Qfff", "TimeUS,Volt,VoltR,Curr")
    bat["Volt"] = bat["VoltR"] = c["volt"]
    bat["Curr"] = c["curr"]
    pos = message("QLLfff", "TimeUS,Lat,Lng,Alt,RelHomeAlt,RelOriginAlt")
    pos["Lat"], pos["Lng"] = np.round(c["lat"] * 1e7), np.round(c["lon"] * 1e7)
    pos["Alt"], pos["RelHomeAlt"] = c["alt"], -c["d"]
    pos["RelOriginAlt"] = -c["d"]
    return {
        "EV": ("QB", events),
        "IMU": ("Qffffff", imu),
        "GPS": ("QBIHBcLLe", gps),
        "BAT": ("Qfff", bat),
        "POS": ("QLLfff", pos),
    }


def write_flight(rows: list[tuple], autopilot: str) -> bytes:
    """The flight as the autopilot logs it: a ULog for PX4, a DataFlash .bin otherwise."""
    from logs.synth import write_dataflash, write_ulog

    columns = _columns(rows)
    rng = np.random.default_rng(11)
    with tempfile.TemporaryDirectory(prefix="sim-log-") as folder:
        path = Path(folder) / "flight"
        if autopilot == "px4":
            write_ulog(path, _px4_topics(columns, rng), info={"sys_name": "PX4", "ver_hw": "SIM"})
        else:
            write_dataflash(path, _dataflash(columns, rng))
        return path.read_bytes()


class LogServer:
    """The autopilot's logs, one per flight, served over MAVLink's log protocol."""

    def __init__(self, autopilot: str) -> None:
        self.autopilot = autopilot
        self.recorder = FlightRecorder()
        self.logs: list[tuple[int, bytes]] = []  # (time_utc, bytes); ids count from 1
        self.queue: list[tuple[int, int, int]] = []  # (id, offset, end) still to send
        self.data_sent = 0

    def record(self, vehicle: Any, mode: str, armed: bool, dt: float) -> None:
        """One physics step: sampled while armed; the disarm closes the flight's log."""
        if armed:
            self.recorder.sample(vehicle, mode, dt)
        elif self.recorder.rows:
            rows = self.recorder.finish()
            if len(rows) >= 2 and math.isfinite(rows[-1][0]):
                self.logs.append((int(time.time()), write_flight(rows, self.autopilot)))

    def handle(self, kind: str, msg: Any, send: Send) -> None:
        if kind == "LOG_REQUEST_LIST":
            self._list(msg.start, msg.end, send)
        elif kind == "LOG_REQUEST_DATA":
            self._request(msg.id, msg.ofs, msg.count)
        elif kind in ("LOG_REQUEST_END", "LOG_ERASE"):
            self.queue.clear()
            if kind == "LOG_ERASE":
                self.logs.clear()

    def _list(self, start: int, end: int, send: Send) -> None:
        count = len(self.logs)
        if count == 0:
            send("log_entry", 0, 0, 0, 0, 0)  # no logs: num_logs 0
            return
        for log_id in range(max(1, start), min(count, end) + 1):
            time_utc, data = self.logs[log_id - 1]
            send("log_entry", log_id, count, count, time_utc, len(data))

    def _request(self, log_id: int, offset: int, count: int) -> None:
        if not 1 <= log_id <= len(self.logs):
            return
        size = len(self.logs[log_id - 1][1])
        end = size if count == 0xFFFFFFFF else min(size, offset + count)
        self.queue = [(log_id, offset, end)] if offset < end else []

    def pump(self, send: Send) -> None:
        """Send the next LOG_DATA of the request, at most DATA_PER_TICK of them."""
        for _ in range(DATA_PER_TICK):
            if not self.queue:
                return
            log_id, offset, end = self.queue[0]
            chunk = self.logs[log_id - 1][1][offset : min(end, offset + LOG_DATA_BYTES)]
            send("log_data", log_id, offset, len(chunk), chunk.ljust(LOG_DATA_BYTES, b"\0"))
            self.data_sent += 1
            offset += len(chunk)
            self.queue = [(log_id, offset, end)] if offset < end else []
