"""Reading an MCAP file as far as it is intact.

A recording can end anywhere (a killed daemon, a full disk) and can be damaged anywhere (a
flipped bit on a card, a copy cut short). The ``mcap`` library's readers stop at the first bad
byte (an ``LZ4F_decompress`` error, a bad length) or need the summary at the end that a killed
file lacks. :func:`read_records` walks the data section record by record instead: a chunk whose
contents fail (decompression, CRC, a record inside) is skipped and counted; a record whose
framing is broken (a flipped length) is skipped by searching on for the next record that checks
out (a chunk or attachment whose CRC matches, a metadata record whose lengths add up), and the
bytes jumped over are counted. The channels and schemas of the summary, when the file has one,
come first, so messages whose channel record sat in a damaged chunk still have their topic.
"""

from __future__ import annotations

import mmap
import os
import re
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    McapRecord,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import breakup_chunk

MAGIC = b"\x89MCAP0\r\n"
_PREFIX = 9  # opcode (1 byte) and record length (8 bytes)
_FOOTER = _PREFIX + 20  # the footer record: summary start, summary offset start, summary crc
_NAME_LIMIT = 1 << 16  # longer names or media types mean a damaged record
_CHUNK_LIMIT = 1 << 30  # a larger uncompressed chunk means a damaged header
_COMPRESSIONS = {b"", b"lz4", b"zstd"}
_OPCODES = {int(op) for op in Opcode}  # an unknown one is taken for damage: it is searched past
# Records worth resuming at after broken framing: each can be checked on its own.
_RESUME = re.compile(
    b"[" + bytes([Opcode.CHUNK, Opcode.ATTACHMENT, Opcode.METADATA, Opcode.DATA_END]) + b"]"
)
_READ = {
    Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.CHUNK: Chunk.read,
    Opcode.METADATA: Metadata.read,
    Opcode.ATTACHMENT: Attachment.read,
    Opcode.DATA_END: DataEnd.read,
    Opcode.FOOTER: Footer.read,
}


class NotMcapError(Exception):
    """The file does not start as an MCAP file does (empty, text, anything else)."""


@dataclass
class Damage:
    """What :func:`read_records` found wrong: ``chunks`` skipped because their contents were
    damaged, ``records`` skipped because their framing was, the ``bytes`` jumped over to find
    the next good record, whether the file ends early (``truncated``: no end of data), and
    ``messages`` its readers could not use."""

    chunks: int = 0
    records: int = 0
    bytes: int = 0
    truncated: bool = False
    messages: int = 0  # for readers: messages they could not use (channel lost, bad content)

    @property
    def any(self) -> bool:
        return bool(self.chunks or self.records or self.messages)


def read_records(path: str | Path, damage: Damage | None = None) -> Iterator[McapRecord]:
    """The schema, channel, message, metadata and attachment records of ``path`` in file order
    (a chunk's records in place of the chunk), skipping what is damaged; ``damage`` (if given)
    counts what was skipped. Raises :class:`NotMcapError` when the file is not MCAP at all."""
    damage = damage if damage is not None else Damage()
    with open(path, "rb") as fh:
        size = os.fstat(fh.fileno()).st_size
        if size < len(MAGIC) or fh.read(len(MAGIC)) != MAGIC:
            raise NotMcapError(f"{path}: not an MCAP recording (it does not start as one)")
        if size < len(MAGIC) + _PREFIX:
            damage.truncated = True
            return
        with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as data:
            yield from _summary_channels(data)
            yield from _data_section(data, damage)


def _data_section(data: mmap.mmap, damage: Damage) -> Iterator[McapRecord]:
    pos, size = len(MAGIC), len(data)
    while pos < size:
        found = _record_at(data, pos)
        if found is None:
            resume = _resume(data, pos + 1)
            if resume is None:  # nothing intact follows: the file was cut off here
                if not _cut_off(data, pos):
                    damage.records += 1
                damage.truncated = True
                return
            damage.records += 1
            damage.bytes += resume - pos
            pos = resume
            continue
        record, pos = found
        if isinstance(record, DataEnd | Footer):
            return  # the summary follows: indexes and repeats of what was read
        if isinstance(record, Chunk):
            try:
                inner = breakup_chunk(record, validate_crc=True)
            except Exception:  # whatever a damaged chunk raises, it is skipped
                damage.chunks += 1
                continue
            yield from inner
        elif record is not None:
            yield record
    damage.truncated = True


