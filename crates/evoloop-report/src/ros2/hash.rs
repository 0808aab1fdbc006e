//! ROS 2 type hashes (REP-2016, `RIHS01_` + the SHA-256 of a type's description), computed from
//! the same `ros2msg` definitions the recording's schemas carry, so a type has one definition.
//!
//! rmw_zenoh puts the hash in every key expression and liveliness token: a peer built from
//! another definition of the same name does not match. The description hashed is the type's
//! fields (name, type id, capacities, nested type), then every type it refers to, directly or
//! not, sorted by name; comments, constants and default values are not part of it. It is
//! written as Python's `json.dumps(..., separators=(', ', ': '))` writes it, which is how
//! `rosidl_generator_type_description` and rcl compute it.

use super::{MessageType, SEPARATOR};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;

/// REP-2016's field type ids (`type_description_interfaces/msg/FieldType`).
const NESTED: u8 = 1;
const STRING: u8 = 17;
const BOUNDED_STRING: u8 = 21;
/// Added to an element's id for an array of fixed size, a bounded and an unbounded sequence.
const ARRAY: u8 = 48;
const BOUNDED_SEQUENCE: u8 = 96;
const UNBOUNDED_SEQUENCE: u8 = 144;

fn primitive(name: &str) -> Option<u8> {
    Some(match name {
        "int8" => 2,
        "uint8" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "char" => 13,
        "wchar" => 14,
        "bool" => 15,
        "byte" => 16,
        "string" => STRING,
        "wstring" => 18,
        _ => return None,
    })
}

#[derive(Debug, Clone, PartialEq)]
struct FieldType {
    id: u8,
    capacity: u64,
    string_capacity: u64,
    nested: String,
}

/// A definition's fields, by the fully qualified names of the types (`pkg/msg/Type`).
type Fields = Vec<(String, FieldType)>;

/// `pkg/Type` or `pkg/msg/Type` as `pkg/msg/Type`; a bare `Type` is in `package`'s (`Header`
/// alone is `std_msgs`', as ROS 2 reads it).
fn qualified(name: &str, package: &str) -> String {
    let parts: Vec<&str> = name.split('/').collect();
    match parts.as_slice() {
        [pkg, "msg", ty] => format!("{pkg}/msg/{ty}"),
        [pkg, ty] => format!("{pkg}/msg/{ty}"),
        ["Header"] => "std_msgs/msg/Header".into(),
        _ => format!("{package}/msg/{name}"),
    }
}

/// One field's type from its token in a definition (`float64[]`, `string<=8`, `Header`, ...).
fn field_type(token: &str, package: &str) -> Result<FieldType, String> {
    let (base, array) = match token.find('[') {
        Some(at) => (&token[..at], Some(&token[at..])),
        None => (token, None),
    };
    let number = |s: &str| {
        s.parse::<u64>()
            .map_err(|_| format!("`{token}`: `{s}` is not a size"))
    };
    let scalar = |id, nested: String| FieldType {
        id,
        capacity: 0,
        string_capacity: 0,
        nested,
    };
    let mut ty = match base.split_once("<=") {
        Some(("string", n)) => FieldType {
            string_capacity: number(n)?,
            ..scalar(BOUNDED_STRING, String::new())
        },
        Some(_) => return Err(format!("`{token}`: only strings take a bound")),
        None => match primitive(base) {
            Some(id) => scalar(id, String::new()),
            None => scalar(NESTED, qualified(base, package)),
        },
    };
    match array {
        None => {}
        Some("[]") => ty.id += UNBOUNDED_SEQUENCE,
        Some(a) => {
            let inner = a
                .strip_prefix('[')
                .and_then(|a| a.strip_suffix(']'))
                .ok_or_else(|| format!("`{token}`: not an array type"))?;
            match inner.strip_prefix("<=") {
                Some(n) => {
                    ty.id += BOUNDED_SEQUENCE;
                    ty.capacity = number(n)?;
                }
                None => {
                    ty.id += ARRAY;
                    ty.capacity = number(inner)?;
                }
            }
        }
    }
    Ok(ty)
}

