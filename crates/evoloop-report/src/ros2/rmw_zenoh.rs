//! The names and bytes of rmw_zenoh, ROS 2's Zenoh middleware (its design document,
//! <https://github.com/ros2/rmw_zenoh/blob/rolling/docs/design.md>), for a process that is a
//! ROS 2 node without ROS 2 installed. Pure: `evoloop_net::ros2` (feature `zenoh`) does the I/O.
//!
//! - A topic's messages are Zenoh puts on `<domain>/<topic>/<type>/<hash>`: the topic's fully
//!   qualified name without its leading '/', the DDS form of the type's name
//!   (`sensor_msgs::msg::dds_::JointState_`) and its REP-2016 hash; the payload is the CDR
//!   message with its 4-byte header.
//! - Each put carries an attachment: the publisher's sequence number (i64), the source
//!   timestamp (i64 ns since the Unix epoch) and its 16-byte GID, as Zenoh's serializer writes
//!   them (little endian, the array after its length 16).
//! - Discovery is by liveliness tokens: `@ros2_lv/<domain>/<session id>/<node id>/<entity id>/
//!   <kind>/<enclave>/<namespace>/<node>` for a node (kind `NN`), followed by
//!   `/<topic>/<type>/<hash>/<qos>` for a publisher (`MP`) or subscription (`MS`); names in a
//!   token have '/' written as '%' ('%' alone for an empty one).

use super::{type_hash, MessageType};

/// The prefix of every liveliness token.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// `pkg/msg/Type` in DDS's form, which rmw_zenoh puts in keys and tokens.
pub fn dds_type_name(ty: &MessageType) -> String {
    let mut parts = ty.name.split('/');
    let (pkg, kind, name) = (
        parts.next().unwrap_or(""),
        parts.next().unwrap_or("msg"),
        parts.next().unwrap_or(""),
    );
    format!("{pkg}::{kind}::dds_::{name}_")
}

/// A name in a token: '/' as '%', an empty one '%'.
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// A ROS 2 name's token (a node's name, a namespace's or a topic's part): a letter or '_', then
/// letters, digits and '_'.
fn check_token(what: &'static str, token: &str) -> Result<(), NameError> {
    let mut chars = token.chars();
    let first_ok = chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
    if first_ok && chars.all(|c| c.is_ascii_alphanumeric() || c == '_') {
        Ok(())
    } else {
        Err(NameError::Token {
            what,
            token: token.into(),
        })
    }
}

/// A node's or topic's name that ROS 2 refuses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NameError {
    /// A domain above 232.
    Domain(u32),
    /// A namespace that does not start with '/'.
    Namespace(String),
    /// A namespace part, node name or topic name part that is not a ROS 2 token.
    Token {
        /// Which ("node name", "namespace part", "topic name part").
        what: &'static str,
        /// The token as given.
        token: String,
    },
}

impl std::fmt::Display for NameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NameError::Domain(d) => write!(f, "ROS 2 domain {d}: domains are 0..=232"),
            NameError::Namespace(ns) => write!(f, "namespace `{ns}`: it starts with '/'"),
            NameError::Token { what, token } => write!(
                f,
                "{what} `{token}`: a ROS 2 name is a letter or '_' then letters, digits or '_'"
            ),
        }
    }
}

impl std::error::Error for NameError {}

/// Where a node is: its domain, namespace and name, checked as ROS 2 checks them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NodeName {
    /// The ROS 2 domain id, 0..=232.
    pub domain: u32,
    /// "/" or "/a/b".
    pub namespace: String,
    /// The node's name: a letter or '_', then letters, digits and '_'.
    pub name: String,
}

impl NodeName {
    /// Check a node's domain, namespace and name as ROS 2 does; the namespace's trailing '/' is
    /// dropped ("/" stays "/").
    ///
    /// # Errors
    ///
    /// A domain above 232, a namespace not starting with '/', or a name or namespace part that is
    /// not a ROS 2 token.
    pub fn new(domain: u32, namespace: &str, name: &str) -> Result<Self, NameError> {
        // ROS 2's domain ids run to 232 (rmw_zenoh takes any u32; DDS's ports stop there).
        if domain > 232 {
            return Err(NameError::Domain(domain));
        }
        let ns = namespace.trim_end_matches('/');
        if !namespace.starts_with('/') {
            return Err(NameError::Namespace(namespace.into()));
        }
        for part in ns.split('/').skip(1) {
            check_token("namespace part", part)?;
        }
        check_token("node name", name)?;
        Ok(Self {
            domain,
            namespace: if ns.is_empty() { "/".into() } else { ns.into() },
            name: name.into(),
        })
    }

