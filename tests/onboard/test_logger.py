"""The DFI flight log: written incrementally, zipped at the end, valid per docs/dfi-format.md."""

from __future__ import annotations

from pathlib import Path

from onboard.logger import FlightLogger
from onboard.protocol import Position

from .dfi_rules import check_dfi, labels


def fly(logger: FlightLogger) -> None:
    logger.on_state(False)
    logger.event("arming", {"action": "arm", "phase": "requested"})
    logger.telemetry("FlightStatus", 100.0, {"Armed": "Armed", "FlightMode": "PositionHold"})
    logger.on_state(True)
    logger.event("arming", {"action": "arm", "phase": "done", "armed": True})
    logger.event("command", {"command": "takeoff", "params": {}})
    logger.event("response", {"command": "takeoff", "ok": True})
    for i in range(5):
        logger.telemetry(
            "AttitudeActual",
            100.0 + i / 10,
            {
                "q1": 1.0,
                "q2": 0.0,
                "q3": 0.0,
                "q4": 0.0,
                "Roll": 0.5 * i,
                "Pitch": float("nan"),
                "Yaw": 90.0,
            },
        )
        logger.telemetry(
            "Waypoint",
            100.0 + i,
            {"Position": [i, 0.0, -10.0], "Velocity": 2.0, "Mode": "Endpoint"},
        )
    logger.event(
        "mission", {"event": "decoded", "mission_id": "m-1", "steps": 2, "decode_ms": 0.42}
    )
    logger.event(
        "step",
        {
            "event": "started",
            "mission_id": "m-1",
            "index": 0,
            "command": "changeN",
            "position": Position(40.1, -8.2, 10.0),
        },
    )
    logger.event(
        "step",
        {
            "event": "completed",
            "mission_id": "m-1",
            "index": 0,
            "command": "changeN",
            "position": None,
            "duration_s": 3.5,
        },
    )
    logger.event(
        "alarm",
        {
            "level": "CRITICAL",
            "sensor": "battery",
            "value": 0.2,
            "position": {"lat": 40.1, "lon": -8.2, "alt": 10.0},
        },
    )
    logger.telemetry("FlightStatus", 110.0, {"Armed": "Disarmed", "FlightMode": "PositionHold"})


def test_a_flight_is_zipped_into_a_valid_dfi_archive_on_disarm(tmp_path: Path) -> None:
    logger = FlightLogger(tmp_path, "D1")
    fly(logger)
    archive = logger.on_state(False)
    assert archive is not None and archive.suffix == ".dfi"
    tables = check_dfi(archive)
    assert len(tables["AttitudeActual"]) == 5
    assert tables["AttitudeActual"][2][0] == str(100_200_000)  # microseconds
    assert tables["AttitudeActual"][0][6] == "nan"
    assert len(tables["steps"]) == 2
    assert labels(archive, "steps", "status") == {0: "started", 1: "completed"}
    assert labels(archive, "FlightStatus", "Armed") == {0: "Armed", 1: "Disarmed"}
    assert labels(archive, "mission", "mission") == {0: "m-1"}
    assert tables["steps"][1][-1] == "3.5"
    # The folder is gone once the archive exists; the next flight gets a new folder.
    assert not archive.with_suffix("").exists()
    assert logger.current.directory != archive.with_suffix("")


def test_the_project_log_reader_opens_the_recording(tmp_path: Path) -> None:
    from logs.importers.base import DEFAULT_LIMITS, no_progress
    from logs.importers.dfi import DfiImporter

    logger = FlightLogger(tmp_path, "D1")
    fly(logger)
    archive = logger.close()
    data = DfiImporter().read(archive, limits=DEFAULT_LIMITS, progress=no_progress)
    paths = set(data.series)
    assert any("Waypoint" in p and "Position" in p for p in paths)


def test_a_crash_leaves_readable_csv_files_and_description(tmp_path: Path) -> None:
    logger = FlightLogger(tmp_path, "D1")
    fly(logger)
    folder = logger.current.directory
    logger.current.flush()
    assert (folder / "description.xml").exists()
    text = (folder / "telemetry_AttitudeActual.csv").read_text()
    assert len(text.splitlines()) == 5
    assert "AttitudeActual" in (folder / "description.xml").read_text()


def test_an_empty_flight_leaves_no_archive(tmp_path: Path) -> None:
    logger = FlightLogger(tmp_path, "D1")
    assert logger.close() is None
    assert list(tmp_path.iterdir()) == []