/// The fields of one definition (comments and constants skipped).
fn fields(text: &str, package: &str) -> Result<Fields, String> {
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        let mut words = line.split_whitespace();
        let (Some(ty), Some(name)) = (words.next(), words.next()) else {
            continue;
        };
        // `TYPE NAME=VALUE` (or `NAME = VALUE`) is a constant, not a field.
        if name.contains('=') || words.next().is_some_and(|w| w.starts_with('=')) {
            continue;
        }
        out.push((name.to_string(), field_type(ty, package)?));
    }
    if out.is_empty() {
        // rosidl gives an empty message this one member.
        out.push((
            "structure_needs_at_least_one_member".into(),
            field_type("uint8", package)?,
        ));
    }
    Ok(out)
}

fn package(qualified_name: &str) -> &str {
    qualified_name.split('/').next().unwrap_or("")
}

/// Every type `ty`'s schema defines: its own, then each dependency's (`MSG: pkg/Type` heads).
fn definitions(ty: &MessageType) -> Result<BTreeMap<String, Fields>, String> {
    let own = qualified(ty.name, "");
    let mut out = BTreeMap::new();
    out.insert(own.clone(), fields(ty.definition, package(&own))?);
    for part in ty
        .dependencies
        .split(SEPARATOR)
        .filter(|p| !p.trim().is_empty())
    {
        let (head, body) = part.split_once('\n').unwrap_or((part, ""));
        let name = head
            .strip_prefix("MSG: ")
            .ok_or_else(|| "a dependency without its `MSG:` line".to_string())?;
        let name = qualified(name.trim(), "");
        let f = fields(body, package(&name))?;
        out.insert(name, f);
    }
    Ok(out)
}

fn json_string(s: &str, out: &mut String) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 || !c.is_ascii() => {
                let mut units = [0u16; 2];
                for u in c.encode_utf16(&mut units) {
                    out.push_str(&format!("\\u{u:04x}"));
                }
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

fn json_type(name: &str, fields: &Fields, out: &mut String) {
    out.push_str("{\"type_name\": ");
    json_string(name, out);
    out.push_str(", \"fields\": [");
    for (i, (field, ty)) in fields.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str("{\"name\": ");
        json_string(field, out);
        out.push_str(&format!(
            ", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \"nested_type_name\": ",
            ty.id, ty.capacity, ty.string_capacity
        ));
        json_string(&ty.nested, out);
        out.push_str("}}");
    }
    out.push_str("]}");
}

/// A message type whose definition does not parse as a ROS 2 `.msg` (evoloop's own always do).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DefinitionError {
    /// The type, `pkg/msg/Type`.
    pub type_name: &'static str,
    /// What does not parse.
    pub reason: String,
}

impl std::fmt::Display for DefinitionError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.type_name, self.reason)
    }
}

impl std::error::Error for DefinitionError {}

/// The description REP-2016 hashes, as the text hashed.
pub fn hashed_description(ty: &MessageType) -> Result<String, DefinitionError> {
    let refused = |reason| DefinitionError {
        type_name: ty.name,
        reason,
    };
    let defs = definitions(ty).map_err(refused)?;
    let own = qualified(ty.name, "");
    // The types referred to, directly or through another, by name (the map's order).
    let mut referenced = std::collections::BTreeSet::new();
    let mut todo = vec![own.clone()];
    while let Some(name) = todo.pop() {
        let f = defs
            .get(&name)
            .ok_or_else(|| refused(format!("`{name}` is used but not defined")))?;
        for (_, t) in f {
            if t.id % ARRAY == NESTED && referenced.insert(t.nested.clone()) {
                todo.push(t.nested.clone());
            }
        }
    }
    let mut out = String::from("{\"type_description\": ");
    json_type(&own, &defs[&own], &mut out);
    out.push_str(", \"referenced_type_descriptions\": [");
    for (i, name) in referenced.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        json_type(name, &defs[name], &mut out);
    }
    out.push_str("]}");
    Ok(out)
}