    /// A topic `name` relative to the node's namespace, fully qualified.
    pub fn topic(&self, name: &str) -> Result<String, NameError> {
        for part in name.split('/') {
            check_token("topic name part", part)?;
        }
        Ok(if self.namespace == "/" {
            format!("/{name}")
        } else {
            format!("{}/{name}", self.namespace)
        })
    }
}

/// A node in a Zenoh session: its name, the session's id and the node's id in the session.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Node {
    /// Where the node is: domain, namespace and name.
    pub name: NodeName,
    /// The Zenoh session's id, as Zenoh prints it (hex).
    pub zid: String,
    /// The node's id in the session (also its entity id in its own token).
    pub id: u64,
}

impl Node {
    /// The node's liveliness token.
    pub fn token(&self) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{}/{}/{}/NN/%/{}/{}",
            self.name.domain,
            self.zid,
            self.id,
            self.id,
            mangle(&self.name.namespace),
            self.name.name
        )
    }

    /// Topic `fq_topic` (fully qualified) of type `ty`, as the node's entity `entity_id`.
    pub fn entity(
        &self,
        entity_id: u64,
        kind: EntityKind,
        fq_topic: &str,
        ty: &MessageType,
        qos: Qos,
    ) -> Entity {
        let (dds, hash) = (dds_type_name(ty), type_hash(ty));
        let kind = match kind {
            EntityKind::Publisher => "MP",
            EntityKind::Subscription => "MS",
        };
        let n = &self.name;
        Entity {
            key: format!(
                "{}/{}/{dds}/{hash}",
                n.domain,
                fq_topic.trim_start_matches('/')
            ),
            token: format!(
                "{ADMIN_SPACE}/{}/{}/{}/{entity_id}/{kind}/%/{}/{}/{}/{dds}/{hash}/{}",
                n.domain,
                self.zid,
                self.id,
                mangle(&n.namespace),
                n.name,
                mangle(fq_topic),
                qos.encode()
            ),
        }
    }
}

/// A publisher or a subscription.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityKind {
    /// Publishes on the topic (token kind `MP`).
    Publisher,
    /// Subscribes to the topic (token kind `MS`).
    Subscription,
}

/// The QoS a token declares: reliable or best effort, volatile, keep the last `depth`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Qos {
    /// Reliable delivery, ROS 2's default (an empty reliability policy in the token).
    Reliable {
        /// Messages kept (history depth, keep last).
        depth: u32,
    },
    /// Best effort: messages may be lost (reliability `2` in the token).
    BestEffort {
        /// Messages kept (history depth, keep last).
        depth: u32,
    },
}

impl Qos {
    /// rmw_zenoh's QoS text: `reliability:durability:history,depth:deadline:lifespan:
    /// liveliness`, each policy empty where it is the default (reliable, volatile, keep last,
    /// infinite durations, automatic liveliness), best effort `2`; depth always written.
    pub fn encode(self) -> String {
        let (reliability, depth) = match self {
            Qos::Reliable { depth } => ("", depth),
            Qos::BestEffort { depth } => ("2", depth),
        };
        format!("{reliability}::,{depth}:,:,:,,")
    }
}

/// A publisher's or subscription's topic: its key expression and its liveliness token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entity {
    /// The key expression its messages are put on: `<domain>/<topic>/<type>/<hash>`.
    pub key: String,
    /// Its liveliness token, which announces it to ROS 2 discovery.
    pub token: String,
}

/// An entity's GID, 16 bytes unique to its token. rmw_zenoh takes the XXH3-128 of the token;
/// peers only compare GIDs, so the first 16 bytes of its SHA-256 serve as well.
pub fn gid(token: &str) -> [u8; 16] {
    use sha2::{Digest, Sha256};
    let d = Sha256::digest(token.as_bytes());
    d[..16].try_into().expect("16 of 32 bytes")
}

/// The attachment of a message: sequence number, source timestamp (ns since the Unix epoch) and
/// the publisher's GID, in Zenoh's serialization (integers little endian, the array after its
/// length as a varint, 16 = one byte 0x10).
pub fn attachment(seq: i64, stamp_ns: i64, gid: &[u8; 16]) -> [u8; 33] {
    let mut out = [0u8; 33];
    out[..8].copy_from_slice(&seq.to_le_bytes());
    out[8..16].copy_from_slice(&stamp_ns.to_le_bytes());
    out[16] = 16;
    out[17..].copy_from_slice(gid);
    out
}

/// An attachment read back: (sequence number, source timestamp, GID).
pub fn parse_attachment(b: &[u8]) -> Result<(i64, i64, [u8; 16]), NotAnAttachment> {
    if b.len() != 33 || b[16] != 16 {
        return Err(NotAnAttachment { len: b.len() });
    }
    let i64_at = |at: usize| i64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"));
    Ok((i64_at(0), i64_at(8), b[17..].try_into().expect("16 bytes")))
}

