"""Your own plant in an evoloop run, in Python.

Subclass `Plant` (`reset() -> y`, `step(u, dt) -> y`, optionally `state()` and `joints(y)`) and
call `run(plant)`. The run is described by the EVOLOOP_* variables the launcher sets when it
starts the scenario's `[plant.external] command` (or prints, for a plant the user starts). The
process then speaks evoloop's plant contract v1 (docs/src/plant-contract.md): it joins the run's
iceoryx2 services, publishes one `PlantState` a control period and applies the controller's
`Command`, in lockstep (as fast as the processes answer, reproducibly) or in realtime (on
CLOCK_MONOTONIC ticks).

`read_run(dir)` reads a run's run.csv into NumPy arrays, one per column.
"""
import csv
import ctypes
import math
import os
import signal
import sys
import time

import numpy as np

__all__ = ["Plant", "run", "read_run", "Environment", "PlantState", "Command", "OptimiserAck",
           "CONTRACT"]

#: The plant contract this package speaks: the `.v1` of every message's type name.
CONTRACT = 1
MAX_STATES, MAX_JOINTS = 32, 8
STATE_FLAG_SAFE, STATE_FLAG_END = 1, 2
U64_MAX = 2**64 - 1


class PlantState(ctypes.Structure):
    """evoloop::PlantState.v1, field by field (the contract's table; tests/python_plant.rs checks
    the offsets against the Rust layout)."""

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
        return f"evoloop::PlantState.v{CONTRACT}"


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
        return f"evoloop::Command.v{CONTRACT}"


class OptimiserAck(ctypes.Structure):
    """evoloop::OptimiserAck.v1."""

    _fields_ = [("through_seq", ctypes.c_uint64)]

    @staticmethod
    def type_name():
        return f"evoloop::OptimiserAck.v{CONTRACT}"


#: The contract's services: (topic, payload, subscriber max buffer).
PUBSUB = {"state": (PlantState, 264), "command": (Command, 264), "optimiser_ack": (OptimiserAck, 4)}


class Failure(Exception):
    """The plant leaves with `code`: 2 setup or IPC, 3 a peer timed out (the contract's codes)."""

    def __init__(self, code, message):
        super().__init__(message)
        self.code = code


class Environment:
    """The run as the launcher describes it in EVOLOOP_* variables."""

    NAMES = ["RUN_ID", "IPC_PREFIX", "IPC_ROOT", "MODE", "PERIOD", "SAMPLES", "SYNC_SAMPLES",
             "SYNC_OFFSET", "TIMEOUT", "SAFE_COMMAND", "COMMAND_TIMEOUT_PERIODS", "STATES",
             "JOINTS", "OUTPUTS", "INPUTS"]

    def __init__(self, environ=None):
        e = os.environ if environ is None else environ
        missing = [n for n in self.NAMES if "EVOLOOP_" + n not in e]
        if missing:
            raise Failure(2, "not started by an evoloop run: EVOLOOP_" + ", EVOLOOP_".join(missing)
                          + " missing (plant.external.command starts this script with them; for "
                          "a plant you start, `evoloop run` prints them)")
        g = lambda n: e["EVOLOOP_" + n]
        self.run_id, self.prefix, self.root = g("RUN_ID"), g("IPC_PREFIX"), g("IPC_ROOT")
        self.mode = g("MODE")
        self.period = float(g("PERIOD"))
        self.samples = None if g("SAMPLES") == "forever" else int(g("SAMPLES"))
        self.sync_samples, self.sync_offset = int(g("SYNC_SAMPLES")), int(g("SYNC_OFFSET"))
        self.timeout = float(g("TIMEOUT"))
        self.safe_command = float(g("SAFE_COMMAND"))
        self.command_timeout_periods = int(g("COMMAND_TIMEOUT_PERIODS"))
        self.states, self.joints = int(g("STATES")), int(g("JOINTS"))
        self.outputs, self.inputs = int(g("OUTPUTS")), int(g("INPUTS"))
        self.seed = int(e.get("EVOLOOP_SEED", "1"))
        self.spin_us = float(e.get("EVOLOOP_SPIN_US", "0"))


class Plant:
    """Subclass and override `reset` and `step`. Arrays may be lists or NumPy arrays."""

    #: False for a plant that has no truth to send, as a real machine has none: every truth field
    #: (x_true, q_true, qd_true) is then NaN, and `state()` and `joints()` are not called. The
    #: scenario's law must then read only the measured outputs (e.g. `velocity = "filtered"`).
    truth = True

    def reset(self):
        """Put the plant in its initial state; return the measured outputs y (one per output)."""
        raise NotImplementedError

    def step(self, u, dt):
        """Hold the command u (one value per input) for dt seconds; return the outputs y after it.
        dt is the control period, or in realtime a part of it (a command arrived mid-period)."""
        raise NotImplementedError

    def state(self):
        """The full state sent as x_true (EVOLOOP_STATES values; state feedback reads it), or
        None for zeros."""
        return None

    def joints(self, y):
        """(q, qd) sent as q_true and qd_true (EVOLOOP_JOINTS values each), or None for the
        first outputs and zero rates."""
        return None


