import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from logs import LogFormatError, find_special, import_log
from logs.analysis import trajectory_of

# ardrone_autonomy/Navdata as its package defines it.
NAVDATA_MSG = """Header header
float32 batteryPercent
uint32 state
int32 magX
int32 magY
int32 magZ
int32 pressure
int32 temp
float32 wind_speed
float32 wind_angle
float32 wind_comp_angle
float32 rotX
float32 rotY
float32 rotZ
int32 altd
float32 vx
float32 vy
float32 vz
float32 ax
float32 ay
float32 az
uint8 motor1
uint8 motor2
uint8 motor3
uint8 motor4
uint32 tags_count
uint32[] tags_type
uint32[] tags_xc
uint32[] tags_yc
uint32[] tags_width
uint32[] tags_height
float32[] tags_orientation
float32[] tags_distance
float32 tm
"""
NAVDATA = "ardrone_autonomy/msg/Navdata"
T0 = 1_400_000_000 * 10**9


def write_bag(path, n=100, compression=None):
    """An ardrone_autonomy bag of `n` Navdata messages; `compression`: "bz2", "lz4" or None."""
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(NAVDATA_MSG, NAVDATA))
    Navdata = store.types[NAVDATA]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    Twist = store.types["geometry_msgs/msg/Twist"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    empty_u32 = np.zeros(0, dtype=np.uint32)
    empty_f32 = np.zeros(0, dtype=np.float32)
    writer = Writer(path)
    if compression:
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    with writer:
        nav = writer.add_connection("/ardrone/navdata", NAVDATA, typestore=store)
        cmd = writer.add_connection("/cmd_vel", "geometry_msgs/msg/Twist", typestore=store)
        for i in range(n):
            stamp = T0 + i * 5_000_000  # 200 Hz
            msg = Navdata(
                header=Header(
                    seq=i,
                    stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9),
                    frame_id="ardrone_base_link",
                ),
                batteryPercent=80.0 - i * 0.01,
                state=3,
                magX=10,
                magY=-20,
                magZ=30,
                pressure=101000,
                temp=300,
                wind_speed=0.0,
                wind_angle=0.0,
                wind_comp_angle=0.0,
                rotX=1.0,
                rotY=-2.0,
                rotZ=90.0,
                altd=1000 + i,
                vx=500.0,
                vy=0.0,
                vz=0.0,
                ax=0.0,
                ay=0.0,
                az=1.0,
                motor1=100,
                motor2=101,
                motor3=102,
                motor4=103,
                tags_count=0,
                tags_type=empty_u32,
                tags_xc=empty_u32,
                tags_yc=empty_u32,
                tags_width=empty_u32,
                tags_height=empty_u32,
                tags_orientation=empty_f32,
                tags_distance=empty_f32,
                tm=float(i * 5000),
            )
            writer.write(nav, stamp, store.serialize_ros1(msg, NAVDATA))
            if i % 10 == 0:
                twist = Twist(
                    linear=Vector3(x=0.5, y=0.0, z=0.1 * i), angular=Vector3(x=0.0, y=0.0, z=-0.2)
                )
                writer.write(cmd, stamp, store.serialize_ros1(twist, "geometry_msgs/msg/Twist"))
    return path


def test_ardrone_bag_maps_navdata_to_the_special_quantities(tmp_path):
    log = import_log(write_bag(tmp_path / "flight.bag"))
    assert log.layers == ["ardrone_navdata", "cmd_vel"]
    special = find_special(log)
    assert special["altitude"] == ["ardrone_navdata/altd"]
    assert special["velocity"] == ["ardrone_navdata/vx", "ardrone_navdata/vy", "ardrone_navdata/vz"]
    assert special["rotation"] == [
        "ardrone_navdata/rotX",
        "ardrone_navdata/rotY",
        "ardrone_navdata/rotZ",
    ]
    assert special["battery"] == ["ardrone_navdata/batteryPercent"]
    assert special["motors"] == [f"ardrone_navdata/motor{i}" for i in range(1, 5)]
    altd = log.series["ardrone_navdata/altd"]
    assert altd.unit == "mm" and altd.values[:3].tolist() == [1000, 1001, 1002]
    assert altd.times[1] - altd.times[0] == 5_000_000
    state = log.series["ardrone_navdata/state"]
    assert state.labels[int(state.values[0])] == "Flying"


def test_ardrone_bag_gives_a_trajectory_heading_east(tmp_path):
    # 0.5 m/s forward with yaw 90 degrees for 0.495 s: about 247 mm east (negative y, west).
    tr = trajectory_of(import_log(write_bag(tmp_path / "flight.bag")))
    assert tr.unit == "mm"
    assert tr.x[-1] == pytest.approx(0, abs=1e-6)
    assert tr.y[-1] == pytest.approx(-247.5, abs=0.1)


def test_generic_topics_flatten_nested_fields(tmp_path):
    log = import_log(write_bag(tmp_path / "flight.bag"))
    assert log.series["cmd_vel/linear/z"].values.tolist() == pytest.approx(
        [0.1 * i for i in range(0, 100, 10)]
    )
    assert log.series["cmd_vel/angular/z"].time_source == "recorder"
    assert log.series["ardrone_navdata/header/frame_id"].kind == "text"


def test_truncated_bag_is_rejected(tmp_path):
    path = write_bag(tmp_path / "flight.bag")
    path.write_bytes(path.read_bytes()[:3000])
    with pytest.raises(LogFormatError, match="ROS 1 bag"):
        import_log(path)
