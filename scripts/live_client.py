#!/usr/bin/env python3
"""A headless Foxglove WebSocket viewer (standard library only, written from the protocol's
specification): connects to `evoloop live` (or `evoloop run --live`), subscribes to every
advertised channel and prints, after SECONDS, the messages and bytes it received per topic as
JSON. For measuring what a connected viewer costs the loop (docs/measurements).

    python3 scripts/live_client.py 127.0.0.1:8765 --seconds 10
"""

import argparse
import base64
import json
import os
import socket
import struct
import sys
import time


def recv_exact(s, n):
    b = b""
    while len(b) < n:
        chunk = s.recv(n - len(b))
        if not chunk:
            raise ConnectionError("closed")
        b += chunk
    return b


def read_frame(s):
    """One WebSocket frame from the server (unmasked): (opcode, payload)."""
    h = recv_exact(s, 2)
    opcode, n = h[0] & 0x0F, h[1] & 0x7F
    if n == 126:
        n = struct.unpack(">H", recv_exact(s, 2))[0]
    elif n == 127:
        n = struct.unpack(">Q", recv_exact(s, 8))[0]
    return opcode, recv_exact(s, n)


def send_text(s, text):
    """A masked text frame, as a client must send."""
    data = text.encode()
    mask = os.urandom(4)
    n = len(data)
    head = bytes([0x81]) + (
        bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n)
    )
    s.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("addr", help="host:port")
    ap.add_argument("--seconds", type=float, default=10.0)
    a = ap.parse_args()
    host, port = a.addr.rsplit(":", 1)
    deadline = time.time() + 10
    while True:
        try:
            s = socket.create_connection((host, int(port)))
            break
        except OSError:
            if time.time() > deadline:
                raise
            time.sleep(0.1)
    key = base64.b64encode(os.urandom(16)).decode()
    s.sendall(
        (
            f"GET / HTTP/1.1\r\nHost: {a.addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n"
        ).encode()
    )
    response = b""
    while b"\r\n\r\n" not in response:
        response += s.recv(1)
    if b" 101 " not in response.split(b"\r\n")[0]:
        sys.exit(f"handshake refused: {response.decode(errors='replace')}")
    topics = {}
    counts = {}
    end = time.time() + a.seconds
    # A timeout inside a frame would lose the stream's framing: a quiet server for 5 s ends it.
    s.settimeout(5.0)
    while time.time() < end:
        try:
            opcode, payload = read_frame(s)
        except (ConnectionError, OSError):
            break  # the run ended, or nothing came for 5 s
        if opcode == 1:
            m = json.loads(payload)
            if m.get("op") == "advertise":
                subs = []
                for c in m["channels"]:
                    topics[c["id"]] = c["topic"]
                    subs.append({"id": c["id"], "channelId": c["id"]})
                send_text(s, json.dumps({"op": "subscribe", "subscriptions": subs}))
        elif opcode == 8:
            break  # closed by the server
        elif opcode == 2 and payload[0] == 1:
            sub = struct.unpack("<I", payload[1:5])[0]
            t = topics.get(sub, str(sub))
            c = counts.setdefault(t, [0, 0])
            c[0] += 1
            c[1] += len(payload)
    s.close()
    print(json.dumps({t: {"messages": c[0], "bytes": c[1]} for t, c in counts.items()}))


if __name__ == "__main__":
    main()
