//! One message on the network: `EVL1`, the payload's size (u32, little-endian), the length of the
//! type's versioned name (u8), the name, then the message's bytes as they are in shared memory.
//!
//! The bytes are the sender's in-memory layout (little-endian on every platform evoloop builds
//! for). The receiver checks the magic, the name (which carries the layout version, see
//! `crate::ipc`) and the size before it reads anything: a message of another build or another
//! type is refused, never misread.

use iceoryx2::prelude::ZeroCopySend;

const MAGIC: &[u8; 4] = b"EVL1";

// Every message type is fields of 8 and 4 bytes in an order that leaves no padding, so its
// bytes are all initialised and any bit pattern read back is a valid value (u64, u32, f64).
const _: () = {
    use crate::msg::*;
    use crate::msg::{MAX_JOINTS as J, MAX_PARAMS as P, MAX_STATES as S};
    use std::mem::size_of;
    assert!(size_of::<PlantState>() == 3 * 8 + 4 * 4 + (S + 4 * J) * 8);
    assert!(size_of::<Command>() == 4 * 8 + 2 * 4 + J * 8);
    assert!(
        size_of::<Telemetry>()
            == 8 * 8 + 2 * 4 + J * 8 + 2 * 8 + 2 * 4 + 2 * 8 + 2 * 4 + MAX_LAW_VALUES * 8
    );
    assert!(size_of::<ParamSet>() == 5 * 8 + 2 * 4 + P * 8);
    assert!(size_of::<ModelEstimate>() == 5 * 8);
    assert!(size_of::<OptimiserStatus>() == 5 * 8);
    assert!(size_of::<OptimiserAck>() == 8);
};

fn type_name<T: ZeroCopySend>() -> &'static str {
    // SAFETY: reads a name; the types' names are set in `crate::ipc`.
    unsafe { <T as ZeroCopySend>::type_name() }
}

/// The message's wire bytes (header and payload).
pub fn encode<T: ZeroCopySend + Copy>(value: &T) -> Vec<u8> {
    let name = type_name::<T>().as_bytes();
    let size = std::mem::size_of::<T>();
    let mut out = Vec::with_capacity(4 + 4 + 1 + name.len() + size);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(size as u32).to_le_bytes());
    out.push(name.len() as u8);
    out.extend_from_slice(name);
    // SAFETY: T is plain data without padding (checked above): all `size` bytes initialised.
    let bytes = unsafe { std::slice::from_raw_parts(value as *const T as *const u8, size) };
    out.extend_from_slice(bytes);
    out
}

/// Why bytes from the network are not a message of this build.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WireError {
    /// No evoloop header (another program's message on the key).
    NoHeader {
        /// The type expected.
        expected: &'static str,
    },
    /// The header is cut short.
    CutShort {
        /// The type expected.
        expected: &'static str,
    },
    /// The sender's message is of another type.
    Type {
        /// The type expected.
        expected: &'static str,
        /// The sender's.
        theirs: String,
    },
    /// The same type, another size (another build's layout).
    Size {
        /// The type expected.
        expected: &'static str,
        /// The payload's bytes.
        theirs: usize,
        /// This build's.
        ours: usize,
    },
}

impl std::fmt::Display for WireError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WireError::NoHeader { expected } => write!(f, "not a {expected}: no evoloop header"),
            WireError::CutShort { expected } => write!(f, "not a {expected}: header cut short"),
            WireError::Type { expected, theirs } => {
                write!(f, "not a {expected}: the sender's type is {theirs:?}")
            }
            WireError::Size {
                expected,
                theirs,
                ours,
            } => write!(
                f,
                "not a {expected}: {theirs} bytes where this build has {ours}"
            ),
        }
    }
}

impl std::error::Error for WireError {}

/// The message in `bytes`, or why it is not a `T` of this build.
pub fn decode<T: ZeroCopySend + Copy>(bytes: &[u8]) -> Result<T, WireError> {
    let expected = type_name::<T>();
    let size = std::mem::size_of::<T>();
    if bytes.len() < 9 || &bytes[..4] != MAGIC {
        return Err(WireError::NoHeader { expected });
    }
    let their_size = u32::from_le_bytes(bytes[4..8].try_into().expect("4 bytes")) as usize;
    let n = bytes[8] as usize;
    let Some(their_name) = bytes.get(9..9 + n) else {
        return Err(WireError::CutShort { expected });
    };
    if their_name != expected.as_bytes() {
        let theirs = String::from_utf8_lossy(their_name).into_owned();
        return Err(WireError::Type { expected, theirs });
    }
    let payload = &bytes[9 + n..];
    if their_size != size || payload.len() != size {
        return Err(WireError::Size {
            expected,
            theirs: payload.len(),
            ours: size,
        });
    }
    // SAFETY: exactly size_of::<T>() bytes; every bit pattern is a valid T (fields are u64,
    // u32 and f64 only); read_unaligned because a network buffer has no alignment.
    Ok(unsafe { std::ptr::read_unaligned(payload.as_ptr() as *const T) })
}
