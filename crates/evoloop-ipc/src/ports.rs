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
    fn send(port: &PubPorts<Self>, value: &Self, topic: Topic) -> Result<(), IpcError>;
    #[doc(hidden)]
    fn receive(port: &SubPorts<Self>, topic: Topic) -> Result<Option<Self>, IpcError>;
    #[doc(hidden)]
    fn has_pending(port: &SubPorts<Self>, topic: Topic) -> Result<bool, IpcError>;
    #[doc(hidden)]
    fn connect_publisher(port: &PubPorts<Self>, topic: Topic) -> Result<(), IpcError>;
    #[doc(hidden)]
    fn connect_subscriber(port: &SubPorts<Self>, topic: Topic) -> Result<(), IpcError>;
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

/// A publisher's iceoryx2 side: the port, its notifier (a waking publisher) and its service.
#[doc(hidden)]
pub struct PubPorts<T: Debug + ZeroCopySend + 'static> {
    publisher: Publisher<Svc, T, ()>,
    notifier: Option<Notifier<Svc>>,
    service: PubSubFactory<T>,
}

/// A subscriber's iceoryx2 side: the port, its listener (a waiting subscriber) and its service.
#[doc(hidden)]
pub struct SubPorts<T: Debug + ZeroCopySend + 'static> {
    subscriber: Subscriber<Svc, T, ()>,
    pub(crate) listener: Option<Listener<Svc>>,
    service: PubSubFactory<T>,
}

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

fn publisher<T: Message>(ipc: &Ipc, topic: Topic, wake: bool) -> Result<Pub<T>, IpcError> {
    let service = pubsub::<T>(ipc, topic)?;
    let publisher = service
        .publisher_builder()
        .max_loaned_samples(1)
        .create()
        .map_err(|e| IpcError::new(format!("publisher on {}", topic.name()), e))?;
    let notifier = if wake {
        Some(ipc.notifier(topic)?)
    } else {
        None
    };
    Ok(Pub::new(
        PubPorts {
            publisher,
            notifier,
            service,
        },
        topic,
    ))
}

fn subscriber<T: Message>(
    ipc: &Ipc,
    topic: Topic,
    buffer: usize,
    wake: bool,
) -> Result<Sub<T>, IpcError> {
    let service = pubsub::<T>(ipc, topic)?;
    let subscriber = service
        .subscriber_builder()
        .buffer_size(buffer.clamp(1, topic.max_buffer()))
        .create()
        .map_err(|e| IpcError::new(format!("subscriber on {}", topic.name()), e))?;
    let listener = if wake {
        Some(ipc.listener(topic)?)
    } else {
        None
    };
    Ok(Sub::new(
        SubPorts {
            subscriber,
            listener,
            service,
        },
        topic,
    ))
}

/// Copy `value` into a shared-memory slot, send it and wake the listeners. No allocation.
fn send<T: Debug + ZeroCopySend + Copy + 'static>(
    p: &PubPorts<T>,
    value: &T,
    topic: Topic,
) -> Result<(), IpcError> {
    let sample = p
        .publisher
        .loan_uninit()
        .map_err(|e| IpcError::new(format!("loan on {}", topic.name()), e))?;
    sample
        .write_payload(*value)
        .send()
        .map_err(|e| IpcError::new(format!("send on {}", topic.name()), e))?;
    if let Some(n) = &p.notifier {
        n.notify()
            .map_err(|e| IpcError::new(format!("notify on {}", topic.name()), e))?;
    }
    Ok(())
}

fn receive<T: Debug + ZeroCopySend + Copy + 'static>(
    s: &SubPorts<T>,
    topic: Topic,
) -> Result<Option<T>, IpcError> {
    match s.subscriber.receive() {
        Ok(Some(sample)) => Ok(Some(*sample.payload())),
        Ok(None) => Ok(None),
        Err(e) => Err(IpcError::new(format!("receive on {}", topic.name()), e)),
    }
}

fn connections(topic: Topic, port: &dyn UpdateConnections) -> Result<(), IpcError> {
    port.update_connections()
        .map_err(|e| IpcError::new(format!("connections of {}", topic.name()), e))
}

macro_rules! messages {
    ($($t:ty),* $(,)?) => {$(
        impl Message for $t {
            fn publisher(ipc: &Ipc, topic: Topic, wake: bool) -> Result<Pub<Self>, IpcError> {
                publisher(ipc, topic, wake)
            }
            fn subscriber(
                ipc: &Ipc,
                topic: Topic,
                buffer: usize,
                wake: bool,
            ) -> Result<Sub<Self>, IpcError> {
                subscriber(ipc, topic, buffer, wake)
            }
            fn send(port: &PubPorts<Self>, value: &Self, topic: Topic) -> Result<(), IpcError> {
                send(port, value, topic)
            }
            fn receive(port: &SubPorts<Self>, topic: Topic) -> Result<Option<Self>, IpcError> {
                receive(port, topic)
            }
            fn has_pending(port: &SubPorts<Self>, topic: Topic) -> Result<bool, IpcError> {
                port.subscriber
                    .has_samples()
                    .map_err(|e| IpcError::new(format!("poll {}", topic.name()), e))
            }
            fn connect_publisher(port: &PubPorts<Self>, topic: Topic) -> Result<(), IpcError> {
                connections(topic, &port.publisher)
            }
            fn connect_subscriber(port: &SubPorts<Self>, topic: Topic) -> Result<(), IpcError> {
                connections(topic, &port.subscriber)
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
