"""Telemetry frames: the documented fixed layout, round trips, refusal of anything else."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.wire.messages import ControlMode, RobotState
from shared.wire.telemetry import (
    FRAME_DTYPE,
    FRAME_SIZE,
    TelemetryError,
    TelemetryFrame,
    decode_frame,
    decode_frames,
    encode_frame,
)

FRAME = TelemetryFrame(
    time=12.34, frame=617, state=RobotState.RUNNING, mode=ControlMode.FORCE, statement=42,
    q=(0.1, -0.2, 0.3, -0.4, 0.5, -0.6), position=(0.45, -0.1, 0.32), rpy=(0.0, 3.1, -0.2),
    gripper=0.012, wrench=(1.0, -2.0, 15.5, 0.01, 0.02, -0.03),
)


def test_layout_is_the_documented_one():
    assert FRAME_SIZE == 174
    offsets = {name: FRAME_DTYPE.fields[name][1] for name in FRAME_DTYPE.names}
    assert offsets == {"magic": 0, "version": 2, "state": 3, "mode": 4, "dof": 5, "time": 6, "frame": 14,
                       "statement": 18, "q": 22, "position": 70, "rpy": 94, "gripper": 118, "wrench": 126}


def test_round_trip():
    data = encode_frame(FRAME)
    assert len(data) == FRAME_SIZE
    assert decode_frame(data) == FRAME


def test_one_frame_decodes_to_plain_python_numbers_as_the_array_view_reads_them():
    """``decode_frame`` (``struct``) and ``decode_frames`` (numpy) read the same bytes alike."""
    data = encode_frame(FRAME)
    frame, rec = decode_frame(data), decode_frames(data)[0]
    assert type(frame.time) is float and type(frame.frame) is int and type(frame.statement) is int
    assert all(type(v) is float for v in (*frame.q, *frame.position, *frame.rpy, frame.gripper, *frame.wrench))
    assert frame.state is RobotState(int(rec["state"])) and frame.mode is ControlMode(int(rec["mode"]))
    assert frame.q == tuple(float(v) for v in rec["q"][: int(rec["dof"])]) and frame.wrench == tuple(rec["wrench"].tolist())
    assert (frame.time, frame.frame, frame.gripper) == (float(rec["time"]), int(rec["frame"]), float(rec["gripper"]))


def test_fewer_joints_are_padded_and_restored():
    rover = TelemetryFrame(time=0.0, frame=0, state=RobotState.IDLE, mode=ControlMode.POSITION, statement=0,
                           q=(0.1, 0.2, 0.3), position=(0, 0, 0), rpy=(0, 0, 0))
    data = encode_frame(rover)
    assert len(data) == FRAME_SIZE
    assert decode_frame(data).q == (0.1, 0.2, 0.3)
    assert np.all(decode_frames(data)["q"][0, 3:] == 0.0)


def test_fields_sit_at_their_offsets_little_endian():
    data = encode_frame(FRAME)
    assert data[:2] == b"TF" and data[3] == int(RobotState.RUNNING) and data[4] == int(ControlMode.FORCE)
    assert int.from_bytes(data[14:18], "little") == 617
    assert int.from_bytes(data[18:22], "little") == 42
    assert np.frombuffer(data[22:30], "<f8")[0] == 0.1


def test_a_recording_decodes_at_once():
    frames = [encode_frame(TelemetryFrame(**{**FRAME.__dict__, "frame": i, "time": i / 50})) for i in range(100)]
    arr = decode_frames(b"".join(frames))
    assert arr.shape == (100,)
    assert np.array_equal(arr["frame"], np.arange(100))
    assert np.allclose(np.diff(arr["time"]), 0.02)


@pytest.mark.parametrize("cut", [0, 1, FRAME_SIZE - 1])
def test_wrong_sizes_are_refused(cut):
    with pytest.raises(TelemetryError):
        decode_frame(encode_frame(FRAME)[:cut])
    with pytest.raises(TelemetryError):
        decode_frame(encode_frame(FRAME) + b"\x00")


@pytest.mark.parametrize(("offset", "value"), [(0, ord("X")), (2, 7), (3, 200), (4, 9), (5, 0), (5, 7)])
def test_bad_header_bytes_are_refused(offset, value):
    data = bytearray(encode_frame(FRAME))
    data[offset] = value
    with pytest.raises(TelemetryError):
        decode_frame(bytes(data))


def test_too_many_joints_cannot_be_encoded():
    with pytest.raises(TelemetryError):
        encode_frame(TelemetryFrame(**{**FRAME.__dict__, "q": (0.0,) * 7}))


# the magic and mostly the version right, the state, mode and joint count bytes anything: most
# of these frames decode, the rest probe the header checks at their edges
TF_HEADER = st.builds(
    lambda version, state, mode, dof: b"TF" + bytes([version, state, mode, dof]),
    st.sampled_from([1, 1, 1, 0, 2]), st.integers(0, 255) | st.sampled_from([int(s) for s in RobotState]),
    st.integers(0, 255) | st.sampled_from([int(m) for m in ControlMode]), st.integers(0, 255) | st.integers(0, 7),
)


def _same(a, b) -> bool:
    return bool(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True))


@settings(max_examples=300)
@given(st.binary(min_size=FRAME_SIZE, max_size=FRAME_SIZE)
       | st.tuples(TF_HEADER, st.binary(min_size=FRAME_SIZE - 6, max_size=FRAME_SIZE - 6)).map(b"".join))
def test_random_bytes_decode_or_raise_the_typed_error(data):
    """Bytes with a bad header (read here from the documented layout) raise ``TelemetryError``;
    any others decode to the values at the documented offsets, and encode back to them."""
    magic, version, state, mode, dof = data[:2], data[2], data[3], data[4], data[5]
    valid = (magic == b"TF" and version == 1 and state in {int(s) for s in RobotState}
             and mode in {int(m) for m in ControlMode} and 1 <= dof <= 6)
    if not valid:
        with pytest.raises(TelemetryError):
            decode_frame(data)
        return
    frame = decode_frame(data)  # anything but a frame fails the test
    f8 = lambda offset, n=1: np.frombuffer(data[offset:offset + 8 * n], "<f8")  # noqa: E731
    assert int(frame.state) == state and int(frame.mode) == mode and len(frame.q) == dof
    assert frame.frame == int.from_bytes(data[14:18], "little") and frame.statement == int.from_bytes(data[18:22], "little")
    assert _same(frame.time, f8(6)[0]) and _same(frame.q, f8(22, dof)) and _same(frame.position, f8(70, 3))
    assert _same(frame.rpy, f8(94, 3)) and _same(frame.gripper, f8(118)[0]) and _same(frame.wrench, f8(126, 6))
    again = decode_frame(encode_frame(frame))
    for name in ("time", "q", "position", "rpy", "gripper", "wrench"):
        assert _same(getattr(again, name), getattr(frame, name)), name
    assert (again.frame, again.statement, again.state, again.mode) == (frame.frame, frame.statement, frame.state, frame.mode)
