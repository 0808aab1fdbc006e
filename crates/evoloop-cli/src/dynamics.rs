//! `evoloop dynamics`: inverse and forward dynamics of a robot file at one state.

use clap::Args;
use evoloop_dynamics::Model;
use nalgebra::DMatrix;
use serde_json::json;
use std::path::PathBuf;

/// Options of `evoloop dynamics`: a robot file and one state, at which it prints
/// tau = M qdd + V + G + F and its terms, and, given `--tau`, the forward dynamics.
#[derive(Args)]
#[command(
    allow_negative_numbers = true,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct DynamicsArgs {
    /// `evoloop dynamics regressor`, if given; otherwise the dynamics at `state`.
    #[command(subcommand)]
    pub cmd: Option<DynamicsCmd>,
    /// Robot description: a D-H table (.toml) or a URDF file (.urdf).
    #[arg(long, required = true)]
    pub robot: Option<PathBuf>,
    /// The joint positions, velocities and accelerations to evaluate at.
    #[command(flatten)]
    pub state: State,
    /// Joint torques/forces: also print the forward dynamics qdd = M^-1 (tau - V - G - F).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub tau: Option<Vec<f64>>,
    /// Rigid-body quantities only: drop joint friction and damping (URDF `<dynamics>`, D-H
    /// `viscous`/`coulomb`), as Pinocchio, RBDL or KDL print them.
    #[arg(long)]
    pub no_friction: bool,
    /// Refuse a file that is only physically dubious (zero-mass links with inertia, inertia
    /// violating the triangle inequality, mimic joints) instead of warning about it.
    #[arg(long)]
    pub strict: bool,
    /// Print JSON (keys joints, tau, M, G, V, F, C, friction_included, warnings and, given
    /// --tau, qdd).
    #[arg(long)]
    pub json: bool,
}

/// The state a dynamics quantity is evaluated at.
#[derive(Args)]
pub struct State {
    /// Joint positions, comma separated (rad or m), in the file's joint order [default: zeros].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub q: Option<Vec<f64>>,
    /// Joint velocities [default: zeros].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub qd: Option<Vec<f64>>,
    /// Joint accelerations [default: zeros].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub qdd: Option<Vec<f64>>,
}

/// The subcommands of `evoloop dynamics`.
#[derive(clap::Subcommand)]
pub enum DynamicsCmd {
    /// The joint-torque regressor Y(q, qd, qdd), tau = Y pi: 10 inertial parameters per body,
    /// bodies base to tip, each m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz (inertia about the
    /// joint frame: Pinocchio's order), then with --friction fv, fc per joint.
    Regressor(RegressorArgs),
}

/// Options of `evoloop dynamics regressor`: the joint-torque regressor Y(q, qd, qdd) of a robot
/// file at one state.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct RegressorArgs {
    /// Robot description: a D-H table (.toml) or a URDF file (.urdf).
    #[arg(long)]
    pub robot: PathBuf,
    /// The joint positions, velocities and accelerations the regressor is evaluated at.
    #[command(flatten)]
    pub state: State,
    /// Add the friction columns (viscous, Coulomb) after the rigid-body ones.
    #[arg(long)]
    pub friction: bool,
    /// Refuse a physically dubious file instead of warning about it.
    #[arg(long)]
    pub strict: bool,
    /// Print JSON (keys Y (rows = joints), parameters, pi, tau, joints, armature).
    #[arg(long)]
    pub json: bool,
}

fn vector(name: &str, v: Option<Vec<f64>>, n: usize) -> Result<Vec<f64>, String> {
    let v = v.unwrap_or_else(|| vec![0.0; n]);
    if v.len() != n {
        return Err(format!(
            "--{name} needs {n} values (one per joint), got {}",
            v.len()
        ));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(format!("--{name}[{i}] is not a finite number"));
    }
    Ok(v)
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect())
        .collect()
}

/// Everything `evoloop dynamics` prints, computed by the library's algorithms.
pub struct Evaluation {
    /// Inverse dynamics tau = M qdd + V + G + F per joint (N m, or N for a prismatic joint).
    pub tau: Vec<f64>,
    /// Joint-space inertia matrix M(q), n x n for n joints.
    pub m: DMatrix<f64>,
    /// Gravity vector G(q), one entry per joint.
    pub g: Vec<f64>,
    /// Centrifugal and Coriolis vector V(q, qd), one entry per joint.
    pub v: Vec<f64>,
    /// Joint friction and damping F(qd), one entry per joint (zeros when the file gives none or
    /// `--no-friction` dropped it).
    pub f: Vec<f64>,
    /// Coriolis matrix C(q, qd), with V = C qd.
    pub c: DMatrix<f64>,
    /// Forward dynamics qdd = M^-1 (tau - V - G - F) for the given torques; `None` without `--tau`.
    pub qdd: Option<Vec<f64>>,
}

