"""Tests for comms.codec: round trips of every message type and rejection of bad bytes.

Wire format: a msgpack array ``[MAGIC, VERSION, sender, seq, t, [[kind, ...], ...]]`` followed
by a 4-byte little-endian CRC-32 of it. Malformed frames are built here with ``msgpack.packb``
directly and sealed with a correct CRC (:func:`seal`) so they reach the schema checks; the
format itself is pinned by :func:`test_wire_format_is_msgpack_array_plus_crc32`.
"""

from __future__ import annotations

import math
import zlib

import msgpack
import pytest
from budget import examples
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from agents.knowledge import Track
from comms.codec import (
    DEFAULT_MAX_BYTES,
    K_HELLO,
    K_INTENT,
    K_SCAN,
    K_THREATS,
    K_TRACKS,
    MAGIC,
    VERSION,
    Frame,
    FrameError,
    decode,
    encode,
    encode_decoded,
    pack_hello,
    pack_intent,
    pack_scans,
    pack_tracks,
)
from comms.messages import (
    MODE_SEARCH,
    MODE_SURVEIL,
    NO_TARGET,
    Hello,
    Intent,
    ScanDigest,
    ScanRecords,
    ThreatItem,
    Threats,
    TrackItem,
    Tracks,
)

# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------


def seal(payload: bytes) -> bytes:
    """Append the frame check sequence the codec expects (CRC-32, little endian)."""
    return payload + zlib.crc32(payload).to_bytes(4, "little")


def packed(obj) -> bytes:
    return seal(msgpack.packb(obj, use_bin_type=True))


def frame_obj(messages, sender=3, seq=7, t=12.5, magic=MAGIC, version=VERSION):
    return [magic, version, sender, seq, t, messages]


def decode_or_frame_error(data: bytes, **kw) -> Frame | None:
    """Decode; a FrameError is fine, anything else propagates and fails the test."""
    try:
        f = decode(data, **kw)
    except FrameError:
        return None
    assert type(f) is Frame
    return f


def assert_well_typed(f: Frame) -> None:
    """A frame that decode accepted satisfies the schema it promises."""
    assert type(f.sender) is int and type(f.seq) is int
    assert type(f.t) is float and math.isfinite(f.t)
    assert type(f.messages) is tuple
    for m in f.messages:
        if type(m) is Hello:
            assert type(m.uav) is int and type(m.type) is str and len(m.type) <= 64
            nums = (m.x, m.y, m.v, m.theta)
        elif type(m) is Intent:
            assert type(m.uav) is int and type(m.target) is int and m.mode in (0, 1)
            nums = (m.wx, m.wy)
        elif type(m) is ScanRecords:
            assert type(m.uav) is int and type(m.records) is tuple and len(m.records) % 4 == 0
            nums = m.records
        elif type(m) is Tracks:
            nums = ()
            for i in m.items:
                assert type(i) is TrackItem and type(i.target) is int
                nums += (i.x, i.y, i.vx, i.vy, i.t, i.value)
        elif type(m) is Threats:
            nums = ()
            for i in m.items:
                assert type(i) is ThreatItem and type(i.threat) is int
                assert 0 < i.radius <= i.d_max
                nums += (i.x, i.y, i.radius, i.d_max)
        elif type(m) is ScanDigest:
            assert type(m.uav) is int and type(m.tick0) is int and type(m.lo) is int and type(m.hi) is int
            assert all(type(o) is int and type(b) is bytes for o, b in m.bitmaps)
            nums = (m.t_cut,)
        else:  # pragma: no cover - the assertion is the point
            raise AssertionError(f"unexpected message type {type(m)}")
        assert all(type(v) is float and math.isfinite(v) for v in nums)


# ---------------------------------------------------------------------------------------------
# strategies
# ---------------------------------------------------------------------------------------------

ints = st.integers(-(2**63), 2**64 - 1)
small_ints = st.integers(-1, 10_000)
finite = st.floats(allow_nan=False, allow_infinity=False)
positive = st.floats(min_value=0.0, exclude_min=True, allow_nan=False, allow_infinity=False)

hellos = st.builds(Hello, ints, st.text(max_size=64), finite, finite, finite, finite)
intents = st.builds(Intent, ints, finite, finite, st.sampled_from([MODE_SEARCH, MODE_SURVEIL]),
                    st.one_of(st.just(NO_TARGET), ints))