def _fill(array, values, n, what):
    """Write the first n entries of a ctypes array from a list, tuple or NumPy array (or zeros
    for None), by one slice assignment: the per-sample path allocates nothing beyond what the
    plant returned. Anything else NumPy can flatten (nested lists, a list of arrays) goes
    through NumPy first, as every value once did."""
    if values is None:
        array[:n] = _ZEROS[:n]
        return
    if not isinstance(values, (list, tuple)) or len(values) != n:
        values = np.ravel(values).tolist()
    if len(values) != n:
        raise Failure(2, f"{what} has {len(values)} values, the scenario declares {n}")
    try:
        array[:n] = values
    except TypeError:  # nested sequences, or entries ctypes does not take as a double
        flat = np.ravel(values).tolist()
        if len(flat) != n:
            raise Failure(2, f"{what} has {len(flat)} values, the scenario declares {n}")
        array[:n] = [float(x) for x in flat]


_ZEROS = [0.0] * max(MAX_STATES, MAX_JOINTS)
_NANS = [math.nan] * max(MAX_STATES, MAX_JOINTS)


class _Ports:
    """The plant's ports, in the Rust plant's order: ready listener, sync notifier, command
    subscriber and listener, optimiser_ack subscriber and listener, state publisher and
    notifier."""

    def __init__(self, env):
        import iceoryx2 as iox2

        self.iox2 = iox2
        # The poll before blocking (EVOLOOP_SPIN_US, the scenario's timing.spin_us): in lockstep
        # the controller answers within tens of microseconds, sooner than a sleep on an event
        # and the wake-up after it.
        self.spin_s = env.spin_us * 1e-6
        iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
        cfg = iox2.config.global_config()
        cfg.global_cfg.prefix = iox2.FileName.new(env.prefix)
        cfg.global_cfg.root_path = iox2.Path.new(env.root)
        try:
            self.node = (iox2.NodeBuilder.new().name(iox2.NodeName.new("evoloop-plant-python"))
                         .config(cfg).signal_handling_mode(iox2.SignalHandlingMode.Disabled)
                         .create(iox2.ServiceType.Ipc))
        except Exception as e:
            raise Failure(2, f"cannot create the iceoryx2 node under {env.root} with prefix "
                          f"{env.prefix}: {e}")
        base = f"evoloop/{env.run_id}"
        self.ready = self._event(f"{base}/ready").listener_builder().create()
        self.sync = self._event(f"{base}/sync").notifier_builder().create()
        self.command_service = self._pubsub(base, "command")
        self.command = self.command_service.subscriber_builder().buffer_size(8).create()
        # Where each received message is copied: one buffer per port, no object per message.
        self.command_in, self.ack_in = Command(), OptimiserAck()
        self.command_wake = self._event(f"{base}/command").listener_builder().create()
        self.ack_service = self._pubsub(base, "optimiser_ack")
        self.ack = self.ack_service.subscriber_builder().buffer_size(4).create()
        self.ack_wake = self._event(f"{base}/optimiser_ack").listener_builder().create()
        self.state_service = self._pubsub(base, "state")
        self.state = self.state_service.publisher_builder().create()
        self.state_wake = self._event(f"{base}/state").notifier_builder().create()

    def _pubsub(self, base, topic):
        payload, max_buffer = PUBSUB[topic]
        iox2 = self.iox2
        try:
            return (self.node.service_builder(iox2.ServiceName.new(f"{base}/{topic}"))
                    .publish_subscribe(payload).subscriber_max_buffer_size(max_buffer)
                    .subscriber_max_borrowed_samples(2).history_size(0).max_publishers(2)
                    .max_subscribers(6).max_nodes(8).enable_safe_overflow(True).open_or_create())
        except Exception as e:
            raise Failure(2, f"cannot open {base}/{topic}: {e} (this package speaks plant "
                          f"contract v{CONTRACT}; a run on another contract names its types "
                          f"otherwise)")

    def _event(self, name):
        iox2 = self.iox2
        try:
            return (self.node.service_builder(iox2.ServiceName.new(name)).event().max_notifiers(4)
                    .max_listeners(6).max_nodes(8).open_or_create())
        except Exception as e:
            raise Failure(2, f"cannot open the event service {name}: {e}")

    def wait(self, listener, seconds):
        """Sleep on an event service until woken, `seconds` pass or a signal arrives (a stop:
        the caller looks at its flag)."""
        try:
            listener.timed_wait(self.iox2.Duration.from_secs_f64(seconds))
        except self.iox2.ListenerWaitError:
            pass

    @staticmethod
    def take(subscriber, into):
        """The next message, copied out of shared memory into `into` (the port's one buffer:
        read it before the next `take` of the port; the loan is returned at once), or None."""
        sample = subscriber.receive()
        if sample is None:
            return None
        ctypes.memmove(ctypes.addressof(into), sample.payload_ptr, ctypes.sizeof(into))
        sample.delete()
        return into

    def poll(self, subscriber, into, listener, seconds):
        """`take`, polling for up to the spin time, then sleeping on `listener` for `seconds`
        (or until woken): None when nothing came."""
        until = time.perf_counter() + self.spin_s
        while True:
            m = self.take(subscriber, into)
            if m is not None:
                return m
            if time.perf_counter() >= until:
                self.wait(listener, seconds)
                return None

    def publish(self, s):
        self.state.send_copy(s)
        self.state_wake.notify()

    def peers_present(self):
        c = self.command_service.dynamic_config.number_of_publishers
        s = self.state_service.dynamic_config.number_of_subscribers
        a = self.ack_service.dynamic_config.number_of_publishers
        return c >= 1 and s >= 2 and a >= 1

    def close(self):
        """The ports, last made first (the node goes with the object)."""
        for port in (self.state_wake, self.state, self.ack_wake, self.ack, self.command_wake,
                     self.command, self.sync, self.ready):
            port.delete()


