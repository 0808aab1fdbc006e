//! `evoloop robot`: arms of one's own to try the controllers on (`generate`, `zoo`).

use clap::{Args, Subcommand};
use evoloop_dynamics::generate::{self, Arm, JOINTS};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The subcommands of `evoloop robot`: generated arms to try the controllers on.
#[derive(Subcommand)]
pub enum RobotCmd {
    /// A plausible serial arm from a seed, written as URDF: base yaw, shoulder and elbow, then a
    /// wrist of 0-4 joints (a 7-joint arm has a Panda-like upper-arm roll); link lengths, masses,
    /// inertias, friction and limits drawn in the spread of the arms evoloop ships. The same
    /// seed gives the same file on any machine. Every command that takes `--robot` takes it.
    Generate(GenerateArgs),
    /// Every arm a zoo file lists (`[[arm]] joints = N, seed = S`), written to a directory as
    /// NAME.urdf: the fixed set of unseen arms claims are measured on
    /// (config/robots/zoo.toml).
    Zoo(ZooArgs),
}

/// Options of `evoloop robot generate`: the joint count and seed of the arm, and its URDF file.
#[derive(Args)]
pub struct GenerateArgs {
    /// Number of joints, 3 to 7.
    #[arg(long, value_parser = clap::value_parser!(u8).range(3..=7))]
    pub joints: u8,
    /// The seed the arm is drawn from.
    #[arg(long)]
    pub seed: u64,
    /// The URDF file to write (replaced whole; a link at the name is replaced, not followed).
    #[arg(long)]
    pub out: PathBuf,
}

/// Options of `evoloop robot zoo`: the zoo file and the directory its arms are written to.
#[derive(Args)]
pub struct ZooArgs {
    /// The zoo file.
    #[arg(long, default_value = "config/robots/zoo.toml")]
    pub file: PathBuf,
    /// Directory to write the arms to (made if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// A zoo file: the arms, each by joint count and seed.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Zoo {
    arm: Vec<ZooArm>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ZooArm {
    joints: usize,
    seed: u64,
}

/// `evoloop robot SUBCOMMAND`: write the arm(s) and return the exit code (0, or 2 with the error
/// on stderr).
pub fn main(cmd: RobotCmd) -> i32 {
    let done = match cmd {
        RobotCmd::Generate(a) => generate_one(a),
        RobotCmd::Zoo(a) => zoo(a),
    };
    match done {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop robot: {e}");
            2
        }
    }
}

fn generate_one(a: GenerateArgs) -> Result<(), String> {
    let arm = generate::generate(a.joints.into(), a.seed).map_err(|e| e.to_string())?;
    write(&arm, &a.out)
}

/// The arms of a zoo file, checked whole before any is written.
pub(crate) fn read_zoo(file: &Path) -> Result<Vec<Arm>, String> {
    let text = evoloop_files::read_text(file)
        .map_err(|e| format!("{}: cannot read: {e}", file.display()))?;
    let zoo: Zoo = evoloop_files::from_toml(&text)
        .map_err(|p| format!("{}: key `{}`: {}", file.display(), p.key, p.reason))?;
    let mut seen = std::collections::BTreeSet::new();
    zoo.arm
        .iter()
        .enumerate()
        .map(|(i, z)| {
            let arm = generate::generate(z.joints, z.seed)
                .map_err(|e| format!("{}: key `arm[{i}].joints`: {e}", file.display()))?;
            if !seen.insert(arm.name.clone()) {
                return Err(format!(
                    "{}: key `arm[{i}]`: {} is listed twice",
                    file.display(),
                    arm.name
                ));
            }
            Ok(arm)
        })
        .collect()
}

fn zoo(a: ZooArgs) -> Result<(), String> {
    let arms = read_zoo(&a.file)?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("cannot make {}: {e}", a.out.display()))?;
    for arm in &arms {
        write(arm, &a.out.join(format!("{}.urdf", arm.name)))?;
    }
    out!(
        "{} arms ({} to {} joints) in {}",
        arms.len(),
        arms.iter().map(|a| a.joints.len()).min().unwrap_or(0),
        arms.iter().map(|a| a.joints.len()).max().unwrap_or(0),
        a.out.display()
    );
    Ok(())
}

fn write(arm: &Arm, out: &Path) -> Result<(), String> {
    evoloop_files::write(out, arm.to_urdf()).map_err(|e| e.to_string())?;
    let (mass, reach) = arm.mass_and_reach();
    out!(
        "wrote {} ({}: {} joints, {mass:.2} kg moving, {reach:.2} m from shoulder to tool)",
        out.display(),
        arm.name,
        arm.joints.len()
    );
    Ok(())
}

// `--joints`' range above is the generator's: a change to one fails the build until both agree.
const _: () = assert!(*JOINTS.start() == 3 && *JOINTS.end() == 7);
