"""Classic libpcap captures of ASTERIX feeds (skytrack.io.asterix.pcap): link layers, byte orders,
packets that are not IPv4/UDP counted by reason with their offsets, offsets mapped back to the file."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from skytrack.io.asterix.pcap import PcapError, udp_payloads, write_pcap

PAYLOADS = [b"\x30\x00\x06abc", b"\x22\x00\x04z", b"0123456789"]


def ipv4(payload: bytes, *, protocol: int = 17, flags_fragment: int = 0x4000, options: bytes = b"") -> bytes:
    udp = struct.pack(">HHHH", 40000, 8600, 8 + len(payload), 0) + payload if protocol == 17 else payload
    ihl = 5 + len(options) // 4
    header = struct.pack(">BBHHHBBH4s4s", 0x40 | ihl, 0, 4 * ihl + len(udp), 1, flags_fragment, 64, protocol, 0,
                         bytes(4), bytes(4))
    return header + options + udp


def capture(frames: list[bytes], *, link: int = 1, big_endian: bool = False, nanoseconds: bool = False,
            cut: dict[int, int] | None = None) -> bytes:
    order = ">" if big_endian else "<"
    magic = 0xA1B23C4D if nanoseconds else 0xA1B2C3D4
    out = [struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, 65535, link)]
    for k, frame in enumerate(frames):
        kept = frame[:len(frame) - (cut or {}).get(k, 0)]
        out.append(struct.pack(order + "IIII", k, 0, len(kept), len(frame)) + kept)
    return b"".join(out)


def ethernet(packet: bytes, vlan_tags: int = 0) -> bytes:
    tags = b"".join(b"\x81\x00" + struct.pack(">H", 7) for _ in range(vlan_tags))
    return bytes(12) + tags + b"\x08\x00" + packet


def test_write_pcap_round_trip_and_file_offsets():
    data = write_pcap(PAYLOADS)
    read = udp_payloads(data)
    assert read.data == b"".join(PAYLOADS) and read.packets == 3 and read.skipped == {}
    for offset in range(len(read.data)):
        assert data[read.file_offset(offset)] == read.data[offset]
    np.testing.assert_array_equal(read.file_offset(np.array([0, 6])), [read.file_start[0], read.file_start[1]])


@pytest.mark.parametrize("big_endian", [False, True])
@pytest.mark.parametrize("nanoseconds", [False, True])
@pytest.mark.parametrize("link, frame", [
    (1, lambda p: ethernet(ipv4(p))),
    (1, lambda p: ethernet(ipv4(p), vlan_tags=2)),
    (1, lambda p: ethernet(ipv4(p, options=b"\x01\x01\x01\x00"))),
    (113, lambda p: bytes(14) + b"\x08\x00" + ipv4(p)),
    (0, lambda p: struct.pack("<I", 2) + ipv4(p)),
    (101, lambda p: ipv4(p)),
])
def test_link_layers_and_byte_orders(big_endian, nanoseconds, link, frame):
    data = capture([frame(p) for p in PAYLOADS], link=link, big_endian=big_endian, nanoseconds=nanoseconds)
    read = udp_payloads(data)
    assert read.data == b"".join(PAYLOADS) and read.skipped == {}


def test_packets_that_are_not_asterix_datagrams_are_counted_with_their_offsets():
    frames = [ethernet(ipv4(PAYLOADS[0])),
              bytes(12) + b"\x86\xdd" + bytes(40),  # IPv6
              ethernet(ipv4(b"tcp segment", protocol=6)),
              ethernet(ipv4(PAYLOADS[1], flags_fragment=0x2000)),  # more fragments
              ethernet(ipv4(PAYLOADS[2])),
              ethernet(ipv4(b"cut by the snap length"))]
    data = capture(frames, cut={5: 4})
    header_at = np.cumsum([24] + [16 + len(f) for f in frames[:-1]])  # the cut one is the last: no shift
    read = udp_payloads(data)
    assert read.data == PAYLOADS[0] + PAYLOADS[2]
    assert read.skipped == {
        "not an IPv4 packet": (1, int(header_at[1])),
        "not a UDP datagram": (1, int(header_at[2])),
        "an IP fragment (reassemble the capture first)": (1, int(header_at[3])),
        "packet shorter than its UDP length (snap length)": (1, int(header_at[5])),
    }


def test_a_capture_cut_short_is_counted_and_bad_files_are_refused():
    data = write_pcap(PAYLOADS)
    read = udp_payloads(data[:-3])
    last_header = len(data) - 16 - (14 + 20 + 8 + len(PAYLOADS[-1]))
    assert read.data == b"".join(PAYLOADS[:2])
    assert read.skipped == {"packet cut short by the end of the file": (1, last_header)}
    with pytest.raises(PcapError, match="pcapng"):
        udp_payloads(b"\x0a\x0d\x0d\x0a" + bytes(40))
    with pytest.raises(PcapError, match="byte offset 0: magic 30000661 is not libpcap's"):
        udp_payloads(PAYLOADS[0] + bytes(30))
    with pytest.raises(PcapError, match="link type 105"):
        udp_payloads(capture([b""], link=105))
