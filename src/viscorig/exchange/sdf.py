"""Frequency responses from HP Standard Data Format (SDF) files, as a 35670A saves them.

Why a reader of our own: the ``sdfascii`` package (MIT) reads SDF revision 2 headers well, but
its data path is written for FFT spectra and cannot return a swept-sine frequency response:

- for any 35670A file it takes ``sqrt(y) / sqrt(2)`` of the data (a Vpk² to Vrms conversion
  for power spectra), which is meaningless for a complex frequency response;
- it reads complex data as ``>c8`` with twice the point count, and always as float32 whatever
  the data header's ``ydata_type`` says;
- it ignores the X data record, which a swept sine with an arbitrary frequency list uses, and
  trims the data to the FFT start/stop indices of the measurement header;
- it reads only the first data header and reports errors with ``sys.exit``.

This module follows the layout of the "Standard Data Format Utilities User's Guide" (HP
5963-1715), revision 2. All numbers are big-endian. Byte offsets below are from the start of
each record (the guide numbers bytes from 1; these are from 0). The file starts with the two
bytes ``B\\0``; every record starts with ``recordType`` (short) and ``recordSize`` (long); the
record offsets in the file header count from the start of the file.

- FILE_HDR (type 10): revision @6 (2), application @8 (10 = 35670A), numbers of DATA_HDR,
  VECTOR, CHANNEL, UNIQUE, SCAN_STRUCT and XDATA records @24..35 (shorts), offsets of
  DATA_HDR, VECTOR, CHANNEL, UNIQUE, SCAN_STRUCT, XDATA and YDATA records @36..63 (longs).
- MEAS_HDR (type 11), right after the file header: measType @126 (2 = swept).
- DATA_HDR (type 12): domain @26 (0 = frequency), dataType @28 (4 = frequency response),
  num_of_points @30 (short), xResolution_type @42 (0 linear, 1 logarithmic, 2 arbitrary one
  per file, 3 arbitrary one per data type), xdata_type @44 and ydata_type @48 (3 float,
  4 double), xPerPoint @46, yPerPoint @50, yIsComplex @52, first_VECTOR_recordNum @60 (long),
  total_rows @64 and total_cols @66, xUnit @68 and yUnit @92 (SDF_UNIT: label char[10] then
  factor and exponents, 22 bytes), yUnitValid @90, abscissa_firstX @114 and abscissa_deltaX
  @122 (doubles; ``x[n] = x[n-1] + deltaX`` linear, ``x[n-1] * deltaX`` logarithmic).
- VECTOR_HDR (type 13): the_CHANNEL_record[2] @10 (response, reference; -1 none) and
  pow_of_CHANNEL[2] @14 (×48: +48 response, -48 reference for a frequency response).
- CHANNEL_HDR (type 14): engUnit @116 (SDF_UNIT), int2engrUnit @138 (float): divide
  internal-unit data by it to get engineering units (V/EU).
- XDATA (type 16), YDATA (type 17): the values follow the 6-byte record head. Y data holds,
  for each data header in turn, rows × cols vectors of num_of_points × yPerPoint values
  (real, imaginary pairs when complex).

Engineering units: the stored frequency response is in internal units (V/V); each channel's
correction is ``int2engrUnit ** (-pow/48)``, so ``H_EU = H_V · s_ref / s_resp`` with the
channel sensitivities ``s`` in V/EU. The unit is response EU over reference EU, from the
channel headers (or the data header's yUnit when the vector names no channel). Window
corrections are not applied: a swept sine uses no window, and for a frequency response the
response and reference corrections cancel.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from viscorig.errors import InputError
from viscorig.exchange import units
from viscorig.exchange.frfset import FrfSet, combine

FILE_ID = b"B\x00"
FILE_HDR, MEAS_HDR, DATA_HDR, VECTOR_HDR, CHANNEL_HDR = 10, 11, 12, 13, 14
XDATA, YDATA = 16, 17
REVISION = 2
APPLICATION_35670A = 10
SWEPT_MEASUREMENT = 2
FREQUENCY_DOMAIN = 0
FREQUENCY_RESPONSE = 4
#: SDF data type code -> big-endian struct letter and size
NUMBER_TYPES = {1: ("h", 2), 2: ("l", 4), 3: ("f", 4), 4: ("d", 8)}
#: The largest SDF file read.
MAX_SDF_BYTES = 16 * 1024 * 1024


@dataclass(frozen=True)
class SdfFrf:
    """One frequency response read from an SDF file, in the units the file declares."""

    frequency_hz: NDArray[np.float64]
    values: NDArray[np.complex128]
    response_unit: str
    reference_unit: str
    title: str

    def accelerance(self, where: str) -> NDArray[np.complex128]:
        """The values in m/s²/N; :class:`InputError` unless acceleration over force."""
        acceleration = units.factor(self.response_unit, units.ACCELERATION_UNITS,
                                    "acceleration", f"{where}: response channel unit")
        force = units.factor(self.reference_unit, units.FORCE_UNITS, "force",
                             f"{where}: reference channel unit")
        return self.values * (acceleration / force)


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

    def record(self, offset: int, kind: int, what: str, minimum: int) -> int:
        """Check a record head at ``offset``; return the record size."""
        record_type, size = self.unpack("hl", offset, what)
        if record_type != kind:
            raise InputError(f"expected the {what} (record type {kind}) at byte {offset}, "
                             f"found type {record_type}", self.where)
        if size < minimum or offset + size > len(self.data):
            raise InputError(f"{what} at byte {offset} has size {size} (file has "
                             f"{len(self.data)} bytes)", self.where)
        return size

    def text(self, offset: int, length: int, what: str) -> str:
        (raw,) = self.unpack(f"{length}s", offset, what)
        return raw.split(b"\x00", 1)[0].decode("latin-1").strip()


def _numbers(b: _Bytes, offset: int, code: int, count: int, what: str) -> NDArray[np.float64]:
    if code not in (3, 4):
        raise InputError(f"{what} data type {code} is not float (3) or double (4)", b.where)
    letter, size = NUMBER_TYPES[code]
    if offset + count * size > len(b.data):
        raise InputError(f"file ends inside the {what} ({count} values from byte {offset})",
                         b.where)
    return np.frombuffer(b.data, dtype=f">{letter}", count=count, offset=offset).astype(float)


def read_sdf(path: Path) -> list[SdfFrf]:
    """Every frequency response in an SDF revision 2 file of a 35670A swept-sine measurement.

    Raises
    ------
    InputError
        Not an SDF file, another revision, application or measurement type, no frequency
        response, a truncated or inconsistent record, an X axis not in Hz.
    """
    path = Path(path)
    where = str(path)
    try:
        size = path.stat().st_size
        if size > MAX_SDF_BYTES:
            raise InputError(f"{size} bytes; an SDF file is read up to {MAX_SDF_BYTES} (a "
                             "35670A saves to 1.44 MB disks)", where)
        data = path.read_bytes()
    except OSError as error:
        raise InputError(f"cannot read the file ({error.strerror})", where) from None
    if data[:2] != FILE_ID:
        raise InputError("not an SDF file (it does not start with 'B\\0')", where)
    b = _Bytes(data, where)
    head = 2
    file_size = b.record(head, FILE_HDR, "file header", 64)
    (revision, application) = b.unpack("hh", head + 6, "file header")
    if revision != REVISION:
        raise InputError(f"SDF revision {revision}; this reader knows revision 2", where)
    if application != APPLICATION_35670A:
        raise InputError(f"application code {application}, not a 35670A file (10)", where)
    counts = b.unpack("6h", head + 24, "file header")
    n_data, n_vector, n_channel, _, _, n_xdata = counts
    offsets = b.unpack("7l", head + 36, "file header")
    data_at, vector_at, channel_at, _, _, xdata_at, ydata_at = offsets
    meas_at = head + file_size
    b.record(meas_at, MEAS_HDR, "measurement header", 128)
    (measurement,) = b.unpack("h", meas_at + 126, "measurement header")
    if measurement != SWEPT_MEASUREMENT:
        raise InputError(f"measurement type {measurement}, not a swept sine (2)", where)
    channels = _channels(b, channel_at, n_channel)
    vectors = _vectors(b, vector_at, n_vector)
    if ydata_at < 0:
        raise InputError("has no Y data record", where)
    y_size = b.record(ydata_at, YDATA, "Y data record", 6)
    y_cursor = ydata_at + 6
    x_cursor = None
    if xdata_at >= 0 and n_xdata > 0:
        b.record(xdata_at, XDATA, "X data record", 6)
        x_cursor = xdata_at + 6
    file_axis: NDArray[np.float64] | None = None
    found: list[SdfFrf] = []
    cursor = data_at
    for index in range(n_data):
        what = f"data header {index + 1}"
        size = b.record(cursor, DATA_HDR, what, 130)
        h = _DataHeader.read(b, cursor, what)
        cursor += size
        values_per_vector = h.points * h.y_per_point * (2 if h.complex else 1)
        vectors_here = max(h.rows, 1) * max(h.cols, 1)
        y_bytes = NUMBER_TYPES.get(h.y_type, ("", 0))[1] * values_per_vector * vectors_here
        # the X axis of this data header
        if h.x_resolution == 0:
            axis = h.first_x + h.delta_x * np.arange(h.points)
        elif h.x_resolution == 1:
            axis = h.first_x * h.delta_x ** np.arange(h.points)
        elif h.x_resolution in (2, 3):
            if x_cursor is None:
                raise InputError(f"{what}: arbitrary X resolution but no X data record", where)
            if h.x_resolution == 2 and file_axis is not None:
                axis = file_axis
            else:
                axis = _numbers(b, x_cursor, h.x_type, h.points * h.x_per_point, "X data")
                axis = axis[:: max(h.x_per_point, 1)]
                x_cursor += NUMBER_TYPES[h.x_type][1] * h.points * h.x_per_point
                file_axis = axis if h.x_resolution == 2 else file_axis
        else:
            raise InputError(f"{what}: X resolution type {h.x_resolution} is not supported "
                             "(0 linear, 1 logarithmic, 2 or 3 arbitrary)", where)
        if h.domain != FREQUENCY_DOMAIN or h.data_type != FREQUENCY_RESPONSE:
            y_cursor += y_bytes  # another trace (a spectrum, the variance...): skip it
            continue
        if not h.complex:
            raise InputError(f"{what}: a frequency response must be complex", where)
        if h.y_per_point != 1:
            raise InputError(f"{what}: {h.y_per_point} Y values per point; expected 1", where)
        scale = units.factor(h.x_unit or "Hz", units.FREQUENCY_UNITS, "frequency",
                             f"{where}: {what} X unit")
        for vector in range(vectors_here):
            number = h.first_vector + vector
            if not 0 <= number < len(vectors):
                raise InputError(f"{what} points to vector header {number}, the file has "
                                 f"{len(vectors)}", where)
            pair = _channel_pair(vectors[number], channels, h, f"{where}: {what}")
            raw = _numbers(b, y_cursor, h.y_type, values_per_vector, "Y data")
            y_cursor += NUMBER_TYPES[h.y_type][1] * values_per_vector
            values = (raw[0::2] + 1j * raw[1::2]) * pair[2]
            found.append(SdfFrf(axis * scale, values, pair[0], pair[1], h.title))
    if y_cursor > ydata_at + y_size:
        raise InputError(f"Y data record holds {y_size - 6} bytes, the data headers describe "
                         f"{y_cursor - ydata_at - 6}", where)
    if not found:
        raise InputError("holds no frequency response (data type 4)", where)
    return found


@dataclass(frozen=True)
class _DataHeader:
    title: str
    domain: int
    data_type: int
    points: int
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
    def read(cls, b: _Bytes, at: int, what: str) -> _DataHeader:
        domain, data_type, points = b.unpack("hhh", at + 26, what)
        x_resolution, x_type, x_per_point, y_type, y_per_point, is_complex = b.unpack(
            "6h", at + 42, what)
        (first_vector,) = b.unpack("l", at + 60, what)
        rows, cols = b.unpack("hh", at + 64, what)
        (y_unit_valid,) = b.unpack("h", at + 90, what)
        first_x, delta_x = b.unpack("dd", at + 114, what)
        if points < 1:
            raise InputError(f"{what}: {points} points", b.where)
        if y_type not in NUMBER_TYPES:
            raise InputError(f"{what}: Y data type {y_type} is unknown", b.where)
        return cls(
            title=b.text(at + 10, 16, what), domain=domain, data_type=data_type, points=points,
            x_resolution=x_resolution, x_type=x_type, x_per_point=x_per_point, y_type=y_type,
            y_per_point=y_per_point, complex=bool(is_complex), first_vector=first_vector,
            rows=rows, cols=cols, x_unit=b.text(at + 68, 10, what),
            y_unit_valid=bool(y_unit_valid), y_unit=b.text(at + 92, 10, what),
            first_x=first_x, delta_x=delta_x,
        )


def _channels(b: _Bytes, at: int, count: int) -> list[tuple[str, float]]:
    """(engineering unit label, int2engrUnit) of each channel header."""
    channels = []
    for index in range(count):
        what = f"channel header {index + 1}"
        size = b.record(at, CHANNEL_HDR, what, 142)
        label = b.text(at + 116, 10, what)
        (factor,) = b.unpack("f", at + 138, what)
        if not np.isfinite(factor) or factor == 0:
            raise InputError(f"{what}: EU correction factor {factor} is not usable", b.where)
        channels.append((label, float(factor)))
        at += size
    return channels


def _vectors(b: _Bytes, at: int, count: int) -> list[tuple[int, int, int, int]]:
    """(response channel, reference channel, response power, reference power) per vector."""
    vectors = []
    for index in range(count):
        what = f"vector header {index + 1}"
        size = b.record(at, VECTOR_HDR, what, 18)
        vectors.append(b.unpack("4h", at + 10, what))
        at += size
    return vectors


def _channel_pair(
    vector: tuple[int, int, int, int],
    channels: list[tuple[str, float]],
    header: _DataHeader,
    where: str,
) -> tuple[str, str, float]:
    """(response unit, reference unit, factor internal -> EU) of one vector."""
    response, reference, response_power, reference_power = vector
    if response < 0 and reference < 0:
        if not header.y_unit_valid or "/" not in header.y_unit:
            raise InputError("names no channel and no Y unit of the form EU/EU", where)
        numerator, denominator = header.y_unit.split("/", 1)
        return numerator, denominator, 1.0
    if not (0 <= response < len(channels) and 0 <= reference < len(channels)):
        raise InputError(f"channel records ({response}, {reference}) are outside the file's "
                         f"{len(channels)} channel headers", where)
    if (response_power, reference_power) != (48, -48):
        raise InputError(f"channel powers ({response_power}, {reference_power})/48 are not "
                         "those of a frequency response (+1, -1)", where)
    (response_unit, response_factor), (reference_unit, reference_factor) = (
        channels[response], channels[reference])
    return response_unit, reference_unit, reference_factor / response_factor


def read_sdf_frfs(paths: list[Path]) -> FrfSet:
    """The FRFs of one or two SDF files as a run: the first is ẍ_s/F_e, the second ẍ_v/F_v.

    A single file may also hold both (two frequency-response data headers or vectors).
    """
    axes, values, names = [], [], []
    for path in paths:
        for number, frf in enumerate(read_sdf(Path(path)), start=1):
            name = f"{path} (frequency response {number})"
            axes.append(frf.frequency_hz)
            values.append(frf.accelerance(name))
            names.append(name)
    source = "SDF " + ", ".join(Path(p).name for p in paths)
    return combine(axes, values, names, source)
