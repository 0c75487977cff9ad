"""rmw_zenoh's names on the wire: data key expressions, graph liveliness tokens, attachments.

Follows rmw_zenoh 0.2 (the ``jazzy`` branch, as of 2025; ``docs/design.md`` and
``rmw_zenoh_cpp/src/detail/liveliness_utils.cpp``, ``attachment_helpers.cpp``):

- a topic's samples go on ``<domain_id>/<topic without leading />/<type>/<type hash>``, with the
  DDS-mangled type name (``tf2_msgs::msg::dds_::TFMessage_``) and its ``RIHS01_<sha256>`` hash;
- each node and publisher holds a liveliness token
  ``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<NN|MP>/<enclave>/<namespace>/<node>``
  (a publisher's followed by ``/<topic>/<type>/<hash>/<qos>``), every ``/`` inside a name
  written ``%`` so that each field is one key chunk;
- each sample carries an attachment: its sequence number and source timestamp (int64, ns), and
  the publisher's 16-byte GID, in zenoh-ext's serialisation.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

from zenoh.ext import Int64, z_serialize

ADMIN_SPACE = "@ros2_lv"
#: rmw_zenoh writes QoS as differences from its default (reliable, volatile, keep last 10):
#: this is a publisher with the default QoS.
DEFAULT_QOS = "::,:,:,:,,"
GID_SIZE = 16


def mangle(name: str) -> str:
    """A ROS name as one key chunk: ``/`` written ``%`` (rmw_zenoh's ``mangle_name``)."""
    return name.replace("/", "%")


def dds_type(ros_type: str) -> str:
    """``tf2_msgs/msg/TFMessage`` as rmw_zenoh names it on the wire:
    ``tf2_msgs::msg::dds_::TFMessage_``."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def full_topic(namespace: str, topic: str) -> str:
    """The fully qualified name of ``topic`` in ``namespace`` (``/tf`` stays absolute)."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


def topic_key(domain_id: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The key expression a topic's samples go on (``topic`` fully qualified)."""
    return f"{domain_id}/{topic.strip('/')}/{dds_type(ros_type)}/{type_hash}"


@dataclass(frozen=True)
class Node:
    """A ROS 2 node as the graph sees it: domain, Zenoh session id, node id, namespace, name."""

    domain_id: int
    zid: str
    namespace: str
    name: str
    node_id: int = 0
    enclave: str = "/"

    def _head(self, entity_id: int, kind: str) -> str:
        return "/".join(
            (
                ADMIN_SPACE,
                str(self.domain_id),
                self.zid,
                str(self.node_id),
                str(entity_id),
                kind,
                mangle(self.enclave),
                mangle(self.namespace),
                mangle(self.name),
            )
        )

    def token(self) -> str:
        """The node's liveliness token (``NN``)."""
        return self._head(self.node_id, "NN")

    def publisher_token(
        self, entity_id: int, topic: str, ros_type: str, type_hash: str, qos: str = DEFAULT_QOS
    ) -> str:
        """A publisher's liveliness token (``MP``); ``topic`` fully qualified."""
        tail = "/".join((mangle(topic), mangle(dds_type(ros_type)), type_hash, qos))
        return f"{self._head(entity_id, 'MP')}/{tail}"


def gid(token: str) -> bytes:
    """A publisher's 16-byte GID, a hash of its liveliness token. (rmw_zenoh hashes the token
    with XXH3-128; a subscriber uses the GID as an opaque identity, so BLAKE2b of the same
    token serves, and needs no extra package.)"""
    return hashlib.blake2b(token.encode(), digest_size=GID_SIZE).digest()


def attachment(sequence_number: int, source_timestamp_ns: int, source_gid: bytes) -> bytes:
    """A sample's attachment as rmw_zenoh reads it: int64 sequence number, int64 source
    timestamp (ns since the epoch), then the GID as a sequence of 16 bytes."""
    if len(source_gid) != GID_SIZE:
        raise ValueError(f"a GID has {GID_SIZE} bytes, got {len(source_gid)}")
    payload = z_serialize((Int64(sequence_number), Int64(source_timestamp_ns), source_gid))
    return payload.to_bytes()
