//! Rigid-body dynamics of serial (and branched) chains of revolute and prismatic joints.
//!
//! - `spatial`: the 6-D motion/force/inertia algebra on glam's 3-D types;
//! - `model`: `Model` (the robot) and `Data` (the buffers), with recursive Newton-Euler inverse
//!   dynamics, the composite-rigid-body inertia matrix M(q), G(q), V(q, qd), the Christoffel
//!   Coriolis matrix C(q, qd), friction F(qd) and forward dynamics by Cholesky;
//! - `dh`: robots from D-H tables in TOML (standard or modified convention);
//! - `urdf`: robots from URDF files (through the `urdf-rs` crate);
//! - `cli`: `evoloop dynamics`.
//!
//! Every algorithm runs in place on a `Data`, so the plant's integrator and the computed-torque
//! controller call them every cycle without allocating.

pub mod cli;
pub mod dh;
pub mod model;
pub mod spatial;
pub mod urdf;

pub use model::{Body, Data, Friction, JointKind, Limits, Model, NotPositiveDefinite};

use glam::{DMat3, DVec3};
use std::fmt;
use std::path::{Path, PathBuf};

/// A robot description that cannot be used: the file, the link or joint, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotError {
    pub file: PathBuf,
    /// "joint `name`" or "link `name`"; empty for file-level errors.
    pub item: String,
    pub reason: String,
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if !self.item.is_empty() {
            write!(f, ": {}", self.item)?;
        }
        write!(f, ": {}", self.reason)
    }
}

impl std::error::Error for RobotError {}

/// Load a robot from a D-H table (`.toml`) or a URDF file (`.urdf`, `.xml`).
pub fn load(path: &Path) -> Result<Model, RobotError> {
    let err = |reason: String| RobotError {
        file: path.to_path_buf(),
        item: String::new(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
    match path.extension().and_then(|e| e.to_str()) {
        Some("toml") => dh::parse(&text, path),
        Some("urdf") | Some("xml") => urdf::parse(&text, path),
        _ => Err(err(
            "unknown robot file type (expected a D-H table `.toml` or a URDF `.urdf`)".into(),
        )),
    }
}

/// The inertia tensor from its six components (URDF order ixx, ixy, ixz, iyy, iyz, izz).
pub fn inertia_tensor(ixx: f64, ixy: f64, ixz: f64, iyy: f64, iyz: f64, izz: f64) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(ixx, ixy, ixz),
        DVec3::new(ixy, iyy, iyz),
        DVec3::new(ixz, iyz, izz),
    )
}

/// Check one link's mass properties: finite, mass >= 0, and a positive-definite inertia tensor
/// obeying the triangle inequality (a physical body) whenever the link has mass. A link with
/// neither mass nor inertia is accepted as massless here; `finish` rejects the model if that
/// leaves a joint moving nothing.
fn check_inertial(mass: f64, i_com: DMat3, com: DVec3) -> Result<(), String> {
    let cols = i_com.to_cols_array();
    if !mass.is_finite() || !com.is_finite() || cols.iter().any(|v| !v.is_finite()) {
        return Err("mass, centre of mass and inertia must be finite numbers".into());
    }
    if mass < 0.0 {
        return Err(format!("negative mass {mass}"));
    }
    let zero_tensor = cols.iter().all(|v| *v == 0.0);
    if mass == 0.0 {
        if !zero_tensor {
            return Err("zero mass with a non-zero inertia tensor".into());
        }
        return Ok(());
    }
    let m = nalgebra::Matrix3::from_fn(|r, c| i_com.col(c)[r]);
    if (m - m.transpose()).abs().max() > 1e-12 * m.abs().max().max(1e-300) {
        return Err("inertia tensor is not symmetric".into());
    }
    let ev = m.symmetric_eigenvalues();
    let (a, b, c) = (ev[0], ev[1], ev[2]);
    if !(a > 0.0 && b > 0.0 && c > 0.0) {
        return Err(format!(
            "inertia tensor is not positive definite (principal moments {a:.6e}, {b:.6e}, {c:.6e})"
        ));
    }
    let tol = 1e-9 * (a + b + c);
    if a > b + c + tol || b > a + c + tol || c > a + b + tol {
        return Err(format!(
            "inertia tensor violates the triangle inequality (principal moments {a:.6e}, {b:.6e}, {c:.6e}): no rigid body has it"
        ));
    }
    Ok(())
}

/// Final checks shared by both loaders: finite placements, unit axes, limits in order, and M(q)
/// positive definite at the middle of the joint ranges (a joint that moves no inertia is named).
fn finish(model: Model, file: &Path) -> Result<Model, RobotError> {
    let fail = |item: String, reason: String| RobotError {
        file: file.to_path_buf(),
        item,
        reason,
    };
    if model.bodies.is_empty() {
        return Err(fail(String::new(), "the robot has no moving joint".into()));
    }
    if model.bodies.len() > crate::MAX_JOINTS {
        return Err(fail(
            String::new(),
            format!(
                "{} moving joints; at most {} are supported",
                model.bodies.len(),
                crate::MAX_JOINTS
            ),
        ));
    }
    for b in &model.bodies {
        let item = format!("joint `{}`", b.joint);
        if b.limits.q_min.partial_cmp(&b.limits.q_max) != Some(std::cmp::Ordering::Less) {
            return Err(fail(
                item,
                format!(
                    "lower limit {} is not below upper limit {}",
                    b.limits.q_min, b.limits.q_max
                ),
            ));
        }
        let positive = |v: f64| v > 0.0; // false for NaN too
        if !positive(b.limits.effort) || !positive(b.limits.velocity) {
            return Err(fail(item, "effort and velocity limits must be > 0".into()));
        }
        let fr = &b.friction;
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        if !(ok(fr.viscous) && ok(fr.coulomb) && ok(b.armature) && fr.v_smooth > 0.0) {
            return Err(fail(
                item,
                "friction (viscous, coulomb), v_smooth and armature must be finite and >= 0 (v_smooth > 0)"
                    .into(),
            ));
        }
    }
    let q: Vec<f64> = model
        .bodies
        .iter()
        .map(|b| {
            let (lo, hi) = (b.limits.q_min, b.limits.q_max);
            if lo.is_finite() && hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                0.0
            }
        })
        .collect();
    let mut d = model.data();
    let m = model.mass_matrix(&mut d, &q).clone();
    let mut rhs = nalgebra::DVector::zeros(model.dof());
    let mut chol = m.clone();
    if let Err(e) = model::cholesky_solve_in_place(&mut chol, &mut rhs) {
        let b = &model.bodies[e.joint];
        return Err(fail(
            format!("joint `{}`", b.joint),
            format!(
                "M(q) is singular: the bodies this joint moves carry no mass or inertia about its axis (does link `{}` lack an <inertial>/mass?)",
                b.link
            ),
        ));
    }
    Ok(model)
}
