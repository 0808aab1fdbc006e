#!/usr/bin/env python3
"""A foreign plant's side of tests/python_interop.rs, written from the plant contract
(docs/src/plant-contract.md) with PyPI's iceoryx2 0.10 and nothing of evoloop: it joins the
namespace and services the contract names, publishes one PlantState, wakes the subscriber,
waits for the Command answering it and prints that command as JSON.

  python3 scripts/stock_plant_interop.py --prefix FULL_PREFIX --root ROOT_PATH --run RUN_ID
"""
import argparse
import ctypes
import json
import sys
import time

import iceoryx2 as iox2

MAX_STATES, MAX_JOINTS = 32, 8


class PlantState(ctypes.Structure):
    """evoloop::PlantState.v1 (the contract's table, field by field)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("stamp_ns", ctypes.c_uint64),
        ("t", ctypes.c_double),
        ("n_x", ctypes.c_uint32),
        ("n_q", ctypes.c_uint32),
        ("n_y", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("x_true", ctypes.c_double * MAX_STATES),
        ("q_true", ctypes.c_double * MAX_JOINTS),
        ("qd_true", ctypes.c_double * MAX_JOINTS),
        ("y", ctypes.c_double * MAX_JOINTS),
        ("u_applied", ctypes.c_double * MAX_JOINTS),
    ]

    @staticmethod
    def type_name():
        return "evoloop::PlantState.v1"


class Command(ctypes.Structure):
    """evoloop::Command.v1."""

    _fields_ = [
        ("cycle", ctypes.c_uint64),
        ("state_seq", ctypes.c_uint64),
        ("stamp_ns", ctypes.c_uint64),
        ("param_version", ctypes.c_uint64),
        ("n_u", ctypes.c_uint32),
        ("_pad", ctypes.c_uint32),
        ("u", ctypes.c_double * MAX_JOINTS),
    ]

    @staticmethod
    def type_name():
        return "evoloop::Command.v1"


def pubsub(node, name, payload, max_buffer):
    """A publish-subscribe service with the contract's settings."""
    return (
        node.service_builder(iox2.ServiceName.new(name))
        .publish_subscribe(payload)
        .subscriber_max_buffer_size(max_buffer)
        .subscriber_max_borrowed_samples(2)
        .history_size(0)
        .max_publishers(2)
        .max_subscribers(6)
        .max_nodes(8)
        .enable_safe_overflow(True)
        .open_or_create()
    )


def event(node, name):
    return (
        node.service_builder(iox2.ServiceName.new(name))
        .event()
        .max_notifiers(4)
        .max_listeners(6)
        .max_nodes(8)
        .open_or_create()
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--prefix", required=True, help="the full iceoryx2 prefix (<ipc prefix><uid>_)")
    ap.add_argument("--root", required=True, help="iceoryx2's root path (ends in /)")
    ap.add_argument("--run", required=True)
    a = ap.parse_args()
    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    # As evoloop's processes do: the global config (an iceoryx2.toml where iceoryx2 looks for
    # one), with the contract's prefix and root path.
    cfg = iox2.config.global_config()
    cfg.global_cfg.prefix = iox2.FileName.new(a.prefix)
    cfg.global_cfg.root_path = iox2.Path.new(a.root)
    node = (
        iox2.NodeBuilder.new()
        .name(iox2.NodeName.new("foreign-plant"))
        .config(cfg)
        .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
        .create(iox2.ServiceType.Ipc)
    )
    base = f"evoloop/{a.run}"
    state = pubsub(node, f"{base}/state", PlantState, 264)
    publisher = state.publisher_builder().create()
    notifier = event(node, f"{base}/state").notifier_builder().create()
    command = pubsub(node, f"{base}/command", Command, 264)
    subscriber = command.subscriber_builder().buffer_size(8).create()

    # tests/common's contract_state, which the test compares bit for bit.
    s = PlantState(seq=7, stamp_ns=123456789, t=0.007, n_x=4, n_q=2, n_y=2, flags=0)
    for i, v in enumerate([0.1, -0.2, 1e-300, sys.float_info.max]):
        s.x_true[i] = v
    s.y[0], s.y[1] = 3.141592653589793, -0.0
    # The evoloop side subscribes before starting this process; its subscriber is there.
    publisher.send_copy(s)
    notifier.notify()
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        sample = subscriber.receive()
        if sample is not None:
            c = sample.payload().contents
            print(json.dumps({"cycle": c.cycle, "state_seq": c.state_seq, "n_u": c.n_u,
                              "u": [c.u[i] for i in range(MAX_JOINTS)]}))
            return 0
        time.sleep(0.001)
    print("no command within 10 s", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
