"""What crosses the radio: message types, the msgpack codec (CRC, schema check), the radio's
settings and link models (disk or log-distance), the radio graph, bounded mailboxes, and the root
error :class:`SwarmError`.

The bottom of the import graph: ``comms`` imports nothing else of ours.
"""

from comms.codec import AuthError, Frame, FrameError, decode, encode
from comms.errors import SwarmError
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox, MailboxStats
from comms.messages import Hello, Intent, ScanDigest, ScanRecords, ThreatItem, Threats, TrackDigest, TrackItem, Tracks
from comms.radio import Delivery, LinkFilter, Radio, RadioCounters
from comms.settings import LinkModel, LogDistance, RadioSettings

__all__ = [
    "AuthError",
    "DecodeCache",
    "Delivery",
    "Frame",
    "FrameError",
    "Hello",
    "Intent",
    "LinkFilter",
    "LinkModel",
    "LogDistance",
    "Mailbox",
    "MailboxStats",
    "Radio",
    "RadioCounters",
    "RadioSettings",
    "ScanDigest",
    "ScanRecords",
    "SwarmError",
    "ThreatItem",
    "Threats",
    "TrackDigest",
    "TrackItem",
    "Tracks",
    "decode",
    "encode",
]