def _record_at(data: mmap.mmap, pos: int) -> tuple[McapRecord | None, int] | None:
    """The record starting at ``pos`` and where the next one starts; None when its framing does
    not check out. Records the reader does not use come back as None (skipped by length)."""
    size = len(data)
    if pos + _PREFIX > size:
        return None
    opcode, length = struct.unpack_from("<BQ", data, pos)
    end = pos + _PREFIX + length
    if end > size or opcode not in _OPCODES or not _plausible(data, pos):
        return None
    read = _READ.get(Opcode(opcode))
    if read is None and opcode != Opcode.MESSAGE:
        return None, end
    body = data[pos + _PREFIX : end]
    stream = ReadDataStream(BytesIO(body))
    try:
        record = Message.read(stream, length) if read is None else read(stream)
    except Exception:  # a field that does not parse is damage
        return None
    if stream.count != length and not isinstance(record, DataEnd | Footer):
        return None  # its fields do not add up to its length
    if isinstance(record, Attachment) and zlib.crc32(body[:-4]) != _u32(body, length - 4):
        return None
    return record, end


def _plausible(data: mmap.mmap, pos: int) -> bool:
    """Cheap checks of a record's fields before it is copied and parsed: the lengths inside
    add up to the record's length (a random byte that looks like an opcode rarely passes)."""
    opcode, length = struct.unpack_from("<BQ", data, pos)
    body = pos + _PREFIX
    try:
        if opcode == Opcode.CHUNK:
            usize = struct.unpack_from("<Q", data, body + 16)[0]
            n = _u32(data, body + 28)
            if n > 4 or data[body + 32 : body + 32 + n] not in _COMPRESSIONS:
                return False
            records = struct.unpack_from("<Q", data, body + 32 + n)[0]
            return usize <= _CHUNK_LIMIT and records == length - (40 + n)
        if opcode == Opcode.ATTACHMENT:
            name = _u32(data, body + 16)
            if name > _NAME_LIMIT:
                return False
            media = _u32(data, body + 20 + name)
            if media > _NAME_LIMIT:
                return False
            size = struct.unpack_from("<Q", data, body + 24 + name + media)[0]
            return size == length - (36 + name + media)
        if opcode == Opcode.METADATA:
            name = _u32(data, body)
            return name <= _NAME_LIMIT and _u32(data, body + 4 + name) == length - (8 + name)
        if opcode == Opcode.DATA_END:
            return length == 4
    except struct.error:  # a field beyond the end of the file
        return False
    return True


def _resume(data: mmap.mmap, start: int) -> int | None:
    """Where the next record that checks out starts, searching from ``start``."""
    for match in _RESUME.finditer(data, start):
        pos = match.start()
        found = _record_at(data, pos)
        if found is None:
            continue
        record = found[0]
        if isinstance(record, Chunk):
            try:
                breakup_chunk(record, validate_crc=True)
            except Exception:  # not a chunk after all, or a damaged one
                continue
        return pos
    return None


def _cut_off(data: mmap.mmap, pos: int) -> bool:
    """Whether the record at ``pos`` is a known one that runs past the end of the file (what
    a killed writer leaves), rather than damage."""
    if pos + _PREFIX > len(data):
        return True
    opcode, length = struct.unpack_from("<BQ", data, pos)
    return opcode in _OPCODES and pos + _PREFIX + length > len(data)


def _summary_channels(data: mmap.mmap) -> Iterator[McapRecord]:
    """The schemas and channels repeated in the summary (none when the file has no footer)."""
    size = len(data)
    footer_at = size - len(MAGIC) - _FOOTER
    if footer_at < len(MAGIC) or data[size - len(MAGIC) :] != MAGIC:
        return
    found = _record_at(data, footer_at)
    if found is None or not isinstance(found[0], Footer):
        return
    footer = found[0]
    pos = footer.summary_start
    checked = data[pos : footer_at + _PREFIX + 16]  # the summary and the footer up to its CRC
    if not 0 < pos < footer_at or (
        footer.summary_crc and zlib.crc32(checked) != footer.summary_crc
    ):
        return  # a damaged summary: the data section has the channels too
    while 0 < pos < footer_at:
        found = _record_at(data, pos)
        if found is None:
            return
        record, pos = found
        if isinstance(record, Schema | Channel):
            yield record


def _u32(data: bytes | mmap.mmap, pos: int) -> int:
    return struct.unpack_from("<I", data, pos)[0]
