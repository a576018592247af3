"""The traces of an HP Standard Data Format (SDF) file, as the 35660A-89410A family saves them.

This module reads the records of an SDF file into :class:`SdfTrace` objects (X axis, Y values,
channels) without judging what they are; :mod:`viscorig.exchange.sdffrf` picks the frequency
responses out of them. It follows the "Standard Data Format Utilities User's Guide" (HP
5963-1715, appendix B). All numbers are big-endian. Byte offsets below are from the start of
each record, counted from 0 (the guide counts from 1); record offsets in the file header count
from the start of the file, which begins with the two bytes ``B\\0``.

Every record starts with ``recordType`` (short) and ``recordSize`` (long). The guide fixes the
size of each header record per SDF revision (table B-1); a header of another size is refused,
and the size, not the file's revision number, says which layout a header has (89410A files
exist with revision 2 in the file header and revision 3 records):

============  ====  =====  =====  ======  =======
revision      FILE  MEAS   DATA   VECTOR  CHANNEL
============  ====  =====  =====  ======  =======
2             64    140    134    18      192
3             80    156    148    18      212
============  ====  =====  =====  ======  =======

Revision 1 (102-byte measurement headers) has another layout and is refused.

- FILE_HDR (type 10): revision @6, application @8, numbers of DATA_HDR, VECTOR, CHANNEL,
  UNIQUE, SCAN_STRUCT and XDATA records @24..35 (shorts), offsets of DATA_HDR, VECTOR, CHANNEL,
  UNIQUE, SCAN_STRUCT, XDATA and YDATA records @36..63 (longs).
- MEAS_HDR (type 11), right after the file header: startFreqIndex @24 and stopFreqIndex @26
  (shorts: the alias-protected points of an FFT measurement), measType @126.
- DATA_HDR (type 12): dataTitle @10 (char[16]), domain @26, dataType @28, num_of_points @30
  (short; in a 148-byte header a long @134), last_valid_index @32 (short; long @138),
  xResolution_type @42 (0 linear, 1 logarithmic, 2 arbitrary one per file, 3 arbitrary one
  per data type), xdata_type @44 and ydata_type @48 (1 short, 2 long, 3 float, 4 double),
  xPerPoint @46, yPerPoint @50, yIsComplex @52, first_VECTOR_recordNum @60 (long),
  total_rows @64, total_cols @66, xUnit @68 (SDF_UNIT: label char[10], factor, eight exponent
  bytes; 22 bytes), yUnitValid @90, yUnit @92, abscissa_firstX @114 and abscissa_deltaX @122
  (doubles; ``x[n] = x[n-1] + deltaX`` linear, ``x[n-1] * deltaX`` logarithmic).
- VECTOR_HDR (type 13): the_CHANNEL_record[2] @10 (-1 none), pow_of_CHANNEL[2] @14 (×48).
- CHANNEL_HDR (type 14): channelLabel @10 (char[30]), window @64 (SDF_WINDOW: windowType,
  windowCorrMode, then five floats of which narrowBandCorr @84), intLabel @106 (char[10]),
  engUnit @116 (SDF_UNIT), int2engrUnit @138 (float: divide internal-unit data by it to get
  EU).
- SCAN_STRUCT (type 15): num_of_scan @6 (short).
- XDATA (type 16), YDATA (type 17): the values follow the 6-byte record head. With one scan,
  Y data holds, for each data header in turn, rows × cols traces of num_of_points × yPerPoint
  values (real, imaginary pairs when complex).

Why a reader of our own: the ``sdfascii`` package (MIT) reads the headers well, but its data
path is written for 35670A spectra: for a 35670A file it returns ``sqrt(y / 2)`` (a power
spectrum's Vpk² to Vrms) whatever the data type, so a frequency response comes out mangled; it
reads the first data header only and stops the program (``sys.exit``) on what it does not know.
It serves the tests as an independent check where it reads as this module does (the 35665A
response in ``tests/data/sdf``).

The analyser input of a channel header is read from the label the analyser gives it ("Chan  2"
is input 2); a channel the user relabelled is taken by its place (the first is input 1). A
35670A writes two channel headers even for a one-channel trace (both "Chan  1"), so the place
alone would not do.
The names of application, measurement and data type codes are those of the guide's tables and
of the enumerations in HP's SDF library header (``SDF_basi.h``, 1994).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError

FILE_ID = b"B\x00"
FILE_HDR, MEAS_HDR, DATA_HDR, VECTOR_HDR, CHANNEL_HDR, SCAN_STRUCT = 10, 11, 12, 13, 14, 15
XDATA, YDATA = 16, 17
#: Header record sizes of each revision read (guide, table B-1).
RECORD_SIZES = {
    2: {FILE_HDR: 64, MEAS_HDR: 140, DATA_HDR: 134, VECTOR_HDR: 18, CHANNEL_HDR: 192},
    3: {FILE_HDR: 80, MEAS_HDR: 156, DATA_HDR: 148, VECTOR_HDR: 18, CHANNEL_HDR: 212},
}
FREQUENCY_DOMAIN = 0
FREQUENCY_RESPONSE = 4
SWEPT_MEASUREMENT, FFT_MEASUREMENT, FFT_NETWORK_MEASUREMENT = 2, 3, 10
#: SDF number type code -> big-endian numpy letter and size
NUMBER_TYPES = {1: ("i2", 2), 2: ("i4", 4), 3: ("f4", 4), 4: ("f8", 8)}
#: An analyser's own channel label ("Chan  2"), which names the input.
CHANNEL_LABEL = re.compile(r"^\s*(?:chan(?:nel)?|ch)\s*(\d{1,2})\s*$", re.IGNORECASE)
#: The largest SDF file read.
MAX_SDF_BYTES = 16 * 1024 * 1024
#: applic codes of the file header (HP's SDF library, enumeration Applic)
APPLICATIONS = {
    -1: "HP 35630", -2: "HP 35631", -3: "HP 35660A", -4: "HP 3562A/3563A", -5: "HP 3588A",
    -6: "HP 3589A", 1: "HP 3566A/3567A", 2: "HP 35665A", 3: "HP 3560A",
    4: "HP 89410A/89440A", 7: "HP 35635R", 8: "HP 35654A", 9: "HP 3569A", 10: "HP 35670A",
    11: "HP 3587", 12: "HP E3200",
}
#: measType codes of the measurement header (HP's SDF library, enumeration Measure_type)
MEASUREMENTS = {
    0: "spectrum measurement", 1: "network measurement", SWEPT_MEASUREMENT: "swept sine",
    FFT_MEASUREMENT: "FFT measurement", 4: "order measurement", 5: "octave measurement",
    6: "time capture", 7: "correlation measurement", 8: "histogram measurement",
    9: "swept network measurement", FFT_NETWORK_MEASUREMENT: "FFT network measurement",
    11: "swept FFT measurement", 12: "analog demodulation", 13: "digital demodulation",
}
#: dataType codes (guide, table B-4a; 37-76 from the library's enumeration Data_type)
DATA_TYPES = {
    0: "time record", 1: "linear spectrum", 2: "auto-power spectrum",
    3: "cross-power spectrum", 4: "frequency response", 5: "auto-correlation",
    6: "cross-correlation", 7: "impulse response", 8: "ordinary coherence",
    9: "partial coherence", 10: "multiple coherence", 11: "full octave", 12: "third octave",
    13: "convolution", 14: "histogram", 15: "probability density function",
    16: "cumulative density function", 17: "power spectrum order tracking",
    18: "composite power tracking", 19: "phase order tracking", 20: "rpm spectral",
    21: "order ratio", 22: "orbit", 23: "HP 35650 series calibration",
    24: "sine rms power", 25: "sine variance", 26: "sine range", 27: "sine settle time",
    28: "sine integration time", 29: "sine source", 30: "sine overload", 31: "sine linear",
    32: "synthesis", 33: "curve fit weighting function", 34: "frequency corrections",
    35: "all pass time data", 36: "norm reference data", 37: "tachometer data",
    38: "limit line", 39: "twelfth octave", 40: "S11 data", 41: "S21 data", 42: "S12 data",
    43: "S22 data", 44: "power spectral density", 45: "decimated time record",
    46: "overload data", 47: "compressed time record", 48: "external trigger data",
    49: "pressure", 50: "intensity", 51: "pressure-intensity index", 52: "particle velocity",
    53: "pressure-velocity index", 54: "sound power", 55: "field indicator",
    56: "partial power", 57: "L_N 1 %", 58: "L_N 10 %", 59: "L_N 50 %", 60: "L_N 90 %",
    61: "L_N 99 %", 62: "L_N user", 63: "T20", 64: "T30", 65: "RT60", 66: "average count",
    67: "sigma", 68: "measured I/Q time record", 69: "measured I/Q spectrum",
    70: "reference I/Q time record", 71: "reference I/Q spectrum", 72: "I/Q error magnitude",
    73: "I/Q error phase", 74: "error vector time record", 75: "error vector spectrum",
    76: "symbol table", -99: "unknown data",
}
#: domain codes (guide, table B-4a)
DOMAINS = {0: "frequency", 1: "time", 2: "amplitude", 3: "RPM", 4: "order", 5: "channel",
           6: "octave", -99: "unknown"}


@dataclass(frozen=True)
class SdfChannel:
    """One analyser input as its channel header describes it."""

    number: int
    """Analyser input, from 1: N of an analyser's own label "Chan  N", else the channel
    header's place in the file."""
    label: str
    unit: str
    """Engineering unit label (``"V"`` when none was set on the analyser)."""
    int2engr: float
    """EU correction factor: internal-unit value / int2engr = value in ``unit``."""
    narrow_band_correction: float = 1.0
    """The window's amplitude correction (SDF_WINDOW narrowBandCorr), which the analyser's
    display applies to a spectrum; it cancels in a frequency response."""