/// Evaluate `model` at the state (`q`, `qd`, `qdd`): tau, M, G, V, F and C, and, given `tau_in`,
/// the forward dynamics. Slices have one entry per joint.
///
/// # Errors
///
/// A message when M(q) is not positive definite (forward dynamics only) or when a result is not
/// finite.
pub fn evaluate(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    tau_in: Option<&[f64]>,
) -> Result<Evaluation, String> {
    let n = model.dof();
    let mut d = model.data();
    let mut tau = vec![0.0; n];
    model.inverse_dynamics(&mut d, q, qd, qdd, &mut tau);
    let m = model.mass_matrix(&mut d, q).clone();
    let mut g = vec![0.0; n];
    model.gravity_torque(&mut d, q, &mut g);
    let mut v = vec![0.0; n];
    model.coriolis(&mut d, q, qd, &mut v);
    let mut f = vec![0.0; n];
    model.friction(qd, &mut f);
    let mut c = DMatrix::zeros(n, n);
    model.coriolis_matrix(&mut d, q, qd, &mut c);
    let qdd_out = match tau_in {
        Some(t) => {
            let mut out = vec![0.0; n];
            model
                .forward_dynamics(&mut d, q, qd, t, &mut out)
                .map_err(|e| {
                    format!(
                        "M(q) is not positive definite at this q (joint {})",
                        e.joint
                    )
                })?;
            Some(out)
        }
        None => None,
    };
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if !(finite(&tau)
        && finite(m.as_slice())
        && finite(&g)
        && finite(&v)
        && finite(&f)
        && finite(c.as_slice())
        && qdd_out.as_deref().is_none_or(finite))
    {
        return Err(
            "the result is not finite: an input or one of the robot's parameters is so \
                    large that the dynamics overflow (f64)"
                .into(),
        );
    }
    Ok(Evaluation {
        tau,
        m,
        g,
        v,
        f,
        c,
        qdd: qdd_out,
    })
}

/// `evoloop dynamics` (and its `regressor` subcommand): print the dynamics as text or JSON.
/// Returns the exit code: 0, or 2 with the error on stderr.
pub fn main(a: DynamicsArgs) -> i32 {
    let usage = |msg: &str| {
        eprintln!("evoloop dynamics: {msg}");
        2
    };
    if let Some(DynamicsCmd::Regressor(r)) = a.cmd {
        return match regressor(r) {
            Ok(()) => 0,
            Err(e) => usage(&e),
        };
    }
    let Some(robot) = a.robot else {
        return usage("--robot FILE is required");
    };
    let options = evoloop_dynamics::LoadOptions {
        strict: a.strict,
        rigid_body_only: a.no_friction,
    };
    let (model, warnings) = match evoloop_dynamics::load_with(&robot, &options) {
        Ok(l) => (l.model, l.warnings),
        Err(e) => return usage(&e.to_string()),
    };
    for w in &warnings {
        eprintln!("evoloop dynamics: warning: {}: {w}", robot.display());
    }
    let friction_included = model.has_friction();
    let friction_note = match (friction_included, a.no_friction) {
        (true, _) => "F(qd) includes the file's joint friction and damping (--no-friction for rigid-body only)",
        (false, true) => "rigid body only: joint friction and damping dropped (--no-friction)",
        (false, false) => "rigid body only: the file gives no joint friction or damping",
    };
    let n = model.dof();
    let q = match vector("q", a.state.q, n) {
        Ok(v) => v,
        Err(e) => return usage(&e),
    };
    let qd = match vector("qd", a.state.qd, n) {
        Ok(v) => v,
        Err(e) => return usage(&e),
    };
    let qdd = match vector("qdd", a.state.qdd, n) {
        Ok(v) => v,
        Err(e) => return usage(&e),
    };
    let tau_in = match a.tau {
        Some(t) => match vector("tau", Some(t), n) {
            Ok(v) => Some(v),
            Err(e) => return usage(&e),
        },
        None => None,
    };
    let ev = match evaluate(&model, &q, &qd, &qdd, tau_in.as_deref()) {
        Ok(e) => e,
        Err(e) => return usage(&e),
    };
    let joints: Vec<&str> = model.bodies.iter().map(|b| b.joint.as_str()).collect();
    if a.json {
        let mut out = json!({
            "robot": model.name,
            "joints": joints,
            "gravity": [model.gravity.x, model.gravity.y, model.gravity.z],
            "q": q, "qd": qd, "qdd_in": qdd,
            "tau": ev.tau,
            "M": rows(&ev.m),
            "G": ev.g,
            "V": ev.v,
            "F": ev.f,
            "C": rows(&ev.c),
            "friction_included": friction_included,
            "warnings": warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        });
        if let Some(x) = &ev.qdd {
            out["qdd"] = json!(x);
            out["tau_in"] = json!(tau_in);
        }
        out!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain numbers serialise")
        );
        return 0;
    }
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:>12.6}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    out!(
        "robot {} ({} joints: {}), gravity {:?} m/s^2, SI units",
        model.name,
        n,
        joints.join(", "),
        model.gravity.to_array()
    );
    out!("{friction_note}");
    out!("tau = M qdd + V + G + F:\n  {}", fmt(&ev.tau));
    out!("M(q):");
    for i in 0..n {
        out!("  {}", fmt(&rows(&ev.m)[i]));
    }
    out!("G(q):\n  {}", fmt(&ev.g));
    out!("V(q, qd):\n  {}", fmt(&ev.v));
    out!("F(qd):\n  {}", fmt(&ev.f));
    if let Some(x) = &ev.qdd {
        out!(
            "forward dynamics qdd = M^-1 (tau - V - G - F) for the given tau:\n  {}",
            fmt(x)
        );
    }
    0
}

