"""The simulator as a UAVTalk board, seen raw through a real pseudo-terminal."""

from __future__ import annotations

import struct
import time

import pytest
import serial

from firmware.sim import start_simulator
from onboard.uavtalk import Codec, FrameDecoder, MessageType, ObjectRegistry, encode_frame

REGISTRY = ObjectRegistry.load()
CODEC = Codec(REGISTRY)
GCS = REGISTRY["GCSTelemetryStats"].defaults()


class RawGround:
    """A minimal ground station: the codec over pyserial, no driver."""

    def __init__(self, path: str, *, ack: bool = True) -> None:
        self.port = serial.Serial(path, 115200, timeout=0.02)
        self.decoder = FrameDecoder(REGISTRY)
        self.ack = ack
        self.frames = []

    def send(self, wire: bytes) -> None:
        self.port.write(wire)

    def pump(self, seconds: float, until=None):
        deadline = time.monotonic() + seconds
        found = None
        while time.monotonic() < deadline and found is None:
            for frame in self.decoder.feed(self.port.read(4096)):
                self.frames.append(frame)
                if self.ack and frame.type == MessageType.OBJ_ACK:
                    self.send(CODEC.encode_reply(MessageType.ACK, frame))
                if found is None and until is not None and until(frame):
                    found = frame
        return found

    def connect(self) -> None:
        self.send(CODEC.encode_object("GCSTelemetryStats", GCS | {"Status": "HandshakeReq"}))
        ack = self.pump(3, lambda f: f.name == "FlightTelemetryStats")
        assert ack is not None and ack.fields()["Status"] == "HandshakeAck"
        self.send(CODEC.encode_object("GCSTelemetryStats", GCS | {"Status": "Connected"}))
        done = self.pump(
            3,
            lambda f: f.name == "FlightTelemetryStats" and f.fields()["Status"] == "Connected",
        )
        assert done is not None

    def close(self) -> None:
        self.port.close()


@pytest.fixture
def board():
    sim = start_simulator(time_scale=10.0, extra_args=["--link-timeout", "1.0"])
    yield sim
    sim.stop()


def test_the_simulator_prints_its_pty_and_answers_the_handshake(board):
    assert board.pty_path.startswith("/dev/pts/")
    ground = RawGround(board.pty_path)
    ground.connect()
    ground.close()


def test_objects_stream_at_their_update_periods_in_simulated_time(board):
    ground = RawGround(board.pty_path)
    ground.connect()
    ground.frames.clear()
    # Ten simulated seconds (one at time scale 10), measured on the board's own clock: from
    # one PositionActual (every 1 s simulated) to the tenth after it, however loaded the host.
    # The ground keeps its side of the link alive meanwhile, as a real one does.
    positions = []
    deadline = time.monotonic() + 20.0
    while len(positions) < 11 and time.monotonic() < deadline:
        ground.send(CODEC.encode_object("GCSTelemetryStats", GCS | {"Status": "Connected"}))
        ground.pump(0.1)
        positions = [i for i, f in enumerate(ground.frames) if f.name == "PositionActual"]
    assert len(positions) >= 11, "the board sent too few PositionActual"
    counts = {}
    for frame in ground.frames[positions[0] : positions[10]]:
        counts[frame.name] = counts.get(frame.name, 0) + 1
    # Every 100 ms simulated; a loaded host may make the board skip a late period, as a
    # real one skips an overrun, never send extra.
    assert 80 <= counts["AttitudeActual"] <= 110
    assert 4 <= counts["GPSPosition"] <= 6  # every 2 s simulated
    gps = next(f for f in ground.frames if f.name == "GPSPosition").fields()
    assert gps["Status"] == "Fix3D" and gps["Satellites"] >= 7
    ground.close()


def test_unknown_objects_are_nacked_and_known_ones_answered(board):
    ground = RawGround(board.pty_path)
    ground.connect()
    ground.send(encode_frame(MessageType.OBJ_REQ, 0x12345678))
    nack = ground.pump(2, lambda f: f.type == MessageType.NACK)
    assert nack is not None and nack.object_id == 0x12345678
    ground.send(CODEC.encode_request("HomeLocation"))
    home = ground.pump(2, lambda f: f.name == "HomeLocation")
    assert home is not None and home.fields()["Set"] == "TRUE"
    ground.close()


