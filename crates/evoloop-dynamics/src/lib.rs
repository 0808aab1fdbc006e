//! Rigid-body dynamics of serial (and branched) chains of revolute and prismatic joints.
//!
//! - `spatial`: the 6-D motion/force/inertia algebra on glam's 3-D types;
//! - `model`: `Model` (the robot) and `Data` (the buffers), with recursive Newton-Euler inverse
//!   dynamics, the composite-rigid-body inertia matrix M(q), G(q), V(q, qd), the Christoffel
//!   Coriolis matrix C(q, qd), friction F(qd) and forward dynamics by Cholesky;
//! - `regressor`: the joint-torque regressor Y(q, qd, qdd), tau = Y pi (Pinocchio's order);
//! - `dh`: robots from D-H tables in TOML (standard or modified convention);
//! - `urdf`: robots from URDF files (through the `urdf-rs` crate);
//! - `nominal`: the robot as a CAD model has it, its mass properties off by seeded factors;
//! - `generate`: plausible serial arms from a seed, written as URDF (`evoloop robot generate`);
//! - (the command `evoloop dynamics` is crate `evoloop-cli`'s `dynamics`).
//!
//! Every algorithm runs in place on a `Data`, so the plant's integrator and the computed-torque
//! controller call them every cycle without allocating.
//!
//! ```
//! use std::path::Path;
//!
//! // A pendulum from a D-H table: one revolute joint, 1 kg at the end of a 0.5 m link.
//! let text = r#"
//! name = "pendulum"
//! convention = "standard"
//! gravity = [0.0, -9.81, 0.0]
//!
//! [[joint]]
//! name = "hinge"
//! a = 0.5
//! alpha = 0.0
//! d = 0.0
//! mass = 1.0
//! com = [0.0, 0.0, 0.0]
//! inertia = [1e-3, 1e-3, 1e-3, 0.0, 0.0, 0.0]
//! q_min = -3.0
//! q_max = 3.0
//! torque_max = 20.0
//! "#;
//! let model = evoloop_dynamics::dh::parse(text, Path::new("pendulum.toml")).unwrap();
//! let mut data = model.data();
//! // Held level (q = 0), gravity pulls with m g l = 4.905 N m; M = m l^2 + I_zz.
//! let mut g = [0.0];
//! model.gravity_torque(&mut data, &[0.0], &mut g);
//! assert!((g[0].abs() - 4.905).abs() < 1e-9);
//! let m = model.mass_matrix(&mut data, &[0.0]);
//! assert!((m[(0, 0)] - 0.251).abs() < 1e-9);
//! ```

#![forbid(unsafe_code)]

pub mod base;
pub mod dh;
pub mod generate;
pub mod model;
pub mod nominal;
pub mod regressor;
pub mod spatial;
pub mod urdf;

pub use evoloop_linalg::NotPositiveDefinite;
pub use model::{Body, Data, Friction, JointKind, Limits, Model};

use glam::{DMat3, DVec3};
use std::fmt;
use std::path::{Path, PathBuf};

/// A robot description that cannot be used: the file, the link or joint, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotError {
    /// The robot file.
    pub file: PathBuf,
    /// "joint `name`" or "link `name`"; empty for file-level errors.
    pub item: String,
    /// What is wrong.
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

/// How a robot file is read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Refuse what is only physically dubious (a zero-mass link with inertia, an inertia tensor
    /// violating the triangle inequality, a `<mimic>` joint simulated as independent) instead of
    /// loading it with a warning.
    pub strict: bool,
    /// Drop joint friction and damping (URDF `<dynamics damping friction>`, D-H `viscous`,
    /// `coulomb`): the rigid-body quantities other libraries (Pinocchio, RBDL, KDL) print.
    pub rigid_body_only: bool,
}

/// Something in a robot file that was loaded but deserves a look: the item and why.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotWarning {
    /// "joint `name`" or "link `name`".
    pub item: String,
    /// What deserves a look, and what the loader did with it.
    pub reason: String,
}

impl fmt::Display for RobotWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.item, self.reason)
    }
}

/// A robot file, loaded: the model and what the loader warned about.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The robot.
    pub model: Model,
    /// What the loader warned about (none in strict mode, where each would have been an error).
    pub warnings: Vec<RobotWarning>,
}

/// Load a robot from a D-H table (`.toml`) or a URDF file (`.urdf`, `.xml`), leniently (warnings
/// dropped) and with its friction. See `load_with` for the warnings and the options.
pub fn load(path: &Path) -> Result<Model, RobotError> {
    load_with(path, &LoadOptions::default()).map(|l| l.model)
}

/// Load a robot file with `options`, returning the model and the loader's warnings.
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Loaded, RobotError> {
    let err = |reason: String| RobotError {
        file: path.to_path_buf(),
        item: String::new(),
        reason,
    };
    let text = evoloop_files::read_text(path).map_err(|e| err(format!("cannot read: {e}")))?;
    match path.extension().and_then(|e| e.to_str()) {
        Some("toml") => dh::parse_with(&text, path, options),
        Some("urdf") | Some("xml") => urdf::parse_with(&text, path, options),
        _ => Err(err(
            "unknown robot file type (expected a D-H table `.toml` or a URDF `.urdf`)".into(),
        )),
    }
}

