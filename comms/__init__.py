"""What crosses the radio: message types, the msgpack codec (CRC, schema check), the radio
graph with its link model (disk or log-distance), bounded mailboxes, and the root error :class:`SwarmError`.

The bottom of the import graph: ``comms`` imports nothing else of ours.
"""

from comms.codec import AuthError, Frame, FrameError, decode, encode
from comms.errors import SwarmError
from comms.framecache import DecodeCache
from comms.mailbox import Mailbox, MailboxStats
from comms.messages import Hello, Intent, ScanDigest, ScanRecords, ThreatItem, Threats, TrackItem, Tracks
from comms.radio import Delivery, LinkFilter, LinkModel, LogDistance, Radio, RadioCounters

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
    "ScanDigest",
    "ScanRecords",
    "SwarmError",
    "ThreatItem",
    "Threats",
    "TrackItem",
    "Tracks",
    "decode",
    "encode",
]
