//! The plant contract says a process that speaks stock iceoryx2 (`ipc::Service`; the bindings'
//! `ipc_threadsafe::Service` differs from it as evoloop's does, in a process-local reference
//! count) can join a run: evoloop's ports use its own pooled
//! service type, which differs from the stock one only in process-local bookkeeping. This proves
//! it on the contract's services: a stock node, configured as the plant contract says (the same
//! prefix and root path, the same service settings), receives evoloop's states, sends commands
//! evoloop receives, and wakes and is woken through the paired event services.

use crate::common;

use common::{assert_same_state, contract_command, contract_state};
use evoloop::ipc::{create_node, ipc_config, Topic, Wait};
use evoloop::msg::{Command, PlantState};
use iceoryx2::prelude::*;
use std::time::Duration;

/// The stock node, as a foreign plant would make it from the contract.
fn stock_node(prefix: &str) -> Node<ipc::Service> {
    let cfg = ipc_config(prefix).unwrap();
    let name = NodeName::new("foreign-plant").unwrap();
    create_node(
        NodeBuilder::new().name(&name).config(&cfg),
        prefix,
        "stock node",
    )
    .unwrap()
}

/// A publish-subscribe service with the contract's settings, opened from the stock side.
fn stock_pubsub<T: std::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    max_buffer: usize,
) -> iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()> {
    node.service_builder(&ServiceName::new(name).unwrap())
        .publish_subscribe::<T>()
        .subscriber_max_buffer_size(max_buffer)
        .subscriber_max_borrowed_samples(2)
        .history_size(0)
        .max_publishers(2)
        .max_subscribers(6)
        .max_nodes(8)
        .enable_safe_overflow(true)
        .open_or_create()
        .unwrap()
}

/// The event service paired with a topic, with the contract's settings, from the stock side.
fn stock_event(
    node: &Node<ipc::Service>,
    name: &str,
) -> iceoryx2::service::port_factory::event::PortFactory<ipc::Service> {
    node.service_builder(&ServiceName::new(name).unwrap())
        .event()
        .max_notifiers(4)
        .max_listeners(6)
        .max_nodes(8)
        .open_or_create()
        .unwrap()
}

/// A topic of the contract from the stock side: its publish-subscribe service `name` (the
/// contract's `evoloop/<run>/<topic>`, spelled out here as a foreign plant would) and the event
/// service of the same name.
#[allow(clippy::type_complexity)]
fn stock_topic<T: std::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    max_buffer: usize,
) -> (
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
    iceoryx2::service::port_factory::event::PortFactory<ipc::Service>,
) {
    (
        stock_pubsub::<T>(node, name, max_buffer),
        stock_event(node, name),
    )
}

#[test]
fn a_stock_iceoryx2_participant_speaks_the_contract_with_evoloops_pooled_ports() {
    let (prefix, run) = common::unique("stock");
    let run = run.as_str();
    // evoloop's side, as the controller makes its ports: the state subscriber, the command
    // publisher, each with its event.
    let ours = common::controller_ports(run, &prefix);
    let (state_sub, command_pub) = (&ours.state, &ours.command);

    // The foreign plant's side, stock iceoryx2.
    let node = stock_node(&prefix);
    let (state, state_event) = stock_topic::<PlantState>(
        &node,
        &format!("evoloop/{run}/state"),
        Topic::State.max_buffer(),
    );
    let state_pub = state
        .publisher_builder()
        .max_loaned_samples(1)
        .create()
        .unwrap();
    let state_notifier = state_event.notifier_builder().create().unwrap();
    let (command, command_event) = stock_topic::<Command>(
        &node,
        &format!("evoloop/{run}/command"),
        Topic::Command.max_buffer(),
    );
    let command_sub = command
        .subscriber_builder()
        .buffer_size(8)
        .create()
        .unwrap();
    let command_listener = command_event.listener_builder().create().unwrap();

    // Foreign plant -> evoloop: a state, every f64 bit for bit, and the wake-up.
    let s = contract_state();
    state_pub.send_copy(s).unwrap();
    state_notifier.notify().unwrap();
    let got = match state_sub
        .wait_next(Duration::ZERO, Duration::from_secs(5))
        .unwrap()
    {
        Wait::Got(g) => g,
        Wait::TimedOut => panic!("evoloop's subscriber saw no state from the stock publisher"),
    };
    assert_eq!(got.seq, 7);
    assert_same_state(&got, &s);

    // evoloop -> foreign plant: the answer, and the stock listener is woken by evoloop's ring.
    let c = contract_command();
    command_pub.send(&c).unwrap();
    let mut woke = 0;
    command_listener
        .timed_wait(|_| woke += 1, Duration::from_secs(5))
        .unwrap();
    assert!(
        woke > 0,
        "the stock listener was not woken by evoloop's notifier"
    );
    let sample = command_sub
        .receive()
        .unwrap()
        .expect("a command from evoloop's publisher");
    assert_eq!(*sample.payload(), c);
    assert_eq!(
        state_sub.publishers(),
        1,
        "evoloop counts the stock publisher"
    );
}
