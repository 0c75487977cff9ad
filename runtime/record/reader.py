"""Reading a recording back (:mod:`.telemetry` writes it): frames with their inputs, world
models, boxes and status, as far as the file is intact."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap_protobuf.decoder import DecoderFactory

from percept.runtime.net.codec import JSON
from percept.runtime.record.mcap_salvage import Damage, NotMcapError, read_records
from percept.runtime.record.topics import (
    TOPIC_BOXES,
    TOPIC_FRAME,
    TOPIC_IMAGE,
    TOPIC_RAW,
    TOPIC_STATUS,
    TOPIC_WORLD,
)

if TYPE_CHECKING:
    from google.protobuf.message import Message as ProtobufMessage

#: Decodes a recorded image's bytes into its Foxglove message (CompressedImage or RawImage).
Decoder: TypeAlias = "Callable[[bytes], ProtobufMessage]"

log = logging.getLogger("percept.recording")


class RecordedFrame:
    """One frame as recorded: the pipeline's inputs, and its image, decoded on first use."""

    def __init__(self, inputs: dict[str, JSON], decode: Decoder, data: bytes) -> None:
        self.inputs = inputs
        self._decode = decode
        self._data = data
        self._image: np.ndarray | None = None

    @property
    def image(self) -> np.ndarray:
        """The BGR image."""
        if self._image is None:
            message = self._decode(self._data)
            self.image_format = getattr(message, "format", None) or message.encoding
            self._image = _decode_image(message)
        return self._image

    image_format: str | None = None
    """``jpeg`` (lossy) or ``bgr8`` once :attr:`image` was decoded."""


@dataclass
class Recording:
    """What :func:`read_recording` found: the metadata, the background model, and what was
    damaged or missing (:class:`~percept.runtime.record.mcap_salvage.Damage`).

    ``truncated`` is true when the file ends early (the writer was killed); everything up to
    the last complete chunk was still read.
    """

    path: Path
    metadata: dict[str, str] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    damage: Damage = field(default_factory=Damage)

    @property
    def truncated(self) -> bool:
        return self.damage.truncated


class RecordingError(Exception):
    """A file that is not a readable percept recording."""


def read_recording(
    path: str | Path, recording: Recording | None = None
) -> Iterator[tuple[str, Any]]:  # Any: the item's type goes with its kind (see below)
    """Stream a recording in file order: ``("frame", RecordedFrame)`` for each processed frame,
    ``("world", dict)`` for each world model, and ``("boxes" | "status", dict)``.

    Reads as far as the file is intact (:mod:`percept.runtime.record.mcap_salvage`): a file without
    summary or footer (a killed writer) reads up to its last complete chunk, a damaged chunk is
    skipped and counted. ``recording`` (if given) collects the metadata and the attachments as they
    come, and ends up saying what was damaged. Raises :class:`RecordingError` for a file that
    is not MCAP.
    """
    rec = recording if recording is not None else Recording(Path(path))
    messages = _Messages(rec.damage)
    try:
        for record in read_records(path, rec.damage):
            if isinstance(record, Schema):
                messages.schemas[record.id] = record
            elif isinstance(record, Channel):
                messages.channels[record.id] = record
            elif isinstance(record, Metadata) and record.name == "percept":
                rec.metadata.update(record.metadata)
            elif isinstance(record, Attachment):
                rec.attachments[record.name] = bytes(record.data)
            elif isinstance(record, Message):
                yield from messages.read(record)
    except NotMcapError as err:
        raise RecordingError(str(err)) from None
    _log_damage(path, rec.damage)


_JSON_TOPICS = {TOPIC_WORLD: "world", TOPIC_BOXES: "boxes", TOPIC_STATUS: "status"}


class _Messages:
    """A recording's messages as they come: JSON ones as they are, and each frame once both its
    image and its inputs (logged at the same time) were read."""

    def __init__(self, damage: Damage) -> None:
        self.damage = damage
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self._decoders = DecoderFactory()
        self._images: dict[int, tuple[Decoder, bytes]] = {}
        self._inputs: dict[int, dict[str, JSON]] = {}

    def read(self, record: Message) -> Iterator[tuple[str, RecordedFrame | dict[str, JSON]]]:
        channel = self.channels.get(record.channel_id)
        if channel is None:  # its channel record was in a damaged chunk
            self.damage.messages += 1
            return
        topic, ns = channel.topic, record.log_time
        message: dict[str, JSON] | None = None
        try:
            if topic in (TOPIC_IMAGE, TOPIC_RAW):
                decode = self._decoders.decoder_for(
                    channel.message_encoding, self.schemas.get(channel.schema_id)
                )
                if decode is None:  # its schema record was in a damaged chunk
                    raise ValueError("no decoder")
                self._images[ns] = (decode, bytes(record.data))
            elif topic == TOPIC_FRAME:
                self._inputs[ns] = json.loads(record.data)
            elif topic in _JSON_TOPICS:
                message = json.loads(record.data)
        except (ValueError, TypeError):  # a damaged message or schema a CRC missed
            self.damage.messages += 1
            return
        if message is not None:
            yield _JSON_TOPICS[topic], message
        if ns in self._images and ns in self._inputs:
            yield "frame", RecordedFrame(self._inputs.pop(ns), *self._images.pop(ns))


def _log_damage(path: str | Path, damage: Damage) -> None:
    if damage.any:
        log.warning(
            "%s is damaged: skipped %d chunks, %d records (%d bytes), %d messages; read the rest",
            path,
            damage.chunks,
            damage.records,
            damage.bytes,
            damage.messages,
        )
    if damage.truncated:
        log.info("%s ends early: read to the last complete chunk", path)


def _decode_image(msg: ProtobufMessage) -> np.ndarray:
    """A decoded CompressedImage or RawImage (bgr8) as a BGR array."""
    import cv2

    if hasattr(msg, "format"):
        image = cv2.imdecode(np.frombuffer(msg.data, np.uint8), cv2.IMREAD_COLOR)
        if image is None:
            raise RecordingError(f"cannot decode a {msg.format} image")
        return image
    if msg.encoding != "bgr8":
        raise RecordingError(f"raw image encoding {msg.encoding!r} is not bgr8")
    rows = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)
    return rows[:, : msg.width * 3].reshape(msg.height, msg.width, 3).copy()