def test_acked_writes_are_acked_and_unacked_board_objects_are_resent_three_times(board):
    ground = RawGround(board.pty_path, ack=False)
    ground.connect()
    ground.pump(1.5)
    homes = [f for f in ground.frames if f.name == "HomeLocation"]
    assert len(homes) == 4  # the first send plus three retries, 250 ms apart
    assert all(f.type == MessageType.OBJ_ACK for f in homes)
    receiver = CODEC.encode_object(
        "UAVTalkReceiver", {"Channel": [1500] * 8, "RSSI": 65535}, acked=True
    )
    ground.send(receiver)
    ack = ground.pump(2, lambda f: f.type == MessageType.ACK)
    assert ack is not None and ack.object_id == REGISTRY["UAVTalkReceiver"].id
    ground.close()


def test_receiver_frames_of_the_old_definition_are_refused_like_a_real_board(board):
    """Channel-only UAVTalkReceiver (no RSSI) has another id: NACKed; right id, 16 bytes: dropped."""
    old_id = 0xE9DAD5F4
    channels = struct.pack("<8H", *([1500] * 8))
    ground = RawGround(board.pty_path)
    ground.connect()
    ground.send(encode_frame(MessageType.OBJ_ACK, old_id, channels))
    nack = ground.pump(2, lambda f: f.type in (MessageType.NACK, MessageType.ACK))
    assert nack is not None and nack.type == MessageType.NACK and nack.object_id == old_id
    receiver_id = REGISTRY["UAVTalkReceiver"].id
    ground.send(encode_frame(MessageType.OBJ_ACK, receiver_id, channels))
    assert ground.pump(1, lambda f: f.type in (MessageType.NACK, MessageType.ACK)) is None
    ground.send(encode_frame(MessageType.OBJ_ACK, receiver_id, channels + b"\xff\xff"))
    ack = ground.pump(2, lambda f: f.type in (MessageType.NACK, MessageType.ACK))
    assert ack is not None and ack.type == MessageType.ACK and ack.object_id == receiver_id
    ground.close()


def test_the_board_drops_to_disconnected_after_silence(board):
    ground = RawGround(board.pty_path)
    ground.connect()
    time.sleep(1.3)  # the simulator was started with a 1 s link timeout
    ground.port.reset_input_buffer()
    ground.decoder = FrameDecoder(REGISTRY)
    ground.frames.clear()
    # A keep-alive now is answered with the truth: the board is not connected any more.
    ground.send(CODEC.encode_object("GCSTelemetryStats", GCS | {"Status": "Connected"}))
    stats = ground.pump(2, lambda f: f.name == "FlightTelemetryStats")
    assert stats is not None and stats.fields()["Status"] == "Disconnected"
    assert not any(f.name == "AttitudeActual" for f in ground.frames)
    ground.close()


def test_garbage_on_the_line_does_not_stop_the_board(board):
    ground = RawGround(board.pty_path)
    ground.send(bytes(range(256)) * 8 + b"\x3c\x20\xff\xff" + b"\x3c" * 300)
    ground.connect()
    ground.close()
    assert board.alive()


def test_many_simulators_run_at_once_each_on_its_own_pty():
    sims = [start_simulator(home=(38.7 + i * 0.01, -9.1, 50.0), time_scale=10.0) for i in range(3)]
    try:
        assert len({s.pty_path for s in sims}) == 3
        for i, sim in enumerate(sims):
            ground = RawGround(sim.pty_path)
            ground.connect()
            ground.send(CODEC.encode_request("HomeLocation"))
            home = ground.pump(2, lambda f: f.name == "HomeLocation" and f.type == MessageType.OBJ)
            assert home is not None
            assert home.fields()["Latitude"] == round((38.7 + i * 0.01) * 1e7)
            ground.close()
    finally:
        for sim in sims:
            sim.stop()


