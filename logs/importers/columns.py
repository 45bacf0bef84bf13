"""Collects per-message values into columns, for the readers that decode one record at a time."""

from __future__ import annotations

import numpy as np

from logs.series import LogData, Series, TimeSource, join


class ColumnCollector:
    """Appends (time, {field: value}) rows per layer; a field missing from a row is skipped
    for that row only, so each series keeps its own times."""

    def __init__(self) -> None:
        self.layers: dict[str, dict[str, tuple[list[int], list[object]]]] = {}
        self.units: dict[str, str] = {}
        self.special: dict[str, str] = {}
        self.labels: dict[str, dict[int, str]] = {}

    def add(self, layer: str, t_ns: int, fields: dict[str, object]) -> None:
        columns = self.layers.setdefault(layer, {})
        for name, value in fields.items():
            col = columns.get(name)
            if col is None:
                col = columns[name] = ([], [])
            col[0].append(t_ns)
            col[1].append(value)

    def build(self, log: LogData, source: TimeSource) -> None:
        shared: dict[tuple[int, ...], np.ndarray] = {}
        for layer, columns in self.layers.items():
            for name, (times, values) in columns.items():
                path = join(layer, *name.split("/"))
                # Fields of one message share a clock: keep one array so the store
                # writes it once.
                t = np.asarray(times, dtype=np.int64)
                key = (len(times), times[0], times[-1])
                same = shared.get(key)
                if same is not None and np.array_equal(same, t):
                    t = same
                else:
                    shared[key] = t
                if isinstance(values[0], str):
                    arr, kind = np.asarray(values, dtype=str), "text"
                elif all(isinstance(v, int | np.integer) for v in values):
                    arr, kind = np.asarray(values, dtype=np.int64), "int"
                else:
                    try:
                        arr, kind = np.asarray(values, dtype=np.float64), "double"
                    except (TypeError, ValueError):
                        log.warnings.append(f"Dropped {path}: mixed value types.")
                        continue
                if path in self.labels:
                    kind = "enum"
                log.add(
                    Series(
                        path,
                        arr,
                        t,
                        unit=self.units.get(path, ""),
                        time_source=source,
                        kind=kind,  # type: ignore[arg-type]
                        labels=self.labels.get(path),
                        special=self.special.get(path),
                    )
                )
