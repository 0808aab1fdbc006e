//! The iceoryx2 code behind a typed port, compiled once, in this crate, for each of evoloop's
//! messages.
//!
//! Why: that code (a service's opening and its static configuration, read and written as TOML;
//! a port's creation, loan, send, receive and drop) is generic over the payload and over
//! evoloop's service type, and a release build compiles a generic function anew in every crate
//! that instantiates it (instances are not shared between crates at opt-level 2 and above). So
//! every crate and test binary that opened a port compiled iceoryx2's service code again: a
//! 64-line test of one publisher and one subscriber took 16 s to build, most of its 365 000
//! lines of LLVM IR iceoryx2's and its configuration's (`cargo llvm-lines`, 2026-12-06). Here
//! each message implements [`Message`] with non-generic functions, compiled in this crate; a
//! port's user calls them and instantiates none of iceoryx2.

use crate::{Ipc, IpcError, Pub, Sub, Svc, Topic};
use evoloop_msg::{
    Command, LinearEstimate, ModelEstimate, OperatorAck, OperatorCommand, OptimiserAck,
    OptimiserStatus, ParamSet, PlantState, Telemetry,
};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use std::fmt::Debug;
use std::mem::ManuallyDrop;

/// A payload of evoloop's ports: one of evoloop-msg's messages. Its port code is compiled in
/// this crate (the module's comment says why); the methods are the ports' plumbing, called
/// through [`Ipc::publisher`], [`Ipc::subscriber`] and the ports' own methods.
pub trait Message: Debug + ZeroCopySend + Copy + 'static {
    #[doc(hidden)]
    fn publisher(ipc: &Ipc, topic: Topic, wake: bool) -> Result<Pub<Self>, IpcError>;
    #[doc(hidden)]
    fn subscriber(
        ipc: &Ipc,
        topic: Topic,
        buffer: usize,
        wake: bool,
    ) -> Result<Sub<Self>, IpcError>;
    #[doc(hidden)]
    fn send(port: &PubPorts<Self>, value: &Self) -> Result<(), IpcError>;
    #[doc(hidden)]
    fn receive(port: &SubPorts<Self>) -> Result<Option<Self>, IpcError>;
    #[doc(hidden)]
    fn has_pending(port: &SubPorts<Self>) -> Result<bool, IpcError>;
    #[doc(hidden)]
    fn connect_publisher(port: &PubPorts<Self>) -> Result<(), IpcError>;
    #[doc(hidden)]
    fn connect_subscriber(port: &SubPorts<Self>) -> Result<(), IpcError>;
    #[doc(hidden)]
    fn subscribers(port: &PubPorts<Self>) -> usize;
    #[doc(hidden)]
    fn publishers(port: &SubPorts<Self>) -> usize;
    #[doc(hidden)]
    fn drop_publisher(port: &mut ManuallyDrop<PubPorts<Self>>);
    #[doc(hidden)]
    fn drop_subscriber(port: &mut ManuallyDrop<SubPorts<Self>>);
}

type PubSubFactory<T> = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>;

/// A publisher's iceoryx2 side: the port, its notifier (a waking publisher), its service and
/// its topic (which names it in errors).
#[doc(hidden)]
pub struct PubPorts<T: Debug + ZeroCopySend + 'static> {
    publisher: Publisher<Svc, T, ()>,
    notifier: Option<Notifier<Svc>>,
    service: PubSubFactory<T>,
    topic: Topic,
}

/// A subscriber's iceoryx2 side: the port, its listener (a waiting subscriber), its service and
/// its topic.
#[doc(hidden)]
pub struct SubPorts<T: Debug + ZeroCopySend + 'static> {
    subscriber: Subscriber<Svc, T, ()>,
    pub(crate) listener: Option<Listener<Svc>>,
    service: PubSubFactory<T>,
    pub(crate) topic: Topic,
}

/// `topic`'s publish-subscribe service, opened or created with the topic's limits.
fn pubsub<T: Debug + ZeroCopySend + 'static>(
    ipc: &Ipc,
    topic: Topic,
) -> Result<PubSubFactory<T>, IpcError> {
    let name = ipc.service_name(topic)?;
    crate::retry(&format!("opening service {}", name.as_str()), || {
        ipc.node
            .service_builder(&name)
            .publish_subscribe::<T>()
            .subscriber_max_buffer_size(topic.max_buffer())
            .subscriber_max_borrowed_samples(2)
            .history_size(0)
            .max_publishers(topic.max_publishers())
            .max_subscribers(topic.max_subscribers())
            .max_nodes(topic.max_nodes())
            .enable_safe_overflow(true)
            .open_or_create()
    })
}