@dataclass(frozen=True)
class SdfTrace:
    """One trace: a data header's row and column, in the file's internal units."""

    title: str
    domain: int
    data_type: int
    x: NDArray[np.float64]
    x_unit: str
    values: NDArray[np.complex128] | NDArray[np.float64]
    response: SdfChannel | None
    reference: SdfChannel | None
    powers: tuple[int, int]
    """pow_of_CHANNEL / 48 of the response and reference channels."""
    y_unit: str
    """The data header's yUnit label when valid, else ``""``."""
    valid: NDArray[np.bool_]
    """Points the instrument marks as measured (last_valid_index, alias-protected range)."""

    @property
    def kind(self) -> str:
        """What the trace is, in words (``"auto-power spectrum"``)."""
        return DATA_TYPES.get(self.data_type, f"data type {self.data_type}")


@dataclass(frozen=True)
class SdfFile:
    """The traces of an SDF file and what its headers say about the measurement."""

    path: str
    revision: int
    application: int
    measurement: int
    scans: int
    traces: list[SdfTrace]

    @property
    def instrument(self) -> str:
        """The saving instrument's name, or its application code."""
        return APPLICATIONS.get(self.application,
                                f"unknown instrument (application code {self.application})")

    @property
    def measurement_name(self) -> str:
        """The measurement type in words."""
        return MEASUREMENTS.get(self.measurement,
                                f"unknown measurement (type {self.measurement})")


