"""Hostile bags: truncated, bit-flipped, chunk-damaged, length-corrupted, empty, random, bad metadata.

A small real bag (the first 30 s of the committed microsat_pd_slew recording, rewritten by the
recorder's own BagWriter in 8 KiB zstd chunks, every CRC on) is damaged in every way below and
given to ``adcs-analyze`` (its ``main`` in-process) and ``adcs-bag-repair``. For each:

* no exception escapes ``main``: exit 0 with one warning line on stderr, or exit 1 with one error
  line (naming the byte offset where there is one);
* metrics come only with the warning, and they equal the metrics of the original cut at the byte
  the warning names (the intact prefix, checked against the mcap library's own message count);
* repair is truthful: 'complete, nothing to repair' only for an intact bag; a repaired bag holds
  exactly the intact prefix's messages; nothing intact -> exit 1 and the file untouched.
"""
from __future__ import annotations

import contextlib
import io
import json
import re
import struct
from pathlib import Path

import pytest
import zstandard
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import CompressionType, Writer
from support.paths import ROOT

from adcs_sim.app.analysis.analyze import main as analyze_main
from adcs_sim.app.analysis.repair import main as repair_main
from adcs_sim.bag.reader import is_complete, read_metadata, read_raw
from adcs_sim.bag.records import MAX_CHUNK_BYTES
from adcs_sim.bag.writer import BagWriter