scans = st.builds(
    ScanRecords,
    ints,
    st.lists(st.tuples(finite, finite, finite, finite), max_size=10).map(lambda rs: tuple(v for r in rs for v in r)),
)
tracks = st.builds(
    Tracks,
    st.lists(st.builds(TrackItem, ints, finite, finite, finite, finite, finite, finite), max_size=6).map(tuple),
)
threat_items = positive.flatmap(
    lambda r: st.builds(
        ThreatItem,
        ints,
        finite,
        finite,
        st.just(r),
        st.one_of(st.just(r), st.floats(min_value=r, allow_nan=False, allow_infinity=False)),
    )
)
threats = st.builds(Threats, st.lists(threat_items, max_size=6).map(tuple))
digests = st.builds(ScanDigest, ints, finite, ints, ints, ints,
                    st.lists(st.tuples(ints, st.binary(max_size=40)), max_size=5).map(tuple))
messages = st.one_of(hellos, intents, scans, tracks, threats, digests)
frames = st.builds(Frame, ints, ints, finite, st.lists(messages, max_size=6).map(tuple))

# arbitrary msgpack-able values, for structure-aware fuzzing
msgpack_values = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        ints,
        st.floats(),  # includes nan/inf
        st.text(max_size=70),
        st.binary(max_size=8),
    ),
    lambda children: st.one_of(st.lists(children, max_size=8), st.dictionaries(st.text(max_size=4), children, max_size=3)),
    max_leaves=20,
)


def enc(f: Frame) -> bytes:
    return encode(f.sender, f.seq, f.t, f.messages)


# ---------------------------------------------------------------------------------------------
# round trip
# ---------------------------------------------------------------------------------------------


def test_wire_format_is_msgpack_array_plus_crc32():
    hello = Hello(4, "A", 1.0, 2.0, 30.0, 0.5)
    data = encode(4, 9, 2.5, [hello])
    body = msgpack.packb([MAGIC, VERSION, 4, 9, 2.5, [[K_HELLO, 4, "A", 1.0, 2.0, 30.0, 0.5]]], use_bin_type=True)
    assert data == seal(body)
    assert decode(data) == Frame(4, 9, 2.5, (hello,))


@settings(deadline=None)
@given(frames)
def test_round_trip_any_frame(f):
    data = enc(f)
    assert type(data) is bytes
    got = decode(data)
    assert got == f
    assert_well_typed(got)
    # bytearray input is accepted too
    assert decode(bytearray(data)) == f


@pytest.mark.parametrize("strategy", [hellos, intents, scans, tracks, threats, digests],
                         ids=["hello", "intent", "scan", "tracks", "threats", "digest"])
def test_round_trip_each_message_type(strategy):
    @settings(deadline=None, max_examples=examples(60))
    @given(ints, ints, finite, st.lists(strategy, min_size=1, max_size=4))
    def check(sender, seq, t, msgs):
        got = decode(encode(sender, seq, t, msgs))
        assert got == Frame(sender, seq, t, tuple(msgs))
        assert [type(m) for m in got.messages] == [type(m) for m in msgs]

    check()


def test_round_trip_concrete_values():
    msgs = (
        Hello(1, "B", -5.5, 1e6, 25.0, -math.pi),
        Intent(1, 100.0, 200.0, MODE_SURVEIL, 17),
        Intent(2, 0.0, -0.0, MODE_SEARCH, NO_TARGET),
        ScanRecords(1, (1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)),
        ScanRecords(3, ()),
        Tracks((TrackItem(5, 1.0, 2.0, 0.5, -0.5, 99.0, 3.0),)),
        Tracks(()),
        Threats((ThreatItem(0, 6000.0, 6000.0, 800.0, 800.0), ThreatItem(1, 0.0, 0.0, 1e-300, 1e300))),
    )
    f = decode(encode(2**64 - 1, -(2**63), 1e-9, msgs))
    assert f == Frame(2**64 - 1, -(2**63), 1e-9, msgs)
    assert decode(encode(0, 0, 0, [])) == Frame(0, 0, 0.0, ())


def test_integer_numbers_decode_as_float():
    data = packed(frame_obj([[K_SCAN, 1, [1, 2, 3, 4]], [K_INTENT, 2, 10, 20, 1, 5]], t=3))
    f = decode(data)
    assert f.t == 3.0 and type(f.t) is float
    assert f.messages[0] == ScanRecords(1, (1.0, 2.0, 3.0, 4.0))
    assert all(type(v) is float for v in f.messages[0].records)
    assert type(f.messages[1].wx) is float


