import numpy as np

from logs import find_special, import_log
from onboard.logger import FlightLogger


def test_a_flight_recorded_by_the_onboard_logger_imports(tmp_path):
    logger = FlightLogger(tmp_path, "DRONE1")
    t0 = 1_795_341_600.0
    for i in range(20):
        logger.telemetry(
            "PositionActual",
            t0 + i * 0.1,
            {
                "Altitude": 10.0 + i,
                "Velocity": {"x": 1.0, "y": 0.5 * i, "z": 0.0},
                "Mode": "Auto" if i else "Manual",
            },
        )
    logger.event(
        "step",
        {
            "mission_id": "m1",
            "index": 0,
            "command": "goto",
            "event": "done",
            "position": {"lat": 50.1, "lon": 14.4, "alt": 20.0},
            "duration_s": 3.5,
        },
    )
    archive = logger.close()

    log = import_log(archive)
    assert log.format == "dfi"
    alt = log.series["PositionActual/Altitude"]
    np.testing.assert_allclose(alt.values, 10.0 + np.arange(20))
    np.testing.assert_array_equal(
        alt.times, np.round((t0 + np.arange(20) * 0.1) * 1e6).astype(np.int64) * 1000
    )
    mode = log.series["PositionActual/Mode"]
    assert [mode.labels[v] for v in mode.values[:2].tolist()] == ["Manual", "Auto"]
    assert log.series["steps/latitude"].values.tolist() == [50.1]
    special = find_special(log)
    assert special["altitude"] == ["PositionActual/Altitude"]
    assert special["velocity"] == [
        "PositionActual/Velocity/x",
        "PositionActual/Velocity/y",
        "PositionActual/Velocity/z",
    ]
