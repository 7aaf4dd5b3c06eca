"""ASTERIX inside classic libpcap captures (issue 11 item 1: ``skytrack track FILE.pcap``).

A capture of a surveillance feed holds UDP datagrams whose payloads are ASTERIX data
blocks.  :func:`udp_payloads` parses the classic libpcap format (magic ``a1b2c3d4``
microseconds or ``a1b23c4d`` nanoseconds, either byte order; not pcapng) with its link
layer (Ethernet with up to two VLAN tags, Linux cooked capture, BSD loopback, raw IP), the
IPv4 header (its IHL) and the UDP header, and joins the payloads into one byte string,
which decodes like a ``.ast`` file (a raw dump of UDP payloads is already that).

The one sequential part, finding each packet header (packet k+1 starts after packet k's
captured length), is a compiled loop; the headers are then read with numpy over all
packets at once.  Packets that are not IPv4/UDP, IP fragments and packets cut short by the
capture's snap length are not decoded: they are counted by reason with the byte offset of
the first one (:class:`PcapPayloads`), never dropped silently.  ``file_offset`` maps a byte
offset in the joined payloads back to the capture file, so decoding problems name a byte of
the ``.pcap`` file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

GLOBAL_HEADER_BYTES = 24
PACKET_HEADER_BYTES = 16
LINK_NULL, LINK_ETHERNET, LINK_RAW, LINK_RAW_OTHER, LINK_LINUX_SLL = 0, 1, 101, 12, 113
_ETHERTYPE_IPV4, _ETHERTYPE_VLAN, _ETHERTYPE_QINQ = 0x0800, 0x8100, 0x88A8
_UDP = 17


class PcapError(ValueError):
    """The file is not a classic libpcap capture skytrack can read (the message says why)."""


@dataclass
class PcapPayloads:
    """The UDP payloads of a capture joined in capture order, with where each came from."""

    data: bytes
    payload_start: np.ndarray  # offset of each payload in ``data``
    file_start: np.ndarray  # offset of the same byte in the capture file
    packets: int = 0
    #: reason -> (count, byte offset of the first such packet's header in the file)
    skipped: dict[str, tuple[int, int]] = field(default_factory=dict)

    def file_offset(self, offset: int | np.ndarray) -> int | np.ndarray:
        """The capture-file offset of byte ``offset`` of ``data``."""
        k = np.clip(np.searchsorted(self.payload_start, offset, side="right") - 1, 0, None)
        if self.payload_start.size == 0:
            return offset
        result = self.file_start[k] + (np.asarray(offset) - self.payload_start[k])
        return int(result) if np.ndim(result) == 0 else result


@njit(cache=True)
def _packet_offsets(data, big_endian, starts, captured, original):
    """Packet header offsets, captured and original lengths; returns (packets, offset where the scan stopped)."""
    n = data.size
    p = GLOBAL_HEADER_BYTES
    count = 0
    while p + PACKET_HEADER_BYTES <= n:
        if big_endian:
            incl = (np.int64(data[p + 8]) << 24) | (np.int64(data[p + 9]) << 16) | (np.int64(data[p + 10]) << 8) | data[p + 11]
            orig = (np.int64(data[p + 12]) << 24) | (np.int64(data[p + 13]) << 16) | (np.int64(data[p + 14]) << 8) | data[p + 15]
        else:
            incl = (np.int64(data[p + 11]) << 24) | (np.int64(data[p + 10]) << 16) | (np.int64(data[p + 9]) << 8) | data[p + 8]
            orig = (np.int64(data[p + 15]) << 24) | (np.int64(data[p + 14]) << 16) | (np.int64(data[p + 13]) << 8) | data[p + 12]
        if p + PACKET_HEADER_BYTES + incl > n:
            return count, p
        starts[count], captured[count], original[count] = p, incl, orig
        count += 1
        p += PACKET_HEADER_BYTES + incl
    return count, p


def _be16(data: np.ndarray, at: np.ndarray) -> np.ndarray:
    return (data[at].astype(np.int64) << 8) | data[at + 1]


def udp_payloads(raw: bytes | np.ndarray) -> PcapPayloads:
    """The UDP payloads of a classic libpcap capture (module docstring); :class:`PcapError` when
    the global header is not libpcap's or the link type is not one listed there."""
    data = np.frombuffer(bytes(raw), np.uint8) if not isinstance(raw, np.ndarray) else raw
    if data.size < GLOBAL_HEADER_BYTES:
        raise PcapError(f"{data.size} bytes: too short for a libpcap global header ({GLOBAL_HEADER_BYTES} bytes)")
    magic = bytes(data[:4])
    if magic in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1"):
        big_endian = False
    elif magic in (b"\xa1\xb2\xc3\xd4", b"\xa1\xb2\x3c\x4d"):
        big_endian = True
    elif magic == b"\x0a\x0d\x0d\x0a":
        raise PcapError("a pcapng capture: save it as classic pcap (e.g. editcap -F pcap in.pcapng out.pcap)")
    else:
        raise PcapError(f"byte offset 0: magic {magic.hex()} is not libpcap's (a1b2c3d4 or a1b23c4d)")
    link = int.from_bytes(bytes(data[20:24]), "big" if big_endian else "little") & 0xFFFF
    if link not in (LINK_NULL, LINK_ETHERNET, LINK_RAW, LINK_RAW_OTHER, LINK_LINUX_SLL):
        raise PcapError(f"link type {link} is not Ethernet (1), raw IP (101, 12), Linux cooked (113) or loopback (0)")
    most = max((data.size - GLOBAL_HEADER_BYTES) // PACKET_HEADER_BYTES, 0)
    starts, captured, original = (np.empty(most, np.int64) for _ in range(3))
    count, stop = _packet_offsets(data, big_endian, starts, captured, original)
    starts, captured, original = starts[:count], captured[:count], original[:count]
    skipped: dict[str, tuple[int, int]] = {}

    def skip(reason: str, mask: np.ndarray) -> None:
        if mask.any():
            skipped[reason] = (int(mask.sum()), int(starts[np.flatnonzero(mask)[0]]))

    if stop < data.size:
        skipped["packet cut short by the end of the file"] = (1, int(stop))
    frame = starts + PACKET_HEADER_BYTES
    end = frame + captured
    usable = np.ones(count, bool)
    # link layer -> IP header offset and the protocol it announces
    if link == LINK_ETHERNET:
        ip, ethertype = frame + 14, np.where(frame + 14 <= end, _be16(data, np.minimum(frame + 12, data.size - 2)), -1)
        for _ in range(2):  # 802.1Q / 802.1ad tags
            tagged = np.isin(ethertype, [_ETHERTYPE_VLAN, _ETHERTYPE_QINQ]) & (ip + 4 <= end)
            ethertype = np.where(tagged, _be16(data, np.minimum(ip + 2, data.size - 2)), ethertype)
            ip = np.where(tagged, ip + 4, ip)
        is_ipv4 = ethertype == _ETHERTYPE_IPV4
    elif link == LINK_LINUX_SLL:
        ip = frame + 16
        is_ipv4 = (ip <= end) & (_be16(data, np.minimum(frame + 14, data.size - 2)) == _ETHERTYPE_IPV4)
    elif link == LINK_NULL:
        ip = frame + 4
        family = data[np.minimum(frame, data.size - 1)].astype(np.int64) | data[np.minimum(frame + 3, data.size - 1)]
        is_ipv4 = (ip <= end) & (family == 2)  # AF_INET, in either byte order
    else:
        ip = frame
        is_ipv4 = np.ones(count, bool)
    at = np.minimum(ip, data.size - 1)
    is_ipv4 &= (ip + 20 <= end) & ((data[at] >> 4) == 4)
    skip("not an IPv4 packet", usable & ~is_ipv4)
    usable &= is_ipv4
    ihl = (data[at] & 0x0F).astype(np.int64) * 4
    protocol = data[np.minimum(ip + 9, data.size - 1)]
    is_udp = protocol == _UDP
    skip("not a UDP datagram", usable & ~is_udp)
    usable &= is_udp
    flags_fragment = _be16(data, np.minimum(ip + 6, data.size - 2))
    fragment = (flags_fragment & 0x3FFF) != 0  # more fragments, or a fragment offset
    skip("an IP fragment (reassemble the capture first)", usable & fragment)
    usable &= ~fragment
    udp = ip + ihl
    udp_length = _be16(data, np.clip(udp + 4, 0, data.size - 2))
    payload_start = udp + 8
    payload_end = udp + udp_length
    short = (udp + 8 > end) | (udp_length < 8) | (payload_end > end) | (original > captured)
    skip("packet shorter than its UDP length (snap length)", usable & short)
    usable &= ~short
    payload_start, payload_end = payload_start[usable], payload_end[usable]
    lengths = payload_end - payload_start
    joined_start = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64) if lengths.size else lengths
    if lengths.size:
        index = np.repeat(payload_start - joined_start, lengths) + np.arange(int(lengths.sum()))
        joined = data[index].tobytes()
    else:
        joined = b""
    return PcapPayloads(joined, joined_start, payload_start, packets=count, skipped=skipped)