class _Bytes:
    """Bounds-checked big-endian reads that name the record on failure."""

    def __init__(self, data: bytes, where: str) -> None:
        self.data = data
        self.where = where

    def unpack(self, layout: str, offset: int, what: str) -> tuple:
        size = struct.calcsize(">" + layout)
        if offset < 0 or offset + size > len(self.data):
            raise InputError(f"file ends inside the {what} (byte {offset})", self.where)
        return struct.unpack_from(">" + layout, self.data, offset)

    def record(self, offset: int, kind: int, what: str) -> int:
        """Check a record head at ``offset`` (and a header's fixed size); return its size."""
        record_type, found = self.unpack("hl", offset, what)
        if record_type != kind:
            raise InputError(f"expected the {what} (record type {kind}) at byte {offset}, "
                             f"found type {record_type}", self.where)
        sizes = sorted({table[kind] for table in RECORD_SIZES.values() if kind in table})
        if sizes and found not in sizes:
            raise InputError(f"{what} at byte {offset} has size {found}; SDF revisions 2 and 3 "
                             f"give {' or '.join(map(str, sizes))}", self.where)
        if found < 6 or offset + found > len(self.data):
            raise InputError(f"{what} at byte {offset} has size {found} (file has "
                             f"{len(self.data)} bytes)", self.where)
        return found

    def text(self, offset: int, length: int, what: str) -> str:
        (raw,) = self.unpack(f"{length}s", offset, what)
        return raw.split(b"\x00", 1)[0].decode("latin-1").strip()

    def numbers(self, offset: int, code: int, count: int, end: int, what: str) -> NDArray:
        """``count`` values of SDF number type ``code`` from ``offset``, within ``end``."""
        if code not in NUMBER_TYPES:
            raise InputError(f"{what}: number type {code} is unknown (1-4)", self.where)
        letter, size = NUMBER_TYPES[code]
        if count < 0 or offset + count * size > end:
            raise InputError(f"{what}: {count} values from byte {offset} run past the end of "
                             f"their record (byte {end})", self.where)
        return np.frombuffer(self.data, dtype=f">{letter}", count=count, offset=offset)