def test_encode_rejects_non_message():
    with pytest.raises(TypeError, match="not a message"):
        encode(1, 1, 0.0, ["hello"])


def _packed_form(m):
    """What a sender may hand encode() instead of the message (see codec.pack_hello, ...)."""
    if type(m) is Hello:
        return pack_hello(m.uav, m.type, m.x, m.y, m.v, m.theta)
    if type(m) is Intent:
        return pack_intent(m.uav, m.wx, m.wy, m.mode, m.target)
    if type(m) is ScanRecords:
        return pack_scans(m.uav, list(m.records))
    if type(m) is Tracks:
        # From objects that only share TrackItem's fields (a UAV's own tracks).
        return pack_tracks([Track(i.target, i.x, i.y, i.vx, i.vy, i.t, i.value) for i in m.items])
    return m


@given(frames)
def test_packed_forms_encode_as_the_messages(f):
    as_messages = encode(f.sender, f.seq, f.t, f.messages)
    assert encode(f.sender, f.seq, f.t, [_packed_form(m) for m in f.messages]) == as_messages


# ---------------------------------------------------------------------------------------------
# rejection: arbitrary bytes, truncation, oversize, corruption
# ---------------------------------------------------------------------------------------------


@settings(deadline=None, max_examples=examples(300))
@given(st.binary(max_size=300))
def test_arbitrary_bytes_give_frame_or_frame_error(data):
    f = decode_or_frame_error(data)
    if f is not None:
        assert_well_typed(f)


@settings(deadline=None, max_examples=examples(300))
@given(st.binary(max_size=300))
def test_arbitrary_sealed_bytes_give_frame_or_frame_error(data):
    # with a valid CRC the msgpack parser and schema checks see the garbage
    f = decode_or_frame_error(seal(data))
    if f is not None:
        assert_well_typed(f)


@settings(deadline=None, max_examples=examples(300))
@given(msgpack_values)
def test_arbitrary_msgpack_objects_give_frame_or_frame_error(obj):
    f = decode_or_frame_error(packed(obj))
    if f is not None:
        assert_well_typed(f)


@settings(deadline=None, max_examples=examples(300))
@given(frames.filter(lambda f: f.messages), st.data())
def test_structure_aware_field_replacement(f, data):
    """Replace one field somewhere inside a valid frame with an arbitrary msgpack value."""
    obj = msgpack.unpackb(enc(f)[:-4], raw=False)
    # collect every (container, index) position
    positions = []

    def walk(node):
        if isinstance(node, list):
            for i, child in enumerate(node):
                positions.append((node, i))
                walk(child)

    walk(obj)
    container, i = data.draw(st.sampled_from(positions))
    container[i] = data.draw(msgpack_values)
    got = decode_or_frame_error(packed(obj))
    if got is not None:
        assert_well_typed(got)