SOURCE = ROOT / 'bags' / 'microsat_pd_slew' / 'bag'
SECONDS = 30
FUZZ = settings(derandomize=True, max_examples=40, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
FLIPS = settings(FUZZ, max_examples=150)


@pytest.fixture(scope='module')
def small(tmp_path_factory) -> bytes:
    """The MCAP bytes of the small bag (BagWriter: 8 KiB chunks, chunk + data + summary CRCs)."""
    folder = tmp_path_factory.mktemp('hostile') / 'bag'
    writer = BagWriter(folder, chunk_size=8192, metadata={'scenario': read_metadata(SOURCE)['scenario']})
    for topic, type_name, t, data in read_raw(SOURCE):
        if t <= SECONDS * 1_000_000_000:
            writer.add_topic(topic, type_name, [])
            writer.write(topic, data, t)
    writer.close()
    return (folder / 'bag_0.mcap').read_bytes()


@pytest.fixture(scope='module')
def full_metrics(small, tmp_path_factory) -> dict:
    code, metrics, err = analyze(write_bag(tmp_path_factory.mktemp('intact'), small))
    assert code == 0 and err == [], err
    return metrics


def write_bag(folder: Path, data: bytes, name: str = 'bag') -> Path:
    bag = folder / name
    bag.mkdir(parents=True, exist_ok=True)
    (bag / 'bag_0.mcap').write_bytes(data)
    return bag


def analyze(bag: Path) -> tuple[int, dict | None, list[str]]:
    """(exit status, metrics or None, stderr lines) of ``adcs-analyze <bag> --json --no-report``."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = analyze_main([str(bag), '--json', '--no-report'])
    metrics = json.loads(out.getvalue()).get(str(bag)) if out.getvalue().strip() else None
    return code, metrics, err.getvalue().splitlines()


def repair(bag: Path) -> tuple[int, list[str], list[str]]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = repair_main([str(bag)])
    return code, out.getvalue().splitlines(), err.getvalue().splitlines()


def library_messages(data: bytes) -> int:
    """Messages the mcap library's own streaming reader (CRCs validated) yields before it stops."""
    n = 0
    try:
        for record in StreamReader(io.BytesIO(data), validate_crcs=True, record_size_limit=len(data)).records:
            n += isinstance(record, Message)
    except (McapError, EOFError, struct.error, ValueError, KeyError, RuntimeError):
        pass
    return n


def record_offsets(data: bytes) -> list[int]:
    """Start of every top-level record of an intact file, then the file's end (footer included)."""
    pos, out = 8, []
    while pos < len(data) - 8:
        out.append(pos)
        pos += 9 + struct.unpack_from('<Q', data, pos + 1)[0]
    return out + [len(data)]


def check_outcome(tmp: Path, damaged: bytes, original: bytes, full: dict) -> str:
    """The contract for any damaged file; returns 'refused', 'prefix' or 'summary'."""
    bag = write_bag(tmp, damaged, 'damaged')
    code, metrics, err = analyze(bag)
    assert len(err) == 1, err                                  # always said, in one line
    if code != 0:
        assert code == 1 and metrics is None and err[0].startswith(f'adcs-analyze: {bag}: ')
        return 'refused'
    assert 'warning' in err[0] and metrics is not None
    if 'summary damaged' in err[0]:                            # data section intact: the full metrics
        assert metrics == full
        return 'summary'
    cut = int(re.search(r'at byte (\d+)', err[0]).group(1))
    assert damaged[:cut] == original[:cut]                      # what was analysed is undamaged
    n = int(re.search(r'analysed the (\d+) messages', err[0]).group(1))
    assert n == library_messages(original[:cut])               # the intact prefix, by the mcap library
    prefix_code, prefix_metrics, _ = analyze(write_bag(tmp, original[:cut], 'prefix'))
    assert prefix_code == 0 and metrics == prefix_metrics
    return 'prefix'


def check_repair(tmp: Path, damaged: bytes) -> None:
    """Repair keeps exactly the messages the reader salvages, or refuses and touches nothing."""
    bag = write_bag(tmp, damaged, 'to_repair')
    salvage = []
    try:
        salvage.extend(m[:3] for m in read_raw(bag))
    except ValueError:
        pass
    code, out, err = repair(bag)
    if code != 0:
        assert code == 1 and len(err) == 1 and out == []
        assert (bag / 'bag_0.mcap').read_bytes() == damaged and not (bag / 'metadata.yaml').exists()
        return
    assert len(out) == 1 and err == []
    assert f'kept {len(salvage)} messages' in out[0] and 'repaired' in out[0]
    assert is_complete(bag) and [m[:3] for m in read_raw(bag)] == salvage


# --- the intact bag ---------------------------------------------------------------------------

def test_intact_bag_is_complete_and_left_alone(small, tmp_path):
    bag = write_bag(tmp_path, small)
    code, out, err = repair(bag)                         # no metadata.yaml yet: written, nothing lost
    assert code == 0 and 'metadata.yaml missing' in out[0]
    n = library_messages(small)
    assert f'kept {n} messages' in out[0] and is_complete(bag)
    code, out, err = repair(bag)
    assert code == 0 and out == [f'{bag}: complete, nothing to repair ({n} messages)']
    with open(bag / 'bag_0.mcap', 'rb') as f:            # every CRC of the file is set
        summary = make_reader(f).get_summary()
    assert all(c.uncompressed_size for c in summary.chunk_indexes)
    assert struct.unpack_from('<I', small, len(small) - 8 - 4)[0] != 0          # summary CRC
    assert struct.unpack_from('<I', small, record_offsets(small)[-3] + 9)[0] != 0  # data-section CRC


# --- truncation -------------------------------------------------------------------------------

def test_truncation_at_every_record_boundary(small, full_metrics, tmp_path):
    offsets = record_offsets(small)
    assert len(offsets) > 30
    outcomes = [check_outcome(tmp_path, small[:cut], small, full_metrics) for cut in offsets[:-1]]
    assert outcomes[0] == 'refused' and outcomes[-1] == 'summary' and 'prefix' in outcomes


@FUZZ
@given(fraction=st.floats(0.0, 1.0, exclude_max=True))
def test_truncation_anywhere(small, full_metrics, tmp_path_factory, fraction):
    cut = small[:int(len(small) * fraction)]
    tmp = tmp_path_factory.mktemp('cut')
    check_outcome(tmp, cut, small, full_metrics)
    check_repair(tmp, cut)


# --- bit flips and corrupted fields -----------------------------------------------------------

@FLIPS
@given(data=st.data())
def test_single_bit_flip_anywhere_is_detected(small, full_metrics, tmp_path_factory, data):
    offset = data.draw(st.integers(0, len(small) - 1), label='offset')
    bit = data.draw(st.integers(0, 7), label='bit')
    damaged = bytearray(small)
    damaged[offset] ^= 1 << bit
    tmp = tmp_path_factory.mktemp('flip')
    # Every byte of a closed BagWriter file is under a CRC: a flip is never silent.
    assert check_outcome(tmp, bytes(damaged), small, full_metrics) in ('refused', 'prefix', 'summary')
    check_repair(tmp, bytes(damaged))


def chunk_spans(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of the chunk records, from the file's summary (the mcap library's reader)."""
    summary = make_reader(io.BytesIO(data)).get_summary()
    return [(c.chunk_start_offset, c.chunk_start_offset + c.chunk_length) for c in summary.chunk_indexes]


def test_flip_inside_a_zstd_chunk_is_found_at_that_chunk(small, full_metrics, tmp_path):
    start, end = chunk_spans(small)[2]
    damaged = bytearray(small)
    damaged[end - 20] ^= 0x10                       # in the compressed records of the third chunk
    assert check_outcome(tmp_path, bytes(damaged), small, full_metrics) == 'prefix'
    code, _, err = analyze(write_bag(tmp_path, bytes(damaged), 'again'))
    assert f'damaged at byte {start}: zstd chunk does not decompress' in err[0]
    with pytest.raises(zstandard.ZstdError):        # the mcap library agrees
        list(StreamReader(io.BytesIO(bytes(damaged)), validate_crcs=True).records)
    check_repair(tmp_path, bytes(damaged))


def test_chunk_crc_mismatch(small, full_metrics, tmp_path):
    """A chunk whose records differ from its CRC: the stored CRC corrupted (our writer's zstd
    bag), and a flipped bit in the records of an uncompressed chunk (the mcap library's writer)."""
    start, _ = chunk_spans(small)[1]
    damaged = bytearray(small)
    damaged[start + 9 + 24] ^= 0x01                 # uncompressed_crc of the second chunk
    assert check_outcome(tmp_path / 'crc', bytes(damaged), small, full_metrics) == 'prefix'
    assert f'damaged at byte {start}: chunk CRC mismatch' in analyze(tmp_path / 'crc' / 'damaged')[2][0]

    plain = io.BytesIO()
    writer = Writer(plain, chunk_size=8192, compression=CompressionType.NONE, enable_data_crcs=True)
    writer.start(profile='ros2', library='test')
    schemas, channels = {}, {}
    for record in StreamReader(io.BytesIO(small)).records:      # (the summary repeats schemas, channels)
        if isinstance(record, Schema) and record.id not in schemas:
            schemas[record.id] = writer.register_schema(record.name, record.encoding, record.data)
        elif isinstance(record, Channel) and record.id not in channels:
            channels[record.id] = writer.register_channel(record.topic, record.message_encoding,
                                                          schemas[record.schema_id], record.metadata)
        elif isinstance(record, Metadata) and record.name == 'scenario':
            writer.add_metadata(record.name, record.metadata)
        elif isinstance(record, Message):
            writer.add_message(channels[record.channel_id], record.log_time, record.data, record.publish_time,
                               record.sequence)
    writer.finish()
    plain = plain.getvalue()
    assert analyze(write_bag(tmp_path / 'plain', plain))[1] == full_metrics
    start, end = chunk_spans(plain)[2]
    damaged = bytearray(plain)
    damaged[end - 3] ^= 0x08                        # a float of the last message of the third chunk
    assert check_outcome(tmp_path / 'plain', bytes(damaged), plain, full_metrics) == 'prefix'
    assert f'damaged at byte {start}: chunk CRC mismatch' in analyze(tmp_path / 'plain' / 'damaged')[2][0]
    with pytest.raises(CRCValidationError):         # the mcap library agrees
        list(StreamReader(io.BytesIO(bytes(damaged)), validate_crcs=True).records)
    check_repair(tmp_path / 'plain', bytes(damaged))


def test_committed_bag_chunk_flips_are_detected(tmp_path):
    """A bag of an older writer (no data-section CRC): a flip inside any chunk still never
    changes the numbers silently (chunk CRC)."""
    original = next(SOURCE.glob('*.mcap')).read_bytes()
    full = analyze(SOURCE)[1]
    outcomes = []
    for i, (start, end) in enumerate(chunk_spans(original)[::7]):
        damaged = bytearray(original)
        damaged[(start + end) // 2] ^= 0x04
        outcomes.append(check_outcome(tmp_path / str(i), bytes(damaged), original, full))
        assert f'damaged at byte {start}' in analyze(tmp_path / str(i) / 'damaged')[2][0]
    assert outcomes[0] == 'refused' and set(outcomes[1:]) == {'prefix'}   # the first chunk holds the first state


def test_corrupted_length_fields_never_allocate(small, full_metrics, tmp_path):
    """Huge record lengths and a chunk claiming 2**40 uncompressed bytes: a clean outcome, fast."""
    start, _ = chunk_spans(small)[1]
    cases = {}
    for name, at, value in (('record', start + 1, 2**62), ('record_small', start + 1, 2**33),
                            ('chunk_size', start + 9 + 16, 2**40), ('chunk_size_limit', start + 9 + 16,
                                                                   MAX_CHUNK_BYTES + 1)):
        damaged = bytearray(small)
        struct.pack_into('<Q', damaged, at, value)
        cases[name] = check_outcome(tmp_path / name, bytes(damaged), small, full_metrics)
        code, _, err = analyze(write_bag(tmp_path / name, bytes(damaged), 'again'))
        assert f'damaged at byte {start}' in err[0], err
        check_repair(tmp_path / name, bytes(damaged))
    assert set(cases.values()) == {'prefix'}


# --- not bags at all --------------------------------------------------------------------------

@pytest.mark.parametrize('content', [b'', b'\x89MCAP0\r\n', bytes(range(256)) * 40, b'\x89MCAP0\r\n' + bytes(9)])
def test_empty_and_random_files_are_one_line_errors(tmp_path, content):
    bag = write_bag(tmp_path, content)
    code, metrics, err = analyze(bag)
    assert code == 1 and metrics is None and len(err) == 1 and err[0].startswith(f'adcs-analyze: {bag}: ')
    code, out, err = repair(bag)
    assert code == 1 and out == [] and len(err) == 1
    assert (bag / 'bag_0.mcap').read_bytes() == content


@FUZZ
@given(noise=st.binary(min_size=0, max_size=4096), magic=st.booleans())
def test_random_bytes(tmp_path_factory, noise, magic):
    bag = write_bag(tmp_path_factory.mktemp('noise'), (b'\x89MCAP0\r\n' if magic else b'') + noise)
    code, metrics, err = analyze(bag)
    assert code == 1 and metrics is None and len(err) == 1


@pytest.mark.parametrize('meta', [None, '', 'rosbag2_bagfile_information: [1, 2\n', '\x00\xff garbage',
                                  'rosbag2_bagfile_information: {relative_file_paths: [../../etc/passwd]}\n'])
def test_missing_or_garbage_metadata_yaml(small, full_metrics, tmp_path, meta):
    bag = write_bag(tmp_path, small)
    if meta is not None:
        (bag / 'metadata.yaml').write_text(meta)
    code, metrics, err = analyze(bag)
    assert code == 0 and metrics == full_metrics and err == []     # the MCAP file is what counts
    code, out, _ = repair(bag)                                     # metadata.yaml rewritten, nothing lost
    assert code == 0 and 'repaired (metadata.yaml missing or unreadable)' in out[0] and is_complete(bag)
    assert analyze(bag)[1] == full_metrics


def test_metadata_yaml_alone_is_a_one_line_error(tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: 9, storage_identifier: mcap}\n')
    code, metrics, err = analyze(bag)
    assert code == 1 and metrics is None and len(err) == 1


def test_repair_is_truthful(small, tmp_path):
    """Nothing intact: exit 1, named, file untouched. A truncated bag: exactly the intact messages
    kept, the cut named. Repairing twice never overwrites the kept original."""
    first_chunk = chunk_spans(small)[0][0]
    for name, data in (('no_chunk', small[:first_chunk]), ('first_chunk_cut', small[:first_chunk + 100])):
        bag = write_bag(tmp_path / name, data)
        code, out, err = repair(bag)
        assert code == 1 and out == [] and len(err) == 1 and 'no intact message to salvage' in err[0]
        assert (bag / 'bag_0.mcap').read_bytes() == data and sorted(p.name for p in bag.iterdir()) == ['bag_0.mcap']
    cut = chunk_spans(small)[3][0] + 50
    bag = write_bag(tmp_path / 'cut', small[:cut])
    n = library_messages(small[:cut])
    code, out, err = repair(bag)
    assert code == 0 and err == [] and len(out) == 1
    assert f'truncated at byte {chunk_spans(small)[3][0]} of {cut}' in out[0] and f'kept {n} messages' in out[0]
    assert f'dropped the {cut - chunk_spans(small)[3][0]} bytes after it' in out[0]
    assert (bag / 'bag_0.mcap.truncated').read_bytes() == small[:cut] and is_complete(bag)
    out2 = io.StringIO()
    with contextlib.redirect_stdout(out2):
        assert repair_main([str(bag), '--force']) == 0
    assert (bag / 'bag_0.mcap.truncated').read_bytes() == small[:cut]       # the first original, kept
    assert (bag / 'bag_0.mcap.original').is_file() and f'kept {n} messages' in out2.getvalue()