/// `what` failed on `topic`: the error names the operation and the topic.
fn failed<E: std::error::Error + Send + Sync + 'static>(
    what: &'static str,
    topic: Topic,
) -> impl FnOnce(E) -> IpcError {
    move |e| IpcError::new(format!("{what} {}", topic.name()), e)
}

impl<T: Debug + ZeroCopySend + Copy + 'static> PubPorts<T> {
    fn open(ipc: &Ipc, topic: Topic, wake: bool) -> Result<Self, IpcError> {
        let service = pubsub::<T>(ipc, topic)?;
        Ok(PubPorts {
            publisher: service
                .publisher_builder()
                .max_loaned_samples(1)
                .create()
                .map_err(failed("publisher on", topic))?,
            notifier: wake.then(|| ipc.notifier(topic)).transpose()?,
            service,
            topic,
        })
    }

    /// Copy `value` into a shared-memory slot, send it and wake the listeners. No allocation.
    fn send(&self, value: &T) -> Result<(), IpcError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(failed("loan on", self.topic))?;
        sample
            .write_payload(*value)
            .send()
            .map_err(failed("send on", self.topic))?;
        if let Some(n) = &self.notifier {
            n.notify().map_err(failed("notify on", self.topic))?;
        }
        Ok(())
    }
}

impl<T: Debug + ZeroCopySend + Copy + 'static> SubPorts<T> {
    fn open(ipc: &Ipc, topic: Topic, buffer: usize, wake: bool) -> Result<Self, IpcError> {
        let service = pubsub::<T>(ipc, topic)?;
        Ok(SubPorts {
            subscriber: service
                .subscriber_builder()
                .buffer_size(buffer.clamp(1, topic.max_buffer()))
                .create()
                .map_err(failed("subscriber on", topic))?,
            listener: wake.then(|| ipc.listener(topic)).transpose()?,
            service,
            topic,
        })
    }

    fn receive(&self) -> Result<Option<T>, IpcError> {
        let sample = self
            .subscriber
            .receive()
            .map_err(failed("receive on", self.topic))?;
        Ok(sample.map(|s| *s.payload()))
    }
}

fn connections(topic: Topic, port: &dyn UpdateConnections) -> Result<(), IpcError> {
    port.update_connections()
        .map_err(failed("connections of", topic))
}

macro_rules! messages {
    ($($t:ty),* $(,)?) => {$(
        impl Message for $t {
            fn publisher(ipc: &Ipc, topic: Topic, wake: bool) -> Result<Pub<Self>, IpcError> {
                PubPorts::open(ipc, topic, wake).map(Pub::new)
            }
            fn subscriber(
                ipc: &Ipc,
                topic: Topic,
                buffer: usize,
                wake: bool,
            ) -> Result<Sub<Self>, IpcError> {
                SubPorts::open(ipc, topic, buffer, wake).map(Sub::new)
            }
            fn send(port: &PubPorts<Self>, value: &Self) -> Result<(), IpcError> {
                port.send(value)
            }
            fn receive(port: &SubPorts<Self>) -> Result<Option<Self>, IpcError> {
                port.receive()
            }
            fn has_pending(port: &SubPorts<Self>) -> Result<bool, IpcError> {
                port.subscriber.has_samples().map_err(failed("poll", port.topic))
            }
            fn connect_publisher(port: &PubPorts<Self>) -> Result<(), IpcError> {
                connections(port.topic, &port.publisher)
            }
            fn connect_subscriber(port: &SubPorts<Self>) -> Result<(), IpcError> {
                connections(port.topic, &port.subscriber)
            }
            fn subscribers(port: &PubPorts<Self>) -> usize {
                port.service.dynamic_config().number_of_subscribers()
            }
            fn publishers(port: &SubPorts<Self>) -> usize {
                port.service.dynamic_config().number_of_publishers()
            }
            fn drop_publisher(port: &mut ManuallyDrop<PubPorts<Self>>) {
                // SAFETY: called once, by `Pub`'s drop, which never touches the ports after.
                unsafe { ManuallyDrop::drop(port) }
            }
            fn drop_subscriber(port: &mut ManuallyDrop<SubPorts<Self>>) {
                // SAFETY: called once, by `Sub`'s drop, which never touches the ports after.
                unsafe { ManuallyDrop::drop(port) }
            }
        }
    )*};
}

messages!(
    PlantState,
    Command,
    Telemetry,
    ParamSet,
    OptimiserAck,
    ModelEstimate,
    OptimiserStatus,
    OperatorCommand,
    OperatorAck,
    LinearEstimate,
);