@settings(deadline=None)
@given(frames)
def test_every_strict_prefix_raises_frame_error(f):
    data = enc(f)
    step = max(1, len(data) // 64)  # all prefixes of short frames, a sample of long ones
    cuts = set(range(0, len(data), step)) | set(range(max(0, len(data) - 8), len(data)))
    for n in sorted(cuts):
        with pytest.raises(FrameError):
            decode(data[:n])


def test_every_strict_prefix_of_a_small_frame_raises_frame_error():
    data = encode(1, 2, 3.0, [Hello(1, "A", 1.0, 2.0, 3.0, 4.0), Intent(1, 5.0, 6.0, 1, 2)])
    for n in range(len(data)):
        with pytest.raises(FrameError):
            decode(data[:n])
    assert decode(data).seq == 2


def test_oversized_frame_is_rejected_before_parsing():
    big = encode(1, 1, 0.0, [ScanRecords(1, tuple(float(i) for i in range(8000)))])
    assert len(big) > DEFAULT_MAX_BYTES
    with pytest.raises(FrameError, match=rf"oversized frame: {len(big)} > {DEFAULT_MAX_BYTES} bytes"):
        decode(big)
    # it is the size cap, not the content: a larger cap accepts the same bytes
    assert len(decode(big, max_bytes=len(big)).messages[0].records) == 8000
    small = encode(1, 1, 0.0, [Hello(1, "A", 0.0, 0.0, 0.0, 0.0)])
    with pytest.raises(FrameError, match="oversized"):
        decode(small, max_bytes=len(small) - 1)
    assert decode(small, max_bytes=len(small)).sender == 1
    # garbage that is oversized is reported as oversized, not as undecodable
    with pytest.raises(FrameError, match="oversized"):
        decode(b"\xc1" * (DEFAULT_MAX_BYTES + 1))


def test_non_bytes_input_is_frame_error():
    for bad in ("text", None, 123, [1, 2], memoryview(b"abc")):
        with pytest.raises(FrameError, match="frame is not bytes"):
            decode(bad)


@settings(deadline=None)
@given(frames, st.data())
def test_single_byte_flip_is_always_detected(f, data):
    raw = enc(f)
    pos = data.draw(st.integers(0, len(raw) - 1))
    x = data.draw(st.integers(1, 255))
    buf = bytearray(raw)
    buf[pos] ^= x
    with pytest.raises(FrameError):
        decode(bytes(buf))


@settings(deadline=None, max_examples=examples(300))
@given(frames, st.data())
def test_random_byte_flips_never_raise_anything_but_frame_error(f, data):
    raw = enc(f)
    flips = data.draw(st.lists(st.tuples(st.integers(0, len(raw) - 1), st.integers(1, 255)), min_size=1, max_size=6))
    buf = bytearray(raw)
    for pos, x in flips:
        buf[pos] ^= x
    got = decode_or_frame_error(bytes(buf))
    if got is not None:
        assert_well_typed(got)
    # the same flips under a recomputed (valid) CRC exercise the parser and schema checks
    got = decode_or_frame_error(seal(bytes(buf[:-4])))
    if got is not None:
        assert_well_typed(got)


def test_crc_mismatch_message():
    data = bytearray(encode(1, 1, 1.0, []))
    data[-1] ^= 0xFF
    with pytest.raises(FrameError, match="checksum mismatch"):
        decode(bytes(data))


def test_trailing_garbage_inside_the_checksum_is_rejected():
    body = msgpack.packb(frame_obj([]), use_bin_type=True) + b"\x00"
    with pytest.raises(FrameError, match="undecodable frame: ExtraData"):
        decode(seal(body))


# ---------------------------------------------------------------------------------------------
# rejection: hand-built frames that violate the schema
# ---------------------------------------------------------------------------------------------

HELLO = [K_HELLO, 1, "A", 1.0, 2.0, 3.0, 4.0]
INTENT = [K_INTENT, 1, 1.0, 2.0, 0, -1]
SCAN = [K_SCAN, 1, [1.0, 2.0, 3.0, 4.0]]
TRACKS = [K_TRACKS, [[1, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]]]
THREATS = [K_THREATS, [[1, 1.0, 2.0, 3.0, 4.0]]]


def test_hand_built_valid_frame_decodes():
    f = decode(packed(frame_obj([HELLO, INTENT, SCAN, TRACKS, THREATS])))
    assert [type(m) for m in f.messages] == [Hello, Intent, ScanRecords, Tracks, Threats]
    assert f.messages[4] == Threats((ThreatItem(1, 1.0, 2.0, 3.0, 4.0),))


@pytest.mark.parametrize(
    "obj, message",
    [
        # envelope
        (frame_obj([], magic=0x5358), "bad magic"),
        (frame_obj([], magic=float(MAGIC)), "bad magic"),
        (frame_obj([], magic="SW"), "bad magic"),
        (frame_obj([], version=2), "unsupported version 2"),
        (frame_obj([], version=0), "unsupported version 0"),
        (frame_obj([], version=True), "unsupported version True"),
        (frame_obj([], version=1.0), "unsupported version 1.0"),
        ([MAGIC, VERSION, 1, 2, 3.0], "expected 6 fields, got 5"),
        ([MAGIC, VERSION, 1, 2, 3.0, [], []], "expected 6 fields, got 7"),
        ({"magic": MAGIC}, "expected an array, got dict"),
        (MAGIC, "expected an array, got int"),
        (frame_obj([], sender=True), "expected an integer, got bool"),
        (frame_obj([], sender=1.0), "expected an integer, got float"),
        (frame_obj([], seq=None), "expected an integer, got NoneType"),
        (frame_obj([], t=True), "expected a number, got bool"),
        (frame_obj([], t=float("nan")), "non-finite number"),
        (frame_obj([], t=float("inf")), "non-finite number"),
        (frame_obj([], t="1.0"), "expected a number, got str"),
        (frame_obj({}), "expected an array, got dict"),
        # message envelope
        (frame_obj([[]]), "empty message"),
        (frame_obj([[0]]), "unknown message kind 0"),
        (frame_obj([[8, 1]]), "unknown message kind 8"),
        (frame_obj([[7, 1]]), "expected 6 fields, got 2"),  # (a track digest, issue 36 M1)
        (frame_obj([[6, 1, 0.0, 0, 0, 9, [[1, "not bytes"]]]]), "digest: bitmap is not bytes"),
        (frame_obj([[6, 1, 0.0, 0, 0, 9, [[1]]]]), "expected 2 fields, got 1"),
        (frame_obj([[6, 1, 0.0, 0, 9, []]]), "expected 7 fields, got 6"),
        (frame_obj([[-1]]), "unknown message kind -1"),
        (frame_obj([[True, 1, "A", 1.0, 2.0, 3.0, 4.0]]), "expected an integer, got bool"),
        (frame_obj([[1.0, 1, "A", 1.0, 2.0, 3.0, 4.0]]), "expected an integer, got float"),
        (frame_obj(["hello"]), "expected an array, got str"),
        # hello
        (frame_obj([HELLO[:-1]]), "expected 7 fields, got 6"),
        (frame_obj([HELLO + [5.0]]), "expected 7 fields, got 8"),
        (frame_obj([[K_HELLO, 1, "A" * 65, 1.0, 2.0, 3.0, 4.0]]), "hello: bad type name"),
        (frame_obj([[K_HELLO, 1, b"A", 1.0, 2.0, 3.0, 4.0]]), "hello: bad type name"),
        (frame_obj([[K_HELLO, 1, "A", True, 2.0, 3.0, 4.0]]), "expected a number, got bool"),
        (frame_obj([[K_HELLO, 1, "A", 1.0, float("nan"), 3.0, 4.0]]), "non-finite number"),
        (frame_obj([[K_HELLO, 1, "A", 1.0, 2.0, float("-inf"), 4.0]]), "non-finite number"),
        (frame_obj([[K_HELLO, False, "A", 1.0, 2.0, 3.0, 4.0]]), "expected an integer, got bool"),
        # intent
        (frame_obj([INTENT[:-1]]), "expected 6 fields, got 5"),
        (frame_obj([[K_INTENT, 1, 1.0, 2.0, 2, -1]]), "intent: bad mode"),
        (frame_obj([[K_INTENT, 1, 1.0, 2.0, -1, -1]]), "intent: bad mode"),
        (frame_obj([[K_INTENT, 1, 1.0, 2.0, True, -1]]), "expected an integer, got bool"),
        (frame_obj([[K_INTENT, 1, 1.0, 2.0, 0, 1.5]]), "expected an integer, got float"),
        (frame_obj([[K_INTENT, 1, False, 2.0, 0, -1]]), "expected a number, got bool"),
        # scan
        (frame_obj([[K_SCAN, 1, [1.0, 2.0, 3.0]]]), "scan: record list not a multiple of 4"),
        (frame_obj([[K_SCAN, 1, [1.0, 2.0, 3.0, 4.0, 5.0]]]), "scan: record list not a multiple of 4"),
        (frame_obj([[K_SCAN, 1, [1.0, 2.0, 3.0, float("nan")]]]), "non-finite number"),
        (frame_obj([[K_SCAN, 1, [1.0, 2.0, True, 4.0]]]), "expected a number, got bool"),
        (frame_obj([[K_SCAN, 1, [1.0, 2.0, None, 4.0]]]), "expected a number, got NoneType"),
        (frame_obj([[K_SCAN, 1]]), "expected 3 fields, got 2"),
        (frame_obj([[K_SCAN, 1, "1,2,3,4"]]), "expected an array, got str"),
        # tracks
        (frame_obj([[K_TRACKS, [[1, 1.0, 2.0, 3.0, 4.0, 5.0]]]]), "expected 7 fields, got 6"),
        (frame_obj([[K_TRACKS, [[1, 1.0, 2.0, 3.0, 4.0, 5.0, float("inf")]]]]), "non-finite number"),
        (frame_obj([[K_TRACKS, [[True, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]]]]), "expected an integer, got bool"),
        (frame_obj([[K_TRACKS, [[1, 1.0, 2.0, 3.0, 4.0, 5.0, True]]]]), "expected a number, got bool"),
        (frame_obj([[K_TRACKS, [1, 2]]]), "expected an array, got int"),
        (frame_obj([[K_TRACKS, [], []]]), "expected 2 fields, got 3"),
        # threats
        (frame_obj([[K_THREATS, [[1, 1.0, 2.0, 0.0, 4.0]]]]), "threat: bad radius"),
        (frame_obj([[K_THREATS, [[1, 1.0, 2.0, -3.0, 4.0]]]]), "threat: bad radius"),
        (frame_obj([[K_THREATS, [[1, 1.0, 2.0, 3.0, 2.9]]]]), "threat: bad radius"),
        (frame_obj([[K_THREATS, [[1, 1.0, 2.0, float("nan"), 4.0]]]]), "non-finite number"),
        (frame_obj([[K_THREATS, [[1, 1.0, 2.0, 3.0]]]]), "expected 5 fields, got 4"),
        (frame_obj([[K_THREATS, [[1, 1.0, 2.0, 3.0, True]]]]), "expected a number, got bool"),
    ],
)
def test_schema_violations_raise_frame_error(obj, message):
    data = packed(obj)
    with pytest.raises(FrameError) as ei:
        decode(data)
    assert message in str(ei.value)
    assert type(ei.value) is FrameError


def test_one_bad_message_rejects_the_whole_frame():
    good = [HELLO, INTENT, SCAN]
    assert len(decode(packed(frame_obj(good))).messages) == 3
    with pytest.raises(FrameError, match="intent: bad mode"):
        decode(packed(frame_obj(good + [[K_INTENT, 1, 1.0, 2.0, 7, -1]])))


def test_undecodable_msgpack_is_frame_error():
    with pytest.raises(FrameError, match="undecodable frame"):
        decode(seal(b"\xc1"))  # 0xc1 is never used in msgpack
    with pytest.raises(FrameError, match="undecodable frame"):
        decode(seal(b"\x96\x01"))  # array of 6 with one element: truncated inside the CRC


def test_deep_nesting_is_frame_error():
    obj = frame_obj([[K_TRACKS, [[1]]]])
    deep: list = []
    cur = deep
    for _ in range(5000):
        nxt: list = []
        cur.append(nxt)
        cur = nxt
    obj[5][0][1][0] = deep
    try:
        data = packed(obj)
    except (ValueError, RecursionError):  # msgpack refuses to pack it: build the bytes by hand
        data = seal(b"\x91" * 5000 + b"\x90")
    with pytest.raises(FrameError):
        decode(data)


def test_frame_error_is_a_value_error():
    assert issubclass(FrameError, ValueError)


@settings(deadline=None)
@given(frames, st.integers(min_value=1, max_value=8))
def test_trailing_bytes_after_a_valid_frame_are_rejected(f, n):
    data = enc(f)
    assume(len(data) + n <= DEFAULT_MAX_BYTES)
    with pytest.raises(FrameError):
        decode(data + b"\x00" * n)


# ---------------------------------------------------------------------------------------------
# encode_decoded: the sender's frame, as decoding would give it
# ---------------------------------------------------------------------------------------------


@settings(deadline=None)
@given(frames, st.sampled_from([None, b"swarm key"]))
def test_encode_decoded_gives_the_bytes_and_what_decoding_them_gives(f, key):
    for msgs in (f.messages, [_packed_form(m) for m in f.messages]):
        data, got = encode_decoded(f.sender, f.seq, f.t, msgs, key)
        assert data == encode(f.sender, f.seq, f.t, msgs, key)
        assert got is not None and got == decode(data, key=key)
        assert_well_typed(got)


def test_encode_decoded_leaves_to_decoding_what_it_cannot_vouch_for():
    import numpy as np

    hello = pack_hello(1, "B", 1.0, 2.0, 3.0, 0.5)
    # A numpy float is written as a float (decoding accepts it); a bool and a NaN are rejected.
    for bad, accepted in ((np.float64(1.5), True), (True, False), (math.nan, False)):
        msgs = [hello, pack_scans(1, [1.0, bad, 2.0, 3.0])]
        data, got = encode_decoded(1, 2, 3.0, msgs)
        assert got is None
        if accepted:
            assert decode(data).messages[1] == ScanRecords(1, (1.0, 1.5, 2.0, 3.0))
        else:
            with pytest.raises(FrameError):
                decode(data)
    data, got = encode_decoded(1, 2, 3.0, [hello], max_bytes=10)  # too long to be decoded
    assert got is None and data == encode(1, 2, 3.0, [hello])
