"""The ingest's batch path: a read's messages each judged alone, the buffer woken once."""

from __future__ import annotations

import threading
import time

from telemetry.ingest import Chunk, CounterSink, DroneMap, IngestConfig, Ingestor, SampleBuffer


def _chunk(rows: int, name: str = "") -> Chunk:
    return Chunk(received=time.monotonic(), rows=rows, text="", days=frozenset(), drone=name)


def test_put_many_keeps_order_and_stops_at_the_bound():
    buffer = SampleBuffer(max_rows=5)
    chunks = [_chunk(2, "a"), _chunk(2, "b"), _chunk(2, "c"), _chunk(1, "d")]
    assert buffer.put_many(chunks, wait=0.05) == 2, "c does not fit, and d may not overtake it"
    taken = buffer.take(max_rows=10, wait=0, min_rows=0)
    assert [c.drone for c in taken] == ["a", "b"]
    assert buffer.rows == 4, "taken rows count until released"
    buffer.release(4)
    assert buffer.put_many(chunks[2:], wait=0) == 2 and buffer.rows == 3


def test_a_waiting_writer_wakes_once_its_rows_are_there_not_at_every_put():
    buffer = SampleBuffer(max_rows=100)
    took: list[tuple[float, int]] = []

    def writer() -> None:
        began = time.monotonic()
        rows = sum(c.rows for c in buffer.take(max_rows=50, wait=5, min_rows=10, quiet=5))
        took.append((time.monotonic() - began, rows))

    thread = threading.Thread(target=writer)
    thread.start()
    time.sleep(0.1)
    assert buffer.put_many([_chunk(3)] * 3, wait=0) == 3  # 9 rows: not enough yet
    time.sleep(0.2)
    assert not took, "the writer slept through a put that left it short"
    assert buffer.put(_chunk(1), wait=0)
    thread.join(2)
    # Woken by the tenth row (put at 0.3 s), not by the quiet period (5 s): measured 0.30 s,
    # quiet and with four busy processes on two cores.
    assert took and took[0][0] < 1.0 and took[0][1] == 10


def test_a_pause_in_the_input_ends_the_batch_before_the_interval():
    buffer = SampleBuffer(max_rows=100)
    took: list[tuple[float, int]] = []

    def writer() -> None:
        began = time.monotonic()
        rows = sum(c.rows for c in buffer.take(max_rows=50, wait=30, min_rows=10, quiet=0.05))
        took.append((time.monotonic() - began, rows))

    thread = threading.Thread(target=writer)
    thread.start()
    assert buffer.put_many([_chunk(3)] * 3, wait=0) == 3  # 9 rows, then nothing more
    thread.join(10)
    assert took and took[0][1] == 9, "the last rows of a burst waited for rows never coming"
    # Measured 0.10 s, quiet and with four busy processes on two cores; the wait is 30 s.
    assert took[0][0] < 10, "they waited out the flush interval"


def test_a_putter_waiting_for_room_goes_on_when_rows_are_released():
    buffer = SampleBuffer(max_rows=4)
    assert buffer.put(_chunk(4), wait=0)
    buffer.take(max_rows=4, wait=0, min_rows=0)
    threading.Timer(0.1, buffer.release, args=(4,)).start()
    began = time.monotonic()
    assert buffer.put_many([_chunk(2), _chunk(2)], wait=3) == 2
    # Measured 0.10-0.11 s (the release comes at 0.1 s), quiet and under load.
    assert time.monotonic() - began < 2


def test_each_message_of_a_batch_is_kept_or_refused_on_its_own():
    counters = CounterSink()
    ingestor = Ingestor(
        IngestConfig(conninfo="", mqtt_url="mqtt://127.0.0.1:1"),
        drones=DroneMap(lambda: {"ACME_1": 7, "ACME_2": 8}),
        counters=counters,
    )
    ingestor.drones.refresh()
    now = time.time()
    good = b'{"ts":%f,"objects":[{"name":"Gyros","ts":%f,"fields":{"x":1.5}}]}' % (now, now)
    two = b'{"ts":%f,"objects":[{"name":"A","ts":%f,"fields":{}},{"name":"B","ts":%f,"fields":{}}]}'
    settled: list[str] = []

    def settle(name: str):  # type: ignore[no-untyped-def]
        return lambda: settled.append(name)

    kept = ingestor.handle_many(
        [
            ("ACME_1/telemetry/out", good, settle("good")),
            ("ACME_1/telemetry/out", b"{not json", settle("not json")),
            ("NOBODY/telemetry/out", good, settle("unknown")),
            ("ACME_2/telemetry/out", two % (now, now, now), None),
            ("ACME_2/telemetry/out", b'{"ts":%f,"objects":[]}' % now, settle("empty")),
        ]
    )
    assert kept == 3
    assert settled == ["not json", "unknown", "empty"], "kept rows settle once committed"
    counts = counters.counts
    assert counts["received"] == 5 and counts["objects_received"] == 3
    assert counts["dropped.not_json"] == 1 and counts["dropped.unknown_drone"] == 1
    assert counters.refusals == {("ACME_1", "telemetry.not_json"): 1}
    chunks = ingestor.buffer.take(max_rows=10, wait=0, min_rows=0)
    assert [(c.drone, c.rows) for c in chunks] == [("ACME_1", 1), ("ACME_2", 2)]
    assert chunks[0].text.split("\t")[1:4] == ["7", "Gyros", '{"x":1.5}']
