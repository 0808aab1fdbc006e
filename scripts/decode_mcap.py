#!/usr/bin/env python3
"""Decode a run.mcap with Foxglove's own readers, not evoloop's: PyPI's `mcap` (the file) and
`mcap-ros2-support` (ROS 2 CDR from the `ros2msg` schemas in the file), what a user's Python
tooling would use. Prints one JSON object per message on stdout:

  {"topic": ..., "log_time": ns, "schema": "pkg/msg/Type", "msg": {field: value, ...}}

Floats are printed as their IEEE-754 bits (an unsigned 64-bit integer), so a reader can compare
them with another source bit for bit, NaN payloads included.

    pip install mcap mcap-ros2-support
    python3 scripts/decode_mcap.py runs/arm3_pd/run.mcap --topic joint_states --limit 5
"""

import argparse
import json
import struct
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def plain(value):
    """A decoded message as JSON-ready data: floats as their bits, messages as dicts."""
    if isinstance(value, float):
        return struct.unpack("<Q", struct.pack("<d", value))[0]
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    return {name: plain(getattr(value, name)) for name in value.__slots__}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("file")
    ap.add_argument("--topic", action="append", help="only these topics (repeatable)")
    ap.add_argument("--limit", type=int, default=None, help="at most this many messages")
    a = ap.parse_args()
    with open(a.file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        out = sys.stdout
        for i, (schema, channel, message, decoded) in enumerate(
            reader.iter_decoded_messages(topics=a.topic, log_time_order=False)
        ):
            if a.limit is not None and i >= a.limit:
                break
            json.dump(
                {
                    "topic": channel.topic,
                    "log_time": message.log_time,
                    "schema": schema.name,
                    "msg": plain(decoded),
                },
                out,
            )
            out.write("\n")


if __name__ == "__main__":
    main()