/// `evoloop dynamics regressor`.
fn regressor(a: RegressorArgs) -> Result<(), String> {
    let options = evoloop_dynamics::LoadOptions {
        strict: a.strict,
        rigid_body_only: false,
    };
    let loaded = evoloop_dynamics::load_with(&a.robot, &options).map_err(|e| e.to_string())?;
    for w in &loaded.warnings {
        eprintln!("evoloop dynamics: warning: {}: {w}", a.robot.display());
    }
    let model = loaded.model;
    let n = model.dof();
    let q = vector("q", a.state.q, n)?;
    let qd = vector("qd", a.state.qd, n)?;
    let qdd = vector("qdd", a.state.qdd, n)?;
    let mut d = model.data();
    let mut y = DMatrix::zeros(n, model.regressor_columns(a.friction));
    model.regressor(&mut d, &q, &qd, &qdd, &mut y);
    let names = model.parameter_names(a.friction);
    let pi = model.parameters(a.friction);
    let armature: Vec<f64> = model.bodies.iter().map(|b| b.armature).collect();
    // tau = Y pi + armature qdd: the model's inverse dynamics (rigid body, or with friction).
    let tau: Vec<f64> = (0..n)
        .map(|j| (0..pi.len()).map(|c| y[(j, c)] * pi[c]).sum::<f64>() + armature[j] * qdd[j])
        .collect();
    let joints: Vec<&str> = model.bodies.iter().map(|b| b.joint.as_str()).collect();
    if a.json {
        super::print_json(&json!({
            "robot": model.name, "joints": joints, "q": q, "qd": qd, "qdd": qdd,
            "parameters": names, "pi": pi, "Y": rows(&y), "tau": tau, "armature": armature,
            "friction_columns": a.friction,
        }));
        return Ok(());
    }
    out!(
        "robot {} ({n} joints: {}): Y is {n} x {}, tau = Y pi{}",
        model.name,
        joints.join(", "),
        y.ncols(),
        if armature.iter().any(|x| *x != 0.0) {
            " + armature qdd"
        } else {
            ""
        }
    );
    out!("one line per parameter: name, the file's value, then its column of Y (one entry per joint)");
    for (c, name) in names.iter().enumerate() {
        let column: Vec<String> = (0..n).map(|j| format!("{:>11.5}", y[(j, c)])).collect();
        out!("  {name:>6} {:>11.5} | {}", pi[c], column.join(" "));
    }
    let tau: Vec<String> = tau.iter().map(|t| format!("{t:>11.5}")).collect();
    out!("  {:>6} {:>11} | {}", "tau", "", tau.join(" "));
    Ok(())
}