/// Warnings of one file as they are gathered: in strict mode the first one is an error instead.
struct Checks<'a> {
    file: &'a Path,
    options: LoadOptions,
    warnings: Vec<RobotWarning>,
}

impl<'a> Checks<'a> {
    fn new(file: &'a Path, options: &LoadOptions) -> Self {
        Checks {
            file,
            options: *options,
            warnings: Vec::new(),
        }
    }

    fn error(&self, item: String, reason: String) -> RobotError {
        RobotError {
            file: self.file.to_path_buf(),
            item,
            reason,
        }
    }

    /// Something dubious but simulable: a warning, or in strict mode an error.
    fn dubious(&mut self, item: String, reason: String) -> Result<(), RobotError> {
        if self.options.strict {
            return Err(self.error(item, format!("{reason} (refused: --strict)")));
        }
        self.warnings.push(RobotWarning { item, reason });
        Ok(())
    }

    /// One link's mass properties (see `check_inertial`), as error or warning for `item`.
    fn inertial(
        &mut self,
        item: &str,
        mass: f64,
        i_com: DMat3,
        com: DVec3,
    ) -> Result<(), RobotError> {
        match check_inertial(mass, i_com, com) {
            Ok(None) => Ok(()),
            Ok(Some(doubt)) => self.dubious(item.to_string(), doubt),
            Err(e) => Err(self.error(item.to_string(), e)),
        }
    }

    /// The model's last checks (`finish`), friction dropped on request, and the warnings.
    fn finish(self, mut model: Model) -> Result<Loaded, RobotError> {
        if self.options.rigid_body_only {
            model.clear_friction();
        }
        Ok(Loaded {
            model: finish(model, self.file)?,
            warnings: self.warnings,
        })
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

/// Relative tolerance of the inertia checks (of the sum of the principal moments): tensors
/// rotated into a link frame and printed with a few digits are off by rounding.
const INERTIA_TOL: f64 = 1e-6;

/// Largest |mass| (kg), |com| (m) or inertia component (kg m^2) a robot file may give.
pub const MAX_INERTIAL: f64 = 1e9;

/// Check one moving link's mass properties. `Err` for what cannot be simulated (non-finite
/// numbers, negative mass, a negative principal moment, an asymmetric tensor); `Ok(Some(doubt))`
/// for what is physically dubious but simulable (zero mass with a non-zero tensor: kept as a pure
/// rotational inertia; a triangle-inequality violation beyond the tolerance); `Ok(None)` otherwise.
/// Zero principal moments with mass (point masses, thin rods) are common idealisations and pass.
fn check_inertial(mass: f64, i_com: DMat3, com: DVec3) -> Result<Option<String>, String> {
    let cols = i_com.to_cols_array();
    if !mass.is_finite() || !com.is_finite() || cols.iter().any(|v| !v.is_finite()) {
        return Err("mass, centre of mass and inertia must be finite numbers".into());
    }
    if mass < 0.0 {
        return Err(format!("negative mass {mass}"));
    }
    // Finite but absurd values (a mass of 1e308 kg) overflow the dynamics into NaN.
    let big = |v: f64| v.abs() > MAX_INERTIAL;
    if big(mass) || com.to_array().into_iter().any(big) || cols.iter().any(|v| big(*v)) {
        return Err(format!(
            "mass, centre of mass or inertia beyond {MAX_INERTIAL:e} (SI units): no robot has it, \
             and the dynamics would overflow"
        ));
    }
    if cols.iter().all(|v| *v == 0.0) {
        return Ok(None);
    }
    let m = nalgebra::Matrix3::from_fn(|r, c| i_com.col(c)[r]);
    if (m - m.transpose()).abs().max() > 1e-12 * m.abs().max().max(1e-300) {
        return Err("inertia tensor is not symmetric".into());
    }
    let ev = m.symmetric_eigenvalues();
    let (a, b, c) = (ev[0], ev[1], ev[2]);
    let tol = INERTIA_TOL * (a.abs() + b.abs() + c.abs());
    if a < -tol || b < -tol || c < -tol {
        return Err(format!(
            "inertia tensor is not positive (semi-)definite (principal moments {a:.6e}, {b:.6e}, {c:.6e}): no body has it"
        ));
    }
    if mass == 0.0 {
        return Ok(Some(format!(
            "zero mass with a non-zero inertia tensor (principal moments {a:.6e}, {b:.6e}, {c:.6e}): kept as a pure rotational inertia"
        )));
    }
    if a > b + c + tol || b > a + c + tol || c > a + b + tol {
        return Ok(Some(format!(
            "inertia tensor violates the triangle inequality (principal moments {a:.6e}, {b:.6e}, {c:.6e}): no rigid body has it; loaded as given"
        )));
    }
    Ok(None)
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
    if model.bodies.len() > evoloop_msg::MAX_JOINTS {
        return Err(fail(
            String::new(),
            format!(
                "{} moving joints; at most {} are supported",
                model.bodies.len(),
                evoloop_msg::MAX_JOINTS
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
    if let Err(e) = evoloop_linalg::cholesky_solve_in_place(&mut chol, &mut rhs) {
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