def test_the_simulator_serves_tcp_like_flightd():
    import socket

    sim = start_simulator(time_scale=10.0, tcp_port=0)
    try:
        host, port = sim.tcp_address
        assert sim.url == f"tcp://{host}:{port}"
        sock = socket.create_connection((host, port), timeout=2)
        sock.sendall(CODEC.encode_object("GCSTelemetryStats", GCS | {"Status": "HandshakeReq"}))
        decoder = FrameDecoder(REGISTRY)
        deadline = time.monotonic() + 3
        status = None
        while time.monotonic() < deadline and status is None:
            for frame in decoder.feed(sock.recv(4096)):
                if frame.name == "FlightTelemetryStats":
                    status = frame.fields()["Status"]
        assert status == "HandshakeAck"
        sock.close()
    finally:
        sim.stop()


def test_a_bad_home_is_refused_with_a_clear_message():
    from firmware.sim import SimulatorError

    with pytest.raises(SimulatorError):
        start_simulator(home=(123.0, 0.0, 0.0))


def test_writing_an_objects_metadata_changes_its_stream_rate(board):
    from onboard.uavtalk import pack_metadata

    ground = RawGround(board.pty_path)
    ground.connect()
    attitude = REGISTRY["AttitudeActual"]
    throttled = 3 << 4  # flight update mode "throttled" in the metadata flags
    meta = encode_frame(MessageType.OBJ_ACK, attitude.id + 1, pack_metadata(throttled, 1000, 0, 0))
    ground.send(meta)
    assert ground.pump(2, lambda f: f.type == MessageType.ACK) is not None
    ground.frames.clear()
    ground.pump(1.0)  # ten simulated seconds
    count = sum(1 for f in ground.frames if f.name == "AttitudeActual")
    # Once a simulated second instead of ten times: measured 9, quiet and with four busy
    # processes on two cores.
    assert 8 <= count <= 12
    ground.send(CODEC.encode_request("AttitudeActual"))  # a plain request still answers
    assert ground.pump(2, lambda f: f.name == "AttitudeActual") is not None
    ground.close()


def test_the_board_reports_its_link_rates_in_bytes_per_second(board):
    ground = RawGround(board.pty_path)
    ground.connect()
    keepalive = CODEC.encode_object("GCSTelemetryStats", GCS | {"Status": "Connected"})
    stats = None
    deadline = time.monotonic() + 15
    while stats is None and time.monotonic() < deadline:
        ground.send(keepalive)
        stats = ground.pump(
            0.5,
            lambda f: f.name == "FlightTelemetryStats" and f.fields()["TxDataRate"] > 0,
        )
    ground.close()
    assert stats is not None, "no FlightTelemetryStats with a data rate"
    fields = stats.fields()
    # The board streams several objects many times a second; the ground sends keep-alives.
    assert fields["TxDataRate"] > 100
    assert 0 < fields["RxDataRate"] < fields["TxDataRate"]


@pytest.mark.parametrize(("firmware", "other"), [("release", "latest"), ("latest", "release")])
def test_each_generation_takes_its_own_manual_control_settings_and_nacks_the_others(
    firmware, other
):
    agent = ObjectRegistry.load(every_generation=True)
    own, foreign = (agent.for_generation(g)["ManualControlSettings"] for g in (firmware, other))
    sim = start_simulator(time_scale=10.0, firmware=firmware)
    ground = RawGround(sim.pty_path)
    try:
        ground.connect()
        for obj in (foreign, own):
            ground.send(encode_frame(MessageType.OBJ_ACK, obj.id, obj.pack(obj.defaults())))
            reply = ground.pump(2, lambda f: f.type in (MessageType.NACK, MessageType.ACK))
            assert reply is not None and reply.object_id == obj.id
            assert reply.type == (MessageType.ACK if obj is own else MessageType.NACK)
        ground.send(encode_frame(MessageType.OBJ_REQ, foreign.id))
        nack = ground.pump(2, lambda f: f.object_id == foreign.id)
        assert nack is not None and nack.type == MessageType.NACK
    finally:
        ground.close()
        sim.stop()