class _Runner:
    def __init__(self, plant, env, ports, stopped):
        self.plant, self.env, self.ports = plant, env, ports
        self._stopped = stopped
        # The one message every sample is written into (and copied from into shared memory): its
        # counts, and the NaN truth of a plant without one, are set once.
        self.msg = PlantState()
        self.msg.n_x, self.msg.n_q, self.msg.n_y = env.states, env.joints, env.outputs
        self.nan_truth = False  # the truth fields hold NaN (written at the first truthless sample)
        self.y = None
        self.t = 0.0

    @property
    def stop(self):
        """A SIGTERM, SIGINT or SIGHUP has arrived."""
        return bool(self._stopped)

    def sample(self, seq, u_applied, flags=0):
        e, m = self.env, self.msg
        m.seq, m.stamp_ns, m.t, m.flags = seq, time.monotonic_ns(), self.t, flags
        _fill(m.y, self.y, e.outputs, "step()'s y")
        _fill(m.u_applied, u_applied, e.inputs, "the command")
        if not self.plant.truth:
            if not self.nan_truth:
                for field, n in ((m.x_true, e.states), (m.q_true, e.joints),
                                 (m.qd_true, e.joints)):
                    field[:n] = _NANS[:n]
                self.nan_truth = True
            return m
        self.nan_truth = False
        _fill(m.x_true, self.plant.state(), e.states, "state()")
        j = self.plant.joints(self.y)
        if j is None and e.joints > e.outputs:
            raise Failure(2, f"the scenario declares {e.joints} joints and {e.outputs} outputs: "
                          "override Plant.joints(y) to give q and qd")
        if j is None:
            y = self.y if isinstance(self.y, (list, tuple)) else np.ravel(self.y).tolist()
            q, qd = y[:e.joints], None
        else:
            q, qd = j
        _fill(m.q_true, q, e.joints, "joints()'s q")
        _fill(m.qd_true, qd, e.joints, "joints()'s qd")
        return m

    def advance(self, u, dt):
        if dt > 0:
            self.y = self.plant.step(list(u), dt)
            self.t += dt

    def wait_for_peers(self):
        # The start timeout, as the Rust plant's: the lockstep timeout, at least 10 s.
        start_timeout = max(self.env.timeout, 10.0)
        limit = time.monotonic() + start_timeout
        while not self.ports.peers_present():
            if self.stop:
                return
            if time.monotonic() > limit:
                raise Failure(3, "the controller and the optimiser did not join within "
                              f"{start_timeout} s")
            self.ports.wait(self.ports.ready, 0.1)

    def lockstep(self):
        e, p = self.env, self.ports
        n = e.samples
        k, u = 0, [0.0] * e.inputs
        paced = True
        while True:
            last = n is not None and k == n
            m = self.sample(k, u, STATE_FLAG_END if last else 0)
            p.publish(m)
            if last or self.stop:
                p.sync.notify()
                return
            if k % e.sync_samples == e.sync_offset:
                p.sync.notify()
                paced = self.wait_for_ack(k, paced)
            u = self.wait_for_command(k)
            if u is None:
                return
            self.advance(u, e.period)
            k += 1

    def wait_for_ack(self, k, paced):
        """Until the optimiser has consumed sample k (the contract's Lockstep, step 4): with no
        optimiser, at once; one that stalled for the timeout is not waited for (paced = False)
        until it acknowledges anything again. Returns whether it is paced."""
        p = self.ports
        t0 = time.monotonic()

        def drain():
            """(any ack heard, one for sample k among them)."""
            heard = False
            while (a := p.take(p.ack, p.ack_in)) is not None:
                heard = True
                if a.through_seq == U64_MAX or a.through_seq >= k:
                    return True, True
            return heard, False

        if p.ack_service.dynamic_config.number_of_publishers == 0:
            return paced
        heard, reached = drain()
        if reached:
            return True
        if not paced:
            if not heard:
                return False
            print(f"evoloop-plant (python): the optimiser acknowledges again; pacing it from "
                  f"sample {k}", file=sys.stderr)
        while True:
            if self.stop or p.ack_service.dynamic_config.number_of_publishers == 0:
                return True
            if time.monotonic() - t0 >= self.env.timeout:
                print(f"evoloop-plant (python): the optimiser did not acknowledge sample {k} "
                      f"within {self.env.timeout} s; going on without waiting for it",
                      file=sys.stderr)
                return False
            p.wait(p.ack_wake, min(0.2, self.env.timeout))
            if drain()[1]:
                return True

    def wait_for_command(self, k):
        p, inputs = self.ports, self.env.inputs
        limit = time.monotonic() + self.env.timeout
        wait = min(0.1, self.env.timeout)
        while not self.stop:
            c = p.poll(p.command, p.command_in, p.command_wake, wait)
            if c is not None:
                if c.state_seq == k:
                    return c.u[:inputs]
                continue
            if time.monotonic() > limit:
                raise Failure(3, f"controller did not answer sample {k} within {self.env.timeout} s")
        return None

    def realtime(self):
        e, p = self.env, self.ports
        period_ns = round(e.period * 1e9)
        timeout_ns = e.command_timeout_periods * period_ns
        safe = [e.safe_command] * e.inputs
        epoch = time.monotonic_ns()
        u, last, safe_mode, flags, k = list(safe), None, False, 0, 0
        while True:
            tick = epoch + k * period_ns
            pause = (tick - time.monotonic_ns()) / 1e9
            if pause > 0:
                time.sleep(pause)
            while True:
                c = p.take(p.command, p.command_in)
                if c is None:
                    break
                at = min(max(c.stamp_ns, epoch + round(self.t * 1e9)), tick)
                self.advance(u, (at - epoch) / 1e9 - self.t)
                u = c.u[:e.inputs]
                last, safe_mode = at, False
            if last is not None and not safe_mode and tick - last > timeout_ns:
                self.advance(u, (last + timeout_ns - epoch) / 1e9 - self.t)
                u, safe_mode, flags = list(safe), True, flags | STATE_FLAG_SAFE
            self.advance(u, k * e.period - self.t)
            end = (e.samples is not None and k == e.samples) or self.stop
            p.publish(self.sample(k, u, flags | (STATE_FLAG_END if end else 0)))
            if end:
                return
            k += 1


def run(plant, environ=None):
    """Join the run the EVOLOOP_* variables describe and play `plant` in it until its last
    sample or SIGTERM/SIGINT. Exits the process with the contract's code on a failure (2 setup,
    3 a peer timed out), with the reason on stderr."""
    ports = None
    stopped = []

    def stop(*_):
        stopped.append(True)

    # Before any port exists: a stop is a flag the loops look at, never an exception.
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, stop)
    try:
        env = Environment(environ)
        ports = _Ports(env)
        r = _Runner(plant, env, ports, stopped)
        r.y = plant.reset()
        r.wait_for_peers()
        if env.mode == "lockstep":
            r.lockstep()
        else:
            r.realtime()
    except Failure as f:
        print(f"evoloop-plant (python): {f}", file=sys.stderr)
        sys.exit(f.code)
    finally:
        if ports is not None:
            ports.close()


def read_run(path):
    """A run's run.csv (finished, or being written: a row cut short at the end is left out) as a
    dict of NumPy float arrays, one per column."""
    with open(os.path.join(path, "run.csv"), newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]
    data = np.array([[float(x) if x else math.nan for x in r] for r in body], dtype=float)
    data = data.reshape(len(body), len(header))
    return {name: data[:, i] for i, name in enumerate(header)}