def write_pcap(payloads: list[bytes], *, port: int = 8600, start_unix_s: float = 0.0, interval_s: float = 0.001) -> bytes:
    """A classic libpcap capture (Ethernet, IPv4, UDP to ``port``) carrying ``payloads``, one
    datagram each: for tests and for handing a recording to tools that read captures."""
    out = [np.array([0xA1B2C3D4], "<u4").tobytes() + np.array([2, 4], "<u2").tobytes()
           + np.array([0, 0, 65535, LINK_ETHERNET], "<u4").tobytes()]
    for k, payload in enumerate(payloads):
        udp = np.array([40000, port, 8 + len(payload), 0], ">u2").tobytes() + payload
        total = 20 + len(udp)
        ip = bytearray(np.array([0x4500, total, k & 0xFFFF, 0x4000, 0x4011, 0], ">u2").tobytes()
                       + bytes([127, 0, 0, 1, 127, 0, 0, 1]))
        words = np.frombuffer(bytes(ip), ">u2").astype(np.int64).sum()
        while words >> 16:
            words = (words & 0xFFFF) + (words >> 16)
        ip[10:12] = int(~words & 0xFFFF).to_bytes(2, "big")
        frame = bytes(12) + b"\x08\x00" + bytes(ip) + udp
        t = start_unix_s + k * interval_s
        seconds = int(t)
        header = np.array([seconds, int(round((t - seconds) * 1e6)), len(frame), len(frame)], "<u4").tobytes()
        out.append(header + frame)
    return b"".join(out)