def read_sdf_file(path: str | Path) -> SdfFile:
    """Every trace of an SDF revision 2 or 3 file.

    Raises
    ------
    InputError
        Not an SDF file, another revision, a waterfall of several scans, a truncated or
        inconsistent record.
    """
    data, where = _read_file(Path(path))
    b = _Bytes(data, where)
    head = 2
    (revision, application) = b.unpack("hh", head + 6, "file header")
    if revision not in RECORD_SIZES:
        raise InputError(f"SDF revision {revision}; this reader knows revisions 2 and 3", where)
    file_size = b.record(head, FILE_HDR, "file header")
    n_data, n_vector, n_channel, _, n_scan, n_xdata = b.unpack("6h", head + 24, "file header")
    data_at, vector_at, channel_at, _, scan_at, xdata_at, ydata_at = b.unpack(
        "7l", head + 36, "file header")
    meas_at = head + file_size
    b.record(meas_at, MEAS_HDR, "measurement header")
    start_index, stop_index = b.unpack("hh", meas_at + 24, "measurement header")
    (measurement,) = b.unpack("h", meas_at + 126, "measurement header")
    scans = 1
    if n_scan > 0 and scan_at >= 0:
        b.record(scan_at, SCAN_STRUCT, "scan structure")
        (scans,) = b.unpack("h", scan_at + 6, "scan structure")
        if scans > 1:
            raise InputError(f"holds a waterfall of {scans} scans; this reader takes one "
                             "trace per data header (save a single trace)", where)
    channels = _channels(b, channel_at, n_channel)
    vectors = _vectors(b, vector_at, n_vector)
    if ydata_at < 0:
        raise InputError("has no Y data record" if ydata_at == -1 else
                         f"Y data record offset {ydata_at} is not in the file", where)
    y_end = ydata_at + b.record(ydata_at, YDATA, "Y data record")
    y_cursor = ydata_at + 6
    x_axes = _XAxes(b, xdata_at, n_xdata)
    traces: list[SdfTrace] = []
    cursor = data_at
    for index in range(n_data):
        what = f"data header {index + 1}"
        size = b.record(cursor, DATA_HDR, what)
        h = _DataHeader.read(b, cursor, what, long_counts=size >= RECORD_SIZES[3][DATA_HDR])
        cursor += size
        per_trace = h.points * max(h.y_per_point, 1) * (2 if h.complex else 1)
        needed = per_trace * NUMBER_TYPES[h.y_type][1] * h.rows * h.cols
        if needed > y_end - y_cursor:
            raise InputError(f"{what}: {h.rows * h.cols} trace(s) of {h.points} points need "
                             f"{needed} bytes; the Y data record has {y_end - y_cursor} left",
                             where)
        axis = x_axes.axis(h, what)
        valid = np.arange(h.points) <= h.last_valid
        if (measurement in (FFT_MEASUREMENT, FFT_NETWORK_MEASUREMENT)
                and 0 <= start_index <= stop_index):
            valid &= (np.arange(h.points) >= start_index) & (np.arange(h.points) <= stop_index)
        for vector in range(h.rows * h.cols):
            number = h.first_vector + vector
            if not 0 <= number < len(vectors):
                raise InputError(f"{what} points to vector header {number + 1}, the file has "
                                 f"{len(vectors)}", where)
            raw = b.numbers(y_cursor, h.y_type, per_trace, y_end, f"{what}: Y data")
            y_cursor += raw.nbytes
            traces.append(_trace(h, raw, axis, valid, vectors[number], channels, what, where))
    if y_cursor != y_end:
        raise InputError(f"Y data record holds {y_end - ydata_at - 6} bytes, the data headers "
                         f"describe {y_cursor - ydata_at - 6}", where)
    return SdfFile(where, revision, application, measurement, scans, traces)


