"""Write SDF revision 2 or 3 files as the 35665A/35670A family saves traces to disk.

Written from the record layout of HP's "Standard Data Format Utilities User's Guide"
(big-endian: 'B\\0', file header, measurement header, scan structure, data header, vector
headers, channel headers, X data, Y data; record sizes of table B-1), for tests of the reader
in ``viscorig.exchange.sdf``, with which it shares no code. One data header holds every trace
(its rows); swept sine by default, FFT with ``measurement=3``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

#: FILE, MEAS, DATA, VECTOR and CHANNEL header sizes of each revision (the guide's table B-1)
SIZES = {2: (64, 140, 134, 18, 192), 3: (80, 156, 148, 18, 212)}


@dataclass
class Channel:
    """One analyser input: engineering unit label and sensitivity (V/EU)."""

    label: str
    unit: str
    volts_per_unit: float


@dataclass
class Trace:
    """One frequency response: response and reference channel numbers (0-based), in EU."""

    response: int
    reference: int
    values_eu: np.ndarray
    title: str = "Freq Resp"


@dataclass
class SdfLayout:
    """What to write; the defaults are those of a 35670A swept sine."""

    frequency_hz: np.ndarray
    channels: list[Channel]
    traces: list[Trace]
    x_resolution: int = 2          # arbitrary, one per file: an X data record
    y_type: int = 4                # double
    x_type: int = 4
    revision: int = 2
    application: int = 10          # 35670A
    measurement: int = 2           # swept (3: FFT)
    data_type: int = 4             # frequency response
    domain: int = 0                # frequency
    x_unit: str = "Hz"
    powers: tuple[int, int] = (48, -48)
    extra_headers: list[int] = field(default_factory=list)
    last_valid: int | None = None  # last_valid_index; None: the last point
    alias_protected: tuple[int, int] | None = None  # FFT start/stop indices; None: all points
    scans: int = 0                 # 0: no scan structure record
    first_x: float | None = None   # abscissa_firstX, deltaX; None: from frequency_hz
    delta_x: float | None = None
    sizes: tuple[int, int, int, int, int] | None = None  # None: the revision's


def _unit(label: str) -> bytes:
    return struct.pack(">10sf8b", label.encode("latin-1"), 1.0, 0, 0, 0, 0, 0, 0, 0, 0)


def _record(kind: int, size: int, body: bytes) -> bytes:
    raw = struct.pack(">hl", kind, size) + body
    assert len(raw) <= size, (kind, len(raw), size)
    return raw + bytes(size - len(raw))


def sdf_bytes(layout: SdfLayout) -> bytes:
    """The file's bytes."""
    f = np.asarray(layout.frequency_hz, dtype=float)
    n = f.size
    n_traces = len(layout.traces)
    y_letter = {3: "f", 4: "d"}[layout.y_type]
    x_letter = {3: "f", 4: "d"}[layout.x_type]
    file_size, meas_size, data_size, vector_size, channel_size = (
        layout.sizes or SIZES.get(layout.revision, SIZES[2]))
    scan_size = 40
    scan_at = 2 + file_size + meas_size
    data_at = scan_at + (scan_size if layout.scans else 0)
    vector_at = data_at + data_size
    channel_at = vector_at + vector_size * n_traces
    xdata_at = channel_at + channel_size * len(layout.channels)
    with_x = layout.x_resolution in (2, 3)
    x_payload = struct.pack(f">{n}{x_letter}", *f) if with_x else b""
    ydata_at = xdata_at + (6 + len(x_payload) if with_x else 0)
    complex_y = layout.data_type in (3, 4)
    y_values = []
    for trace in layout.traces:
        s_resp = np.float32(layout.channels[trace.response].volts_per_unit)
        s_ref = np.float32(layout.channels[trace.reference].volts_per_unit)
        volts = np.asarray(trace.values_eu) * (float(s_resp) / float(s_ref))  # internal V/V
        if complex_y:
            pairs = np.empty(2 * n)
            pairs[0::2], pairs[1::2] = volts.real, volts.imag
        else:
            pairs = np.asarray(volts.real, dtype=float)
        y_values.append(pairs)
    y_all = np.concatenate(y_values)
    y_payload = struct.pack(f">{y_all.size}{y_letter}", *y_all)

    file_hdr = struct.pack(
        ">hhhhh8s6h7l", layout.revision, layout.application, 1998, 1231, 2359,
        b"A.02.00", 1, n_traces, len(layout.channels), 0, 1 if layout.scans else 0,
        1 if with_x else 0, data_at, vector_at, channel_at, -1,
        scan_at if layout.scans else -1, xdata_at if with_x else -1, ydata_at)
    meas = bytearray(meas_size - 6)
    struct.pack_into(">l", meas, 0, -1)
    start, stop = layout.alias_protected or (0, n - 1)
    struct.pack_into(">hh", meas, 18, start, stop)  # startFreqIndex, stopFreqIndex
    struct.pack_into(">60s", meas, 32, b"swept sine")
    struct.pack_into(">3d", meas, 96, 70.0, 100.0, 0.0)
    struct.pack_into(">h", meas, 120, layout.measurement)
    first_x = float(f[0]) if layout.first_x is None else layout.first_x
    delta_x = float(f[1] - f[0]) if n > 1 else 0.0
    delta_x = delta_x if layout.delta_x is None else layout.delta_x
    last_valid = n - 1 if layout.last_valid is None else layout.last_valid
    data = bytearray(data_size - 6)
    struct.pack_into(">l16shhhh", data, 0, -1, layout.traces[0].title.encode(), layout.domain,
                     layout.data_type, min(n, 32767), min(last_valid, 32767))
    struct.pack_into(">6h", data, 36, layout.x_resolution, layout.x_type, 1, layout.y_type, 1,
                     1 if complex_y else 0)
    struct.pack_into(">hhhl", data, 48, 0, 0, 1, 0)  # not normalized/power, valid; vector 0
    struct.pack_into(">hh", data, 58, n_traces, 1)
    data[62:84] = _unit(layout.x_unit)
    struct.pack_into(">h", data, 84, 0)
    data[86:108] = _unit("")
    struct.pack_into(">ddhh", data, 108, first_x, delta_x, 1 if layout.scans else 0, 0)
    if data_size >= 148:  # revision 3: num_of_points and last_valid_index as longs
        struct.pack_into(">ll", data, 128, n, last_valid)
    parts = [b"B\x00", _record(10, file_size, file_hdr), _record(11, meas_size, bytes(meas))]
    if layout.scans:
        parts.append(_record(15, scan_size, struct.pack(">hhhh10sf8b", layout.scans,
                                                        layout.scans - 1, 0, 3, b"count", 1.0,
                                                        0, 0, 0, 0, 0, 0, 0, 0)))
    parts.append(_record(12, data_size, bytes(data)))
    for trace in layout.traces:
        parts.append(_record(13, vector_size, struct.pack(
            ">l4h", -1, trace.response, trace.reference, *layout.powers)))
    for channel in layout.channels:
        body = bytearray(channel_size - 6)
        struct.pack_into(">l30s12s12s", body, 0, -1, channel.label.encode(), b"", b"")
        struct.pack_into(">2h5f", body, 58, 0, 0, 0.0, 0.0, 0.0, 1.0, 1.0)  # no window
        struct.pack_into(">hffhhhh10s", body, 82, 0, 0.0, 1.0, 1, 0, 0, 0, b"V")
        body[110:132] = _unit(channel.unit)
        struct.pack_into(">ffhhh", body, 132, channel.volts_per_unit, 1e6, 0, 1, 0)
        parts.append(_record(14, channel_size, bytes(body)))
    if with_x:
        parts.append(struct.pack(">hl", 16, 6 + len(x_payload)) + x_payload)
    parts.append(struct.pack(">hl", 17, 6 + len(y_payload)) + y_payload)
    raw = b"".join(parts)
    assert raw[data_at:data_at + 2] == b"\x00\x0c" and raw[ydata_at:ydata_at + 2] == b"\x00\x11"
    return raw


FOUR_CHANNELS = [
    Channel("F_e", "N", 0.01124),
    Channel("xdd_s", "m/s2", 0.0102),
    Channel("F_v", "N", 0.01124),
    Channel("xdd_v", "m/s2", 0.0102),
]
