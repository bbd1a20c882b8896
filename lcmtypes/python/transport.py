"""Receive clutterseg's LCM messages in Python without the lcm module.

Debian 12 ships no python3-lcm. The messages the lcm-gen'd classes of this package decode
travel either over UDP multicast (LCM's udpm provider) or in LCM log files (the file://
provider, lcm-logger); this module reads both with the standard library only:

    from clutterseg import objects_t
    from clutterseg.transport import Subscriber, read_log

    with Subscriber() as sub:                       # LCM_DEFAULT_URL, else LCM's default
        for channel, data in sub.messages(timeout_s=5.0):
            if channel == "CLUTTERSEG_OBJECTS":
                print(objects_t.decode(data).num_objects)

    for event in read_log("/var/lib/clutterseg/run.lcmlog"):
        ...                                         # event.channel, event.utime, event.data

Subscriber implements LCM's udpm wire format (LCM 1.x, big-endian): short messages
("LC02" magic, sequence number, channel, payload) and fragmented ones ("LC03": sequence
number, message size, fragment offset, fragment number, fragment count, the channel in
fragment 0). It receives only; publish with the C++ or Java library.
"""

import os
import socket
import struct
import time
import urllib.parse

__all__ = ["Subscriber", "LogEvent", "read_log", "parse_udpm_url", "DEFAULT_URL"]

DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0"
_MAGIC_SHORT = 0x4C433032  # "LC02"
_MAGIC_LONG = 0x4C433033  # "LC03"
_LOG_SYNC = 0xEDA1DA01
_MAX_MESSAGE = 64 * 1024 * 1024  # messages beyond this are refused, never buffered


def parse_udpm_url(url=None):
    """(group, port, options) of a udpm:// URL; None or "" means LCM_DEFAULT_URL or LCM's
    default. Raises ValueError for other providers or a malformed URL."""
    url = url or os.environ.get("LCM_DEFAULT_URL") or DEFAULT_URL
    parsed = urllib.parse.urlsplit(url)
    if parsed.scheme != "udpm":
        raise ValueError("clutterseg.transport receives udpm:// only (got %r); read file:// "
                         "logs with read_log()" % url)
    host, _, port = parsed.netloc.partition(":")
    group = host or "239.255.76.67"
    port = int(port) if port else 7667
    options = dict(urllib.parse.parse_qsl(parsed.query))
    return group, port, options


class Subscriber:
    """A udpm receiver: joins the multicast group and yields (channel, payload) pairs.

    `channels` (an iterable of names) filters by exact channel name; None takes every
    channel. `recv_buf_size` (bytes, also read from the URL) sizes the kernel receive
    buffer: label images are fragmented, and a small buffer loses them (the kernel caps it at
    net.core.rmem_max). Not thread-safe: use one Subscriber per thread.
    """

    def __init__(self, url=None, channels=None, recv_buf_size=None):
        group, port, options = parse_udpm_url(url)
        self.group, self.port = group, port
        self.channels = set(channels) if channels is not None else None
        self.fragments_lost = 0  # messages whose fragments did not all arrive
        self._partial = {}  # (sender, seqno) -> [size, received bytes, buffer, channel]
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if hasattr(socket, "SO_REUSEPORT"):
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        size = recv_buf_size or int(options.get("recv_buf_size", 4 * 1024 * 1024))
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
        self._sock.bind(("", port))
        mreq = struct.pack("4s4s", socket.inet_aton(group), socket.inet_aton("0.0.0.0"))
        self._sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)

    def close(self):
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def receive(self, timeout_s=None):
        """The next complete message as (channel, payload bytes), or None when `timeout_s`
        (None = wait forever) passes first."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
            self._sock.settimeout(remaining)
            try:
                packet, sender = self._sock.recvfrom(65536)
            except socket.timeout:
                return None
            message = self._parse(packet, sender)
            if message is not None and (self.channels is None or message[0] in self.channels):
                return message
            if deadline is not None and time.monotonic() >= deadline:
                return None

    def messages(self, timeout_s=None):
        """Yields messages until `timeout_s` passes without one."""
        while True:
            message = self.receive(timeout_s)
            if message is None:
                return
            yield message

    def _parse(self, packet, sender):
        if len(packet) < 8:
            return None
        magic, seqno = struct.unpack_from(">II", packet, 0)
        if magic == _MAGIC_SHORT:
            end = packet.find(b"\0", 8)
            if end < 0:
                return None
            return packet[8:end].decode("utf-8", "replace"), bytes(packet[end + 1:])
        if magic != _MAGIC_LONG or len(packet) < 20:
            return None
        size, offset, number, count = struct.unpack_from(">IIHH", packet, 8)
        if size > _MAX_MESSAGE or count == 0 or number >= count:
            return None
        key = (sender, seqno)
        body = 20
        if number == 0:
            end = packet.find(b"\0", 20)
            if end < 0:
                return None
            channel = packet[20:end].decode("utf-8", "replace")
            body = end + 1
            # A new first fragment ends whatever this sender left unfinished.
            for stale in [k for k in self._partial if k[0] == sender and k != key]:
                del self._partial[stale]
                self.fragments_lost += 1
            self._partial[key] = [size, 0, bytearray(size), channel]
        entry = self._partial.get(key)
        if entry is None or entry[0] != size:
            return None
        chunk = packet[body:]
        if offset + len(chunk) > size:
            del self._partial[key]
            self.fragments_lost += 1
            return None
        entry[2][offset:offset + len(chunk)] = chunk
        entry[1] += len(chunk)
        if entry[1] < size:
            return None
        del self._partial[key]
        return entry[3], bytes(entry[2])


class LogEvent:
    """One event of an LCM log: its number, the time it was logged (microseconds), its
    channel and payload."""

    __slots__ = ("eventnum", "utime", "channel", "data")

    def __init__(self, eventnum, utime, channel, data):
        self.eventnum, self.utime, self.channel, self.data = eventnum, utime, channel, data


def read_log(path, channels=None):
    """Yields the LogEvents of an LCM log file (lcm-logger, or the daemon's file:// URL),
    optionally only those of `channels`. A torn event at the end (a log still being written,
    or cut by a crash) ends the iteration; a corrupt event in the middle raises ValueError."""
    wanted = set(channels) if channels is not None else None
    with open(path, "rb") as f:
        while True:
            header = f.read(28)
            if len(header) < 28:
                return
            sync, eventnum, utime, channel_len, data_len = struct.unpack(">IqqII", header)
            if sync != _LOG_SYNC:
                raise ValueError("%s: bad sync word at offset %d" % (path, f.tell() - 28))
            if channel_len > 4096 or data_len > _MAX_MESSAGE:
                raise ValueError("%s: implausible event sizes at offset %d" % (path, f.tell() - 28))
            channel = f.read(channel_len)
            data = f.read(data_len)
            if len(channel) < channel_len or len(data) < data_len:
                return
            name = channel.decode("utf-8", "replace")
            if wanted is None or name in wanted:
                yield LogEvent(eventnum, utime, name, data)