def _read_file(path: Path) -> tuple[bytes, str]:
    """The file's bytes (at most :data:`MAX_SDF_BYTES`) and its name for messages."""
    where = str(path)
    try:
        size = path.stat().st_size
        if size > MAX_SDF_BYTES:
            raise InputError(f"{size} bytes; an SDF file is read up to {MAX_SDF_BYTES} (the "
                             "analysers save to 1.44 MB disks)", where)
        data = path.read_bytes()
    except OSError as error:
        raise InputError(f"cannot read the file ({error.strerror})", where) from None
    if data[:2] != FILE_ID:
        raise InputError("not an SDF file (it does not start with 'B\\0')", where)
    return data, where


class _XAxes:
    """The X axis of each data header: computed (linear, logarithmic) or read in turn from the
    X data record (arbitrary; resolution type 2 shares the first one read by the file)."""

    def __init__(self, b: _Bytes, xdata_at: int, n_xdata: int) -> None:
        self.b = b
        self.cursor: int | None = None
        self.end: int | None = None
        self.file_axis: NDArray[np.float64] | None = None
        if xdata_at >= 0 and n_xdata > 0:
            self.end = xdata_at + b.record(xdata_at, XDATA, "X data record")
            self.cursor = xdata_at + 6

    def axis(self, h: _DataHeader, what: str) -> NDArray[np.float64]:
        """The X values of the points of data header ``h``."""
        where = self.b.where
        if h.x_resolution in (0, 1):
            n = np.arange(h.points, dtype=float)
            with np.errstate(over="ignore", invalid="ignore"):
                axis = (h.first_x + h.delta_x * n if h.x_resolution == 0
                        else h.first_x * h.delta_x ** n)
        elif h.x_resolution in (2, 3):
            if self.cursor is None or self.end is None:
                raise InputError(f"{what}: arbitrary X resolution but no X data record", where)
            if h.x_resolution == 2 and self.file_axis is not None:
                axis = self.file_axis
            else:
                per = max(h.x_per_point, 1)
                raw = self.b.numbers(self.cursor, h.x_type, h.points * per, self.end,
                                     f"{what}: X data")
                axis = _quiet(raw[::per])
                self.cursor += raw.nbytes
                self.file_axis = axis if h.x_resolution == 2 else self.file_axis
        else:
            raise InputError(f"{what}: X resolution type {h.x_resolution} is not read "
                             "(0 linear, 1 logarithmic, 2 or 3 arbitrary)", where)
        if axis.size != h.points:
            raise InputError(f"{what}: the X axis has {axis.size} points, the data header "
                             f"{h.points}", where)
        return axis


def _quiet(raw: NDArray) -> NDArray[np.float64]:
    """``raw`` as floats, a damaged word that reads as a signalling NaN made a quiet NaN (any
    arithmetic on a signalling one warns)."""
    with np.errstate(invalid="ignore"):
        values = raw.astype(float)
    values[np.isnan(values)] = np.nan
    return values


def _trace(h: _DataHeader, raw: NDArray, axis: NDArray[np.float64], valid: NDArray[np.bool_],
           vector: tuple[int, int, int, int], channels: list[SdfChannel], what: str,
           where: str) -> SdfTrace:
    """One trace of data header ``h`` from its raw Y numbers and its vector header."""
    values = _quiet(raw)
    if h.complex:
        values = values[0::2] + 1j * values[1::2]
    values = values[:: max(h.y_per_point, 1)]
    response, reference, *powers = vector
    return SdfTrace(
        title=h.title, domain=h.domain, data_type=h.data_type, x=axis,
        x_unit=h.x_unit, values=values,
        response=_channel(channels, response, what, where),
        reference=_channel(channels, reference, what, where),
        powers=(powers[0], powers[1]), y_unit=h.y_unit if h.y_unit_valid else "",
        valid=valid,
    )


