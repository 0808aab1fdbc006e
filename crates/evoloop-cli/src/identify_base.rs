//! `evoloop identify base`: the base parameters of a robot file.

use clap::Args;
use evoloop_dynamics::base::{base_parameters, TOLERANCE};
use serde_json::json;
use std::path::PathBuf;

/// Options of `evoloop identify base`: the robot file and the random states its regressor is
/// stacked over.
#[derive(Args)]
pub struct BaseArgs {
    /// Robot description: a D-H table (.toml) or a URDF file (.urdf).
    #[arg(long)]
    pub robot: PathBuf,
    /// Include the friction columns (viscous, Coulomb per joint).
    #[arg(long)]
    pub friction: bool,
    /// Random states stacked into the regressor.
    #[arg(long, default_value_t = 100)]
    pub states: usize,
    /// Seed of the random states.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print JSON (keys base_count, base, unidentifiable, combined, regrouping).
    #[arg(long)]
    pub json: bool,
}

/// `evoloop identify base`: print the base parameters, the unidentifiable and the combined ones,
/// and the regrouping. Returns the exit code: 0, or 2 when the file does not load or `--states`
/// is too few for the robot.
pub fn main(a: &BaseArgs) -> i32 {
    let model = match evoloop_dynamics::load(&a.robot) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("evoloop identify base: {e}");
            return 2;
        }
    };
    let need = model.regressor_columns(a.friction).div_ceil(model.dof()) + 1;
    if a.states < need {
        eprintln!(
            "evoloop identify base: --states {}: at least {need} for this robot",
            a.states
        );
        return 2;
    }
    let b = base_parameters(&model, a.friction, a.states, a.seed);
    if a.json {
        super::print_json(&json!({
            "robot": model.name,
            "base_count": b.base_count(),
            "base": b.base.iter().map(|x| x.name.clone()).collect::<Vec<_>>(),
            "unidentifiable": b.unidentifiable,
            "combined": b.combined,
            "regrouping": b.base.iter().map(|x| x.relation()).collect::<Vec<_>>(),
            "base_values": b.base.iter().map(|x| x.value).collect::<Vec<_>>(),
            "parameters": b.names.len(),
            "rows": b.rows,
            "column_norms": b.names.iter().cloned().zip(b.column_norms.iter().map(|v| json!(v)))
                .collect::<serde_json::Map<String, serde_json::Value>>(),
            "tolerance": TOLERANCE,
        }));
        return 0;
    }
    out!(
        "robot {}: {} base parameters of {} ({} unidentifiable, {} only in combination), from {} regressor rows",
        model.name,
        b.base_count(),
        b.names.len(),
        b.unidentifiable.len(),
        b.combined.len(),
        b.rows
    );
    // The paper's procedure as a table: each column's norm (0: unidentifiable) and whether it
    // raised the rank of the columns kept before it (base) or not (combined).
    out!("column norms (over the largest) and class, per body:");
    for (row, chunk) in b.names.chunks(10).enumerate() {
        let cells: Vec<String> = chunk
            .iter()
            .enumerate()
            .map(|(k, name)| {
                let c = row * 10 + k;
                let class = if b.unidentifiable.contains(name) {
                    "u"
                } else if b.combined.contains(name) {
                    "c"
                } else {
                    "B"
                };
                format!("{name}={:.3}{class}", b.column_norms[c])
            })
            .collect();
        out!("  {}", cells.join(" "));
    }
    out!("  (B base, c identifiable only in combination, u unidentifiable)");
    out!("unidentifiable: {}", b.unidentifiable.join(", "));
    out!("base parameters (regrouping; value for the file's parameters):");
    for base in &b.base {
        out!("  {:<60} = {:.6}", base.relation(), base.value);
    }
    0
}