/// The type's `RIHS01_...` hash.
pub fn type_hash(ty: &MessageType) -> String {
    let text = hashed_description(ty).unwrap_or_else(|e| panic!("evoloop's own definition: {e}"));
    let digest = Sha256::digest(text.as_bytes());
    let mut out = String::with_capacity(71);
    out.push_str("RIHS01_");
    for b in digest {
        out.push_str(&format!("{b:02x}"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;

    /// The hashes of the standard types, as ROS 2 Jazzy has them: each is printed by
    /// `ros2 topic info --verbose` and is in rmw_zenoh's key expressions; the same values come
    /// from an independent implementation, rosbags 0.11.9 (`get_typestore(Stores.ROS2_JAZZY)
    /// .hash_rihs01(name)`).
    #[test]
    fn standard_types_hash_as_ros_2s() {
        for (ty, hash) in [
            (
                JOINT_STATE,
                "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
            ),
            (
                FLOAT64_MULTI_ARRAY,
                "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
            ),
            (
                SET_PARAMETERS_RESULT,
                "RIHS01_cfcc0fb0371ee5159b403960ef4300f8f9d2f1fd6117c8666b7f9654d528a9b1",
            ),
        ] {
            assert_eq!(type_hash(&ty), hash, "{}", ty.name);
        }
        let string = MessageType {
            name: "std_msgs/msg/String",
            definition: "string data\n",
            dependencies: "",
        };
        assert_eq!(
            type_hash(&string),
            "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
        );
        let time = MessageType {
            name: "builtin_interfaces/msg/Time",
            definition: "int32 sec\nuint32 nanosec\n",
            dependencies: "",
        };
        assert_eq!(
            type_hash(&time),
            "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197"
        );
    }

    /// evoloop's own types, hashed by rosbags 0.11.9 from the same definitions (registered with
    /// `get_types_from_msg`): a change to a definition changes its hash, and a ROS 2 peer built
    /// from the old one no longer matches, so this test says so.
    #[test]
    fn evoloops_types_hash_as_rosbags_does() {
        for (ty, hash) in EVOLOOP_HASHES {
            let ty = TOPICS
                .iter()
                .map(|(_, t)| *t)
                .find(|t| t.name == ty)
                .expect("a run topic");
            assert_eq!(type_hash(&ty), hash, "{}", ty.name);
        }
    }

    const EVOLOOP_HASHES: [(&str, &str); 6] = [
        (
            "evoloop_msgs/msg/PlantState",
            "RIHS01_bf30d88f9cf516e691d27dda51b3dcfd25cae6cf81e6ce2435318c2836381ed6",
        ),
        (
            "evoloop_msgs/msg/Command",
            "RIHS01_b3fdb42f0c19cc6fc3b99c61d470cceccf68177a0f53aaf1d1fd23fb352ddade",
        ),
        (
            "evoloop_msgs/msg/Telemetry",
            "RIHS01_4fb19e71b9f22cf8d43f99cde9841c0d390ed3ae07ee019aa171690c6074954c",
        ),
        (
            "evoloop_msgs/msg/ParamSet",
            "RIHS01_ed071dc3c2027c0a5728d6300b04cbf225bae64bcea5b334a905a095033c653b",
        ),
        (
            "evoloop_msgs/msg/ModelEstimate",
            "RIHS01_13c02312901363e09f9ca1c2a3d8a0a76f1608e70274a096074462de918ddb40",
        ),
        (
            "evoloop_msgs/msg/LinearEstimate",
            "RIHS01_ca007b0227752a90d985186266dbf77a07006cdd856126c8cf75524aef3e17f8",
        ),
    ];

    #[test]
    fn field_types_are_rep_2016s() {
        let t = |s| field_type(s, "p").unwrap();
        assert_eq!((t("float64").id, t("float64[]").id), (11, 155));
        assert_eq!((t("int32[3]").id, t("int32[3]").capacity), (54, 3));
        assert_eq!((t("uint8[<=5]").id, t("uint8[<=5]").capacity), (99, 5));
        assert_eq!((t("string<=8").id, t("string<=8").string_capacity), (21, 8));
        assert_eq!(t("Header").nested, "std_msgs/msg/Header");
        assert_eq!(t("Other[]").nested, "p/msg/Other");
        assert_eq!(t("Other[]").id, 145);
        assert!(field_type("int32<=3", "p").is_err());
        assert!(field_type("int32[x]", "p").is_err());
        let f = fields("int32 A=1\nint32 B = 2\nbool x # c\n", "p").unwrap();
        assert_eq!(f.len(), 1);
    }
}