@dataclass(frozen=True)
class _DataHeader:
    title: str
    domain: int
    data_type: int
    points: int
    last_valid: int
    x_resolution: int
    x_type: int
    x_per_point: int
    y_type: int
    y_per_point: int
    complex: bool
    first_vector: int
    rows: int
    cols: int
    x_unit: str
    y_unit_valid: bool
    y_unit: str
    first_x: float
    delta_x: float

    @classmethod
    def read(cls, b: _Bytes, at: int, what: str, long_counts: bool) -> _DataHeader:
        domain, data_type, points, last_valid = b.unpack("hhhh", at + 26, what)
        if long_counts:
            points, last_valid = b.unpack("ll", at + 134, what)
        x_resolution, x_type, x_per_point, y_type, y_per_point, is_complex = b.unpack(
            "6h", at + 42, what)
        (first_vector,) = b.unpack("l", at + 60, what)
        rows, cols = b.unpack("hh", at + 64, what)
        (y_unit_valid,) = b.unpack("h", at + 90, what)
        first_x, delta_x = b.unpack("dd", at + 114, what)
        if points < 1:
            raise InputError(f"{what}: {points} points", b.where)
        if rows < 1 or cols < 1:
            raise InputError(f"{what}: {rows} rows × {cols} columns of traces", b.where)
        if y_type not in NUMBER_TYPES:
            raise InputError(f"{what}: Y data type {y_type} is unknown (1-4)", b.where)
        if not (np.isfinite(first_x) and np.isfinite(delta_x)):
            raise InputError(f"{what}: X axis start {first_x} or step {delta_x} is not finite",
                             b.where)
        return cls(
            title=b.text(at + 10, 16, what), domain=domain, data_type=data_type, points=points,
            last_valid=last_valid, x_resolution=x_resolution, x_type=x_type,
            x_per_point=x_per_point, y_type=y_type, y_per_point=y_per_point,
            complex=bool(is_complex), first_vector=first_vector, rows=rows, cols=cols,
            x_unit=b.text(at + 68, 10, what), y_unit_valid=bool(y_unit_valid),
            y_unit=b.text(at + 92, 10, what), first_x=first_x, delta_x=delta_x,
        )


def _channels(b: _Bytes, at: int, count: int) -> list[SdfChannel]:
    channels = []
    for index in range(count):
        what = f"channel header {index + 1}"
        size = b.record(at, CHANNEL_HDR, what)
        (factor,) = b.unpack("f", at + 138, what)
        (narrow_band,) = b.unpack("f", at + 84, what)
        if not np.isfinite(factor) or abs(factor) < np.finfo(np.float32).tiny:
            # 0, or a subnormal: what damaged exponent bits read as, no analyser's sensitivity
            raise InputError(f"{what}: EU correction factor {factor:g} is not usable", b.where)
        label = b.text(at + 10, 30, what)
        named = CHANNEL_LABEL.match(label)
        channels.append(SdfChannel(int(named.group(1)) if named else index + 1, label,
                                   b.text(at + 116, 10, what) or b.text(at + 106, 10, what),
                                   float(factor), float(narrow_band)))
        at += size
    return channels


def _vectors(b: _Bytes, at: int, count: int) -> list[tuple[int, int, int, int]]:
    """(response record, reference record, response power, reference power) per vector."""
    vectors = []
    for index in range(count):
        what = f"vector header {index + 1}"
        size = b.record(at, VECTOR_HDR, what)
        vectors.append(b.unpack("4h", at + 10, what))
        at += size
    return vectors


def _channel(channels: list[SdfChannel], record: int, what: str, where: str) -> SdfChannel | None:
    if record < 0:
        return None
    if record >= len(channels):
        raise InputError(f"{what} names channel record {record + 1}, the file has "
                         f"{len(channels)} channel headers", where)
    return channels[record]