/// Bytes that are not an rmw_zenoh attachment (33 bytes: seq, stamp, 16, gid).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotAnAttachment {
    /// How many bytes there were.
    pub len: usize,
}

impl std::fmt::Display for NotAnAttachment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "an rmw_zenoh attachment is 33 bytes (seq, stamp, 16, gid), not these {}",
            self.len
        )
    }
}

impl std::error::Error for NotAnAttachment {}

#[cfg(test)]
mod tests {
    use super::super::{FLOAT64_MULTI_ARRAY, JOINT_STATE};
    use super::*;

    /// The forms rmw_zenoh's design document gives (its `chatter` example), with the types and
    /// hashes of this module's own.
    #[test]
    fn keys_and_tokens_have_rmw_zenohs_form() {
        let name = NodeName::new(0, "/", "talker").unwrap();
        let node = Node {
            name: name.clone(),
            zid: "aac3178e146ba6f1fc6e6a4085e77f21".into(),
            id: 0,
        };
        assert_eq!(
            node.token(),
            "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/talker"
        );
        let node = Node {
            zid: "aac3".into(),
            ..node
        };
        let e = node.entity(
            10,
            EntityKind::Publisher,
            &name.topic("joint_states").unwrap(),
            &JOINT_STATE,
            Qos::Reliable { depth: 7 },
        );
        let hash = "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e";
        assert_eq!(
            e.key,
            format!("0/joint_states/sensor_msgs::msg::dds_::JointState_/{hash}")
        );
        assert_eq!(
            e.token,
            format!("@ros2_lv/0/aac3/0/10/MP/%/%/talker/%joint_states/sensor_msgs::msg::dds_::JointState_/{hash}/::,7:,:,:,,")
        );
        let ns = NodeName::new(3, "/robot/arm/", "evoloop").unwrap();
        assert_eq!(ns.namespace, "/robot/arm");
        assert_eq!(ns.topic("set_gains").unwrap(), "/robot/arm/set_gains");
        let node = Node {
            name: ns.clone(),
            zid: "z".into(),
            id: 1,
        };
        let e = node.entity(
            2,
            EntityKind::Subscription,
            &ns.topic("set_gains").unwrap(),
            &FLOAT64_MULTI_ARRAY,
            Qos::BestEffort { depth: 1 },
        );
        assert!(e.key.starts_with(
            "3/robot/arm/set_gains/std_msgs::msg::dds_::Float64MultiArray_/RIHS01_1025dd"
        ));
        assert!(e
            .token
            .starts_with("@ros2_lv/3/z/1/2/MS/%/%robot%arm/evoloop/%robot%arm%set_gains/"));
        assert!(e.token.ends_with("/2::,1:,:,:,,"));
    }

    #[test]
    fn names_are_checked_as_ros_2_checks_them() {
        let token = |what, token: &str| NameError::Token {
            what,
            token: token.into(),
        };
        let ns = NameError::Namespace("evoloop".into());
        assert_eq!(NodeName::new(0, "evoloop", "n"), Err(ns));
        assert_eq!(
            NodeName::new(0, "/a-b", "n"),
            Err(token("namespace part", "a-b"))
        );
        assert_eq!(NodeName::new(0, "/", "1n"), Err(token("node name", "1n")));
        assert_eq!(NodeName::new(233, "/", "n"), Err(NameError::Domain(233)));
        let n = NodeName::new(0, "/", "n").unwrap();
        assert_eq!(n.topic("a//b"), Err(token("topic name part", "")));
        let e = n.topic("a-b").unwrap_err().to_string();
        assert_eq!(
            e,
            "topic name part `a-b`: a ROS 2 name is a letter or '_' then letters, digits or '_'"
        );
        assert_eq!(n.topic("a/b").unwrap(), "/a/b");
    }

    /// Zenoh's serialization of (i64, i64, [u8; 16]), worked by hand from its rules.
    #[test]
    fn the_attachment_is_zenohs_serialization() {
        let gid = [0xab; 16];
        let a = attachment(7, 0x0102_0304_0506_0708, &gid);
        let mut expect = 7i64.to_le_bytes().to_vec();
        expect.extend(0x0102_0304_0506_0708i64.to_le_bytes());
        expect.push(0x10);
        expect.extend(gid);
        assert_eq!(a.to_vec(), expect);
        assert_eq!(
            parse_attachment(&a).unwrap(),
            (7, 0x0102_0304_0506_0708, gid)
        );
        assert!(parse_attachment(&a[..32]).is_err());
        assert_ne!(super::gid("a"), super::gid("b"));
    }
}
