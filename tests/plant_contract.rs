//! The plant contract (docs/src/plant-contract.md) gives each message's layout byte by byte: a
//! plant in another language is written from it. This test reads the chapter's tables and checks
//! every field's name, order, offset and size, and each message's size and alignment, against the
//! Rust layouts, so the document cannot drift from what the processes put in shared memory.

use evoloop::msg::{Command, ModelEstimate, OptimiserAck, OptimiserStatus, ParamSet, PlantState};
use evoloop::msg::{Telemetry, CONTRACT};
use std::collections::BTreeMap;
use std::mem::{align_of, offset_of, size_of};

/// (field, type, offset, size) of one message, in declaration order.
type Fields = Vec<(&'static str, &'static str, usize, usize)>;

/// The type name (`f64`, `[f64; 32]`) and size of the field a projection points at.
fn field<T, F>(_: fn(&T) -> &F) -> (&'static str, usize) {
    (std::any::type_name::<F>(), size_of::<F>())
}

macro_rules! layout {
    ($t:ty { $($f:ident),* $(,)? }) => {
        (
            stringify!($t),
            (
                vec![$({
                    let (ty, size) = field(|s: &$t| &s.$f);
                    (stringify!($f), ty, offset_of!($t, $f), size)
                }),*] as Fields,
                size_of::<$t>(),
                align_of::<$t>(),
            ),
        )
    };
}

/// Every message type of the contract, as the compiler lays it out.
fn rust_layouts() -> BTreeMap<&'static str, (Fields, usize, usize)> {
    BTreeMap::from([
        layout!(PlantState {
            seq,
            stamp_ns,
            t,
            n_x,
            n_q,
            n_y,
            flags,
            x_true,
            q_true,
            qd_true,
            y,
            u_applied
        }),
        layout!(Command {
            cycle,
            state_seq,
            stamp_ns,
            param_version,
            n_u,
            _pad,
            u
        }),
        layout!(OptimiserAck { through_seq }),
        layout!(ParamSet {
            version,
            apply_at_seq,
            expected_cost,
            until_seq,
            fallback_version,
            kind,
            n,
            values
        }),
        layout!(ModelEstimate {
            t,
            value,
            std,
            last_version,
            apply_at_seq
        }),
        layout!(OptimiserStatus {
            t,
            epochs,
            published,
            best_cost,
            in_service_cost
        }),
        layout!(Telemetry {
            cycle,
            state_seq,
            t,
            lateness_ns,
            compute_ns,
            state_age_ns,
            reference,
            tracking_error,
            n_u,
            flags,
            u,
            param_version,
            param_event_version,
            param_code,
            param_index,
            overruns,
            missed,
            n_law,
            _pad,
            law,
        }),
    ])
}

/// The chapter's text.
fn chapter() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/src/plant-contract.md");
    std::fs::read_to_string(path).unwrap()
}

/// One documented message: its rows (field, type, offset, size) and its stated (size, alignment).
type Documented = (Vec<(String, String, usize, usize)>, Option<(usize, usize)>);

/// The chapter's message sections: `### Type`, a `| field | type | offset | size | meaning |`
/// table, then "Size: N bytes, alignment: A."
fn documented() -> BTreeMap<String, Documented> {
    let text = chapter();
    let mut out = BTreeMap::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        if line.starts_with("## ") || line.starts_with("# ") {
            // A section above the messages' level ends the message before it.
            current = None;
            continue;
        }
        if let Some(name) = line.strip_prefix("### ") {
            let name = name.trim().trim_matches('`').to_string();
            current = Some(name.clone());
            out.insert(name, (Vec::new(), None));
            continue;
        }
        let Some(name) = &current else { continue };
        let entry = out.get_mut(name).unwrap();
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() >= 6 && cells[0].is_empty() {
            let (field, ty) = (cells[1].trim_matches('`'), cells[2].trim_matches('`'));
            if let (Ok(o), Ok(s)) = (cells[3].parse(), cells[4].parse()) {
                entry.0.push((field.to_string(), ty.to_string(), o, s));
            }
        }
        if let Some(rest) = line.strip_prefix("Size: ") {
            let nums: Vec<usize> = rest
                .split(|c: char| !c.is_ascii_digit())
                .filter_map(|w| w.parse().ok())
                .collect();
            assert_eq!(nums.len(), 2, "{name}: {line}");
            entry.1 = Some((nums[0], nums[1]));
        }
    }
    out
}

#[test]
fn the_documented_layouts_are_the_rust_layouts() {
    let rust = rust_layouts();
    let doc = documented();
    for must in ["PlantState", "Command"] {
        assert!(
            doc.contains_key(must),
            "the plant contract documents no {must}"
        );
    }
    for (name, (fields, size_align)) in &doc {
        let Some((rfields, size, align)) = rust.get(name.as_str()) else {
            // A section that is not a message (e.g. a heading of prose) has no table.
            assert!(
                fields.is_empty(),
                "{name}: a table for a type the contract has not"
            );
            continue;
        };
        let written: Vec<(&str, &str, usize, usize)> = fields
            .iter()
            .map(|(f, t, o, s)| (f.as_str(), t.as_str(), *o, *s))
            .collect();
        assert_eq!(
            &written, rfields,
            "{name}: (field, type, offset, size) as documented vs as built"
        );
        assert_eq!(
            *size_align,
            Some((*size, *align)),
            "{name}: size and alignment"
        );
    }
}

#[test]
fn the_chapter_names_the_contract_version_it_documents() {
    let text = chapter();
    assert!(
        text.contains(&format!("(v{CONTRACT})")),
        "the title names the contract version"
    );
    assert!(text.contains(&format!("evoloop::PlantState.v{CONTRACT}")));
    assert!(text.contains(&format!("evoloop::Command.v{CONTRACT}")));
}
