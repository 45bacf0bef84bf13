"""A logbook as PDF: one A4 page per flight with its main figures and its track drawn
from above. Written to the PDF 1.4 file structure of [ISO 32000-1] (§7.5: header, body
of indirect objects, cross-reference table, trailer) with the standard Helvetica font,
which every reader has (§9.6.2.2), so no font is embedded and nothing is fetched."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from django.utils import timezone

from .models import FlightRecord

PAGE_W, PAGE_H = 595, 842  # A4 in points
MARGIN = 50
TRACK_BOX = 300  # the track's square, points
LINE_H = 16


def _text(value: str) -> bytes:
    """A PDF literal string (§7.3.4.2) in WinAnsiEncoding: backslash and parentheses
    escaped, characters the encoding lacks replaced."""
    raw = value.encode("cp1252", errors="replace")
    return b"(" + raw.replace(b"\\", b"\\\\").replace(b"(", b"\\(").replace(b")", b"\\)") + b")"


def _number(value: float) -> bytes:
    return f"{value:.2f}".rstrip("0").rstrip(".").encode()


def _when(moment: object) -> str:
    return timezone.localtime(moment).strftime("%Y-%m-%d %H:%M:%S") if moment else "-"


def _fmt(value: float | None, unit: str, digits: int = 0) -> str:
    return "-" if value is None else f"{value:.{digits}f} {unit}"


def figure_lines(r: FlightRecord) -> list[tuple[str, str]]:
    """The figures printed, as (label, value)."""
    battery = "-"
    if r.battery_start is not None and r.battery_end is not None:
        battery = f"{r.battery_start * 100:.0f} % -> {r.battery_end * 100:.0f} %"
    energy = _fmt(r.energy_wh, "Wh", 2)
    if r.energy_wh is not None:
        energy += f" ({r.get_energy_method_display()})"
    return [
        ("Drone", r.drone_ident),
        ("Started by", f"{r.pilot_name or '-'} ({r.get_origin_display()})"),
        ("Mission", r.mission_name or "-"),
        ("Armed", _when(r.started_at)),
        ("Disarmed", _when(r.ended_at)),
        ("Take-off", _when(r.takeoff_at) + _place(r.takeoff_position)),
        ("Landing", _when(r.landing_at) + _place(r.landing_position)),
        ("Duration", _fmt(r.duration_s, "s") + f" ({_fmt(r.airborne_s, 's')} airborne)"),
        ("Distance flown", _fmt(r.distance_m, "m")),
        ("Max height above home", _fmt(r.max_height_m, "m", 1)),
        ("Max distance from home", _fmt(r.max_distance_m, "m")),
        ("Max ground speed", _fmt(r.max_speed_ms, "m/s", 1)),
        ("Battery", battery + (f", pack {r.battery}" if r.battery else "")),
        ("Energy used", energy),
        ("Events", str(len(r.events))),
        (
            "Correction",
            f"of record {r.corrects_id}: {r.correction_reason}" if r.corrects_id else "-",
        ),
    ]


def _place(position: object) -> str:
    if not isinstance(position, dict) or position.get("lat") is None:
        return ""
    return f" at {position['lat']:.6f}, {position.get('lon', 0):.6f}"


def _track_path(track: Sequence, left: float, bottom: float) -> list[bytes]:
    """Drawing operators for the track in its box, north up (§8.5.2 path construction)."""
    points = [(p[2], p[1]) for p in track if isinstance(p, list) and len(p) >= 4]
    ops = [
        b"0.8 w 0.6 G",
        b"%s %s %d %d re S" % (_number(left), _number(bottom), TRACK_BOX, TRACK_BOX),
    ]
    if len(points) < 2:
        return ops
    east, north = [p[0] for p in points], [p[1] for p in points]
    span = max(max(east) - min(east), max(north) - min(north), 1.0)
    scale = (TRACK_BOX - 20) / span
    xy = [
        (left + 10 + (e - min(east)) * scale, bottom + 10 + (n - min(north)) * scale)
        for e, n in points
    ]
    ops.append(b"1.5 w 0.08 0.44 0.94 RG")
    ops.append(b"%s %s m" % (_number(xy[0][0]), _number(xy[0][1])))
    ops += [b"%s %s l" % (_number(x), _number(y)) for x, y in xy[1:]]
    ops.append(b"S")
    for (x, y), colour in ((xy[0], b"0.07 0.72 0.42 rg"), (xy[-1], b"0.85 0.18 0.13 rg")):
        ops.append(colour + b" %s %s 6 6 re f" % (_number(x - 3), _number(y - 3)))
    ops.append(b"0 g BT /F1 9 Tf %d %s Td %s Tj ET" % (
        left, _number(bottom - 14), _text(f"Track from above, north up, {span:.0f} m across")
    ))  # fmt: skip
    return ops


def page_content(r: FlightRecord) -> bytes:
    """One page's content stream; its times in the portal's time zone, named in the title
    as the pages name it."""
    top = PAGE_H - MARGIN
    zone = timezone.get_current_timezone_name()
    ops = [
        b"BT /F1 16 Tf %d %d Td %s Tj ET"
        % (MARGIN, top, _text(f"Flight {r.pk}: {r.drone_ident}, {_when(r.started_at)} {zone}"))
    ]
    y = top - 2 * LINE_H
    for label, value in figure_lines(r):
        ops.append(b"BT /F1 10 Tf %d %d Td %s Tj ET" % (MARGIN, y, _text(label)))
        ops.append(b"BT /F1 10 Tf %d %d Td %s Tj ET" % (MARGIN + 170, y, _text(value[:70])))
        y -= LINE_H
    ops += _track_path(r.track, MARGIN, y - TRACK_BOX - 10)
    return b"\n".join(ops)


@dataclass
class _Writer:
    """Indirect objects in order; `finish` adds the cross-reference table and trailer."""

    body: bytearray
    offsets: list[int]

    def add(self, content: bytes) -> int:
        number = len(self.offsets) + 1
        self.offsets.append(len(self.body))
        self.body += b"%d 0 obj\n" % number + content + b"\nendobj\n"
        return number

    def finish(self, root: int) -> bytes:
        start = len(self.body)
        xref = [b"xref", b"0 %d" % (len(self.offsets) + 1), b"0000000000 65535 f "]
        xref += [b"%010d 00000 n " % offset for offset in self.offsets]
        trailer = b"trailer\n<< /Size %d /Root %d 0 R >>\nstartxref\n%d\n%%%%EOF\n" % (
            len(self.offsets) + 1, root, start,
        )  # fmt: skip
        return bytes(self.body) + b"\n".join(xref) + b"\n" + trailer


def logbook_pdf(records: Iterable[FlightRecord]) -> bytes:
    """The PDF file: catalog (1), page tree (2), font (3), then a page and its content
    stream per flight; a logbook with no flight has one empty page, as a page tree needs."""
    writer = _Writer(bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n"), [])
    writer.add(b"<< /Type /Catalog /Pages 2 0 R >>")
    writer.add(b"")  # the page tree, written once its kids are known
    writer.add(b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>")
    pages = []
    for record in records:
        stream = page_content(record)
        content = writer.add(b"<< /Length %d >>\nstream\n" % len(stream) + stream + b"\nendstream")
        pages.append(writer.add(
            b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 %d %d] /Contents %d 0 R "
            b"/Resources << /Font << /F1 3 0 R >> >> >>" % (PAGE_W, PAGE_H, content)
        ))  # fmt: skip
    if not pages:
        pages.append(
            writer.add(b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 %d %d] >>" % (PAGE_W, PAGE_H))
        )
    return _with_page_tree(writer, pages)


def _with_page_tree(writer: _Writer, pages: list[int]) -> bytes:
    """Rewrite object 2 (the page tree) now the pages are known: objects after it move,
    so the body is rebuilt with fresh offsets."""
    kids = b" ".join(b"%d 0 R" % p for p in pages)
    tree = b"<< /Type /Pages /Kids [%s] /Count %d >>" % (kids, len(pages))
    old_start = writer.offsets[1]
    old_end = writer.offsets[2]
    new_object = b"2 0 obj\n" + tree + b"\nendobj\n"
    shift = len(new_object) - (old_end - old_start)
    body = writer.body[:old_start] + new_object + writer.body[old_end:]
    offsets = writer.offsets[:2] + [o + shift for o in writer.offsets[2:]]
    return _Writer(bytearray(body), offsets).finish(root=1)
