"""The automatic log checks on a dRonin drone's DFI recording, written by the agent's own
recorder (onboard/logger.py) from decoded UAVTalk objects, and on a ROS bag written with
the rosbags writer: each finding at its time and severity, and a clean flight with none."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

from logs.checks import CHECKS, run_checks
from logs.store import import_to_store
from onboard.logger import FlightLogger

T0 = 1_795_341_600.0
DURATION = 60
ARMED = (2.0, 58.0)
GPS_OUT = (20.0, 23.0)
SAG = (30.0, 32.0)
CPU_SPIKE = (40.0, 43.0)
TAKEOVER = 50.0


def _checks(tmp_path, archive) -> dict[str, dict]:
    store = import_to_store(archive, tmp_path / "store")
    results = run_checks(store)
    assert [r["name"] for r in results] == list(CHECKS)
    return {r["name"]: r for r in results}


def _in(t: float, span: tuple[float, float]) -> bool:
    return span[0] <= t < span[1]


def dronin_flight(directory, *, faults: bool, battery: bool = True):
    """A minute of a 4S dRonin quadcopter as the agent records it: the objects at their
    telemetry rates (GPSPosition 2 Hz, the others 1 Hz), enumerations as their labels.
    GPSPosition's first Status is Fix3D, so the recording numbers the labels in another
    order than gpsposition.xml does (a reader of the numbers would get them wrong)."""
    logger = FlightLogger(directory, "DRONIN1")
    for k in range(DURATION * 2):
        t = k / 2
        ts = T0 + t
        lost = faults and _in(t, GPS_OUT)
        logger.telemetry(
            "GPSPosition",
            ts,
            {
                "Status": "NoFix" if lost else "Fix3D",
                "Latitude": 501000000 + k,
                "Longitude": 144000000,
                "Altitude": 300.0,
                "Satellites": 4 if lost else 12,
                "PDOP": 9.9 if lost else 1.4,
                "HDOP": 9.9 if lost else 0.9,
                "VDOP": 9.9 if lost else 1.1,
            },
        )
        if k % 2:
            continue
        armed = ARMED[0] <= t < ARMED[1]
        taken = faults and t >= TAKEOVER and armed
        logger.telemetry(
            "FlightStatus",
            ts,
            {
                "Armed": "Armed" if armed else "Disarmed",
                "FlightMode": "ReturnToHome" if taken else "PositionHold",
                "ControlSource": "Failsafe" if taken else "Transmitter",
            },
        )
        logger.telemetry(
            "ManualControlCommand",
            ts,
            {"Connected": "False" if taken else "True", "Throttle": 0.5, "Rssi": 80},
        )
        if battery:
            sag = faults and _in(t, SAG)
            logger.telemetry(
                "FlightBatteryState",
                ts,
                {
                    "Voltage": 13.0 if sag else 16.4 - 0.01 * t,
                    "Current": 40.0 if sag else 12.0,
                    "DetectedCellCount": 4,
                },
            )
        spike = faults and _in(t, CPU_SPIKE)
        logger.telemetry("SystemStats", ts, {"CPULoad": 97 if spike else 35, "CPUTemp": 40})
        logger.telemetry("Accels", ts, {"x": 0.1, "y": -0.1, "z": -9.8, "temperature": 30.0})
    return logger.close()


def test_a_dronin_recording_reports_each_fault_at_its_time(tmp_path):
    found = _checks(tmp_path, dronin_flight(tmp_path / "rec", faults=True))

    gps = found["gps"]
    assert gps["status"] == "fail"
    assert gps["t"] == pytest.approx(GPS_OUT[0])
    assert "GPSPosition/Status" in gps["series"]

    sag = found["battery_sag"]
    assert sag["status"] == "fail"
    assert sag["t"] == pytest.approx(SAG[0])
    assert sag["value"] == pytest.approx(13.0 / 4)
    assert "4 cells, recorded" in sag["reason"] and "drawing 40.0 A" in sag["reason"]

    cpu = found["cpu_load"]
    assert cpu["status"] == "fail"
    assert cpu["value"] == pytest.approx(0.97)
    # The rule holds a load for three records: the third record of the spike.
    assert cpu["t"] == pytest.approx(CPU_SPIKE[0] + 2)

    failsafe = found["failsafe"]
    assert failsafe["status"] == "fail"
    assert failsafe["t"] == pytest.approx(TAKEOVER)
    assert "ReturnToHome" in failsafe["reason"]

    rc = found["rc_loss"]
    assert rc["status"] == "fail"
    assert rc["t"] == pytest.approx(TAKEOVER)

    # Accels arrive once a second: too slow for the vibration metric, and said so.
    assert found["vibration"]["status"] == "not_checked"
    assert "Accels recorded at 1 Hz" in found["vibration"]["reason"]
    assert found["clipping"]["status"] == "not_checked"


def test_a_clean_dronin_recording_has_no_finding(tmp_path):
    found = _checks(tmp_path, dronin_flight(tmp_path / "rec", faults=False))
    for name in ("gps", "battery_sag", "cpu_load", "failsafe", "rc_loss"):
        assert found[name]["status"] == "pass", (name, found[name])
    assert found["gps"]["value"] == 12.0  # the fewest satellites while armed


def test_a_dronin_recording_without_a_battery_object_is_not_checked(tmp_path):
    found = _checks(tmp_path, dronin_flight(tmp_path / "rec", faults=True, battery=False))
    sag = found["battery_sag"]
    assert sag["status"] == "not_checked"
    assert sag["reason"].startswith("no ") and "FlightBatteryState" in sag["reason"]
    assert found["gps"]["status"] == "fail"


ROS_OUT = (10.0, 13.0)
ROS_T0 = 1_700_000_000 * 10**9
IMU_HZ = 200
# m/s² per axis: the change between samples averages about 1.6 x IMU_NOISE x sqrt(2), a
# metric near 1.4 m/s², under PX4's 4.9 m/s² warning.
IMU_NOISE = 0.6


def ros_bag(path, *, outage: bool):
    """30 s of mavros' NavSatFix at 5 Hz and a 3S BatteryState at 1 Hz (sensor_msgs as
    ROS Noetic defines them), the fix lost for ROS_OUT when `outage`."""
    store = get_typestore(Stores.ROS1_NOETIC)
    NavSatFix = store.types["sensor_msgs/msg/NavSatFix"]
    NavSatStatus = store.types["sensor_msgs/msg/NavSatStatus"]
    BatteryState = store.types["sensor_msgs/msg/BatteryState"]
    Imu = store.types["sensor_msgs/msg/Imu"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    with Writer(path) as writer:
        fix_c = writer.add_connection(
            "/mavros/global_position/raw/fix", "sensor_msgs/msg/NavSatFix", typestore=store
        )
        bat_c = writer.add_connection(
            "/mavros/battery", "sensor_msgs/msg/BatteryState", typestore=store
        )
        imu_c = writer.add_connection("/mavros/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        rng = np.random.default_rng(7)
        for k in range(30 * IMU_HZ):
            stamp = ROS_T0 + k * (10**9 // IMU_HZ)
            header = Header(
                seq=k, stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="imu"
            )
            ax, ay, az = rng.normal(0.0, IMU_NOISE, 3)
            imu = Imu(
                header=header,
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=Vector3(x=0.0, y=0.0, z=0.0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vector3(x=ax, y=ay, z=9.81 + az),
                linear_acceleration_covariance=np.zeros(9),
            )
            writer.write(imu_c, stamp, store.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
        for i in range(150):
            t = i / 5
            stamp = ROS_T0 + i * 200_000_000
            header = Header(
                seq=i, stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="gps"
            )
            lost = outage and _in(t, ROS_OUT)
            fix = NavSatFix(
                header=header,
                status=NavSatStatus(status=-1 if lost else 0, service=1),
                latitude=50.1,
                longitude=14.4,
                altitude=300.0,
                position_covariance=np.full(9, 4.0),
                position_covariance_type=2,
            )
            writer.write(fix_c, stamp, store.serialize_ros1(fix, "sensor_msgs/msg/NavSatFix"))
            if i % 5:
                continue
            battery = BatteryState(
                header=header,
                voltage=12.4,
                temperature=25.0,
                current=-8.0,
                charge=2.0,
                capacity=2.2,
                design_capacity=2.2,
                percentage=0.9,
                power_supply_status=2,
                power_supply_health=1,
                power_supply_technology=3,
                present=True,
                cell_voltage=np.zeros(0, dtype=np.float32),
                cell_temperature=np.zeros(0, dtype=np.float32),
                location="",
                serial_number="",
            )
            writer.write(
                bat_c, stamp, store.serialize_ros1(battery, "sensor_msgs/msg/BatteryState")
            )
    return path


@pytest.mark.parametrize("outage", [True, False])
def test_a_ros_bag_gps_outage_is_found(tmp_path, outage):
    found = _checks(tmp_path, ros_bag(tmp_path / "flight.bag", outage=outage))
    gps = found["gps"]
    assert "mavros_global_position_raw_fix/status/status" in gps["series"]
    if outage:
        assert gps["status"] == "fail"
        assert gps["t"] == pytest.approx(ROS_OUT[0])
        assert gps["value"] == pytest.approx(ROS_OUT[1] - ROS_OUT[0])
    else:
        assert gps["status"] == "pass"
    battery = found["battery_sag"]
    assert battery["status"] == "pass"
    assert battery["value"] == pytest.approx(12.4 / 3, rel=1e-6)
    assert "drawing 8.0 A" in battery["reason"]
    vibration = found["vibration"]
    assert vibration["status"] == "pass"
    assert 0.8 < vibration["value"] < 2.5
    assert "mavros_imu_data/linear_acceleration/z" in vibration["series"]


def test_dronin_accels_recorded_fast_enough_give_the_vibration_figure(tmp_path):
    """Accels at 200 Hz (a raised telemetry rate): PX4's metric recomputed from them,
    a shaking airframe over the 9.81 m/s² failure level."""
    logger = FlightLogger(tmp_path / "rec", "DRONIN1")
    rng = np.random.default_rng(3)
    for k in range(3 * IMU_HZ):
        ts = T0 + k / IMU_HZ
        if k % IMU_HZ == 0:
            logger.telemetry("FlightStatus", ts, {"Armed": "Armed", "FlightMode": "Manual"})
        x, y, z = rng.normal(0.0, 6.0, 3)
        logger.telemetry("Accels", ts, {"x": x, "y": y, "z": -9.81 + z, "temperature": 30.0})
    found = _checks(tmp_path, logger.close())
    vibration = found["vibration"]
    assert vibration["status"] == "fail"
    assert vibration["value"] > 9.81
    assert vibration["series"] == ["Accels/x", "Accels/y", "Accels/z"]
