//! Robots from Denavit-Hartenberg tables in TOML.
//!
//! ```toml
//! name = "arm3"
//! convention = "standard"        # or "modified" (Craig)
//! gravity = [0.0, 0.0, -9.81]    # root frame, m/s^2 (default)
//!
//! [[joint]]
//! name = "waist"                 # default joint<i>
//! type = "revolute"              # or "prismatic"
//! a = 0.0                        # m
//! alpha = 1.5707963267948966     # rad
//! d = 0.3                        # m (offset for prismatic joints)
//! theta = 0.0                    # rad, joint-angle offset (default 0)
//! mass = 2.0                     # kg
//! com = [0.0, -0.15, 0.0]        # m, in this link's D-H frame
//! inertia = [0.02, 0.005, 0.02, 0.0, 0.0, 0.0]  # ixx iyy izz ixy ixz iyz about the com, kg m^2
//! q_min = -3.0                   # optional limits (rad or m), velocity_max, torque_max
//! viscous = 0.1                  # optional friction (N m s/rad), coulomb (N m), v_smooth
//! armature = 0.0                 # optional reflected rotor inertia (kg m^2)
//! ```
//!
//! **Standard** D-H (Spong; Siciliano et al.): row i is Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)
//! and carries link i's frame at its distal end; the link's mass properties are given in that frame.
//! **Modified** D-H (Craig): row i is Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i), the row
//! holding (a_{i-1}, alpha_{i-1}) as Craig's tables print them, and frame i sits on joint i.
//!
//! Both become the generic model of `model`: a fixed placement, then the joint's motion about (or
//! along) its z axis. For standard rows the fixed part of row i becomes the placement of joint
//! i + 1, and link i's mass properties are carried from the D-H frame into the body frame.

use super::model::{Body, Friction, JointKind, Limits, Model};
use super::spatial::{Inertia, Transform};
use super::{inertia_tensor, Checks, LoadOptions, Loaded, RobotError};
use glam::{DMat3, DVec3};
use serde::Deserialize;
use std::path::Path;

/// The D-H convention a table is written in (its `convention` key).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Convention {
    /// Standard D-H (Spong; Siciliano et al.): row i is Rz(theta_i + q_i) Tz(d_i) Tx(a_i)
    /// Rx(alpha_i), link i's frame at its distal end.
    Standard,
    /// Modified D-H (Craig): row i is Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i),
    /// frame i on joint i.
    Modified,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTable {
    name: Option<String>,
    convention: Convention,
    gravity: Option<[f64; 3]>,
    joint: Vec<RawRow>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRow {
    name: Option<String>,
    #[serde(rename = "type")]
    kind: Option<String>,
    a: f64,
    alpha: f64,
    d: f64,
    theta: Option<f64>,
    mass: Option<f64>,
    com: Option<[f64; 3]>,
    inertia: Option<[f64; 6]>,
    q_min: Option<f64>,
    q_max: Option<f64>,
    velocity_max: Option<f64>,
    torque_max: Option<f64>,
    viscous: Option<f64>,
    coulomb: Option<f64>,
    v_smooth: Option<f64>,
    armature: Option<f64>,
}

fn rot_z(t: f64) -> Transform {
    Transform::from_placement(DMat3::from_rotation_z(t), DVec3::ZERO)
}
fn rot_x(t: f64) -> Transform {
    Transform::from_placement(DMat3::from_rotation_x(t), DVec3::ZERO)
}
fn trans(x: f64, y: f64, z: f64) -> Transform {
    Transform::from_placement(DMat3::IDENTITY, DVec3::new(x, y, z))
}

/// A D-H table, read leniently with its friction (see `parse_with`).
pub fn parse(text: &str, file: &Path) -> Result<Model, RobotError> {
    parse_with(text, file, &LoadOptions::default()).map(|l| l.model)
}

/// A D-H table read with `options`: the model and the loader's warnings.
pub fn parse_with(text: &str, file: &Path, options: &LoadOptions) -> Result<Loaded, RobotError> {
    let mut checks = Checks::new(file, options);
    let fail = |item: String, reason: String| RobotError {
        file: file.to_path_buf(),
        item,
        reason,
    };
    let raw: RawTable = evoloop_files::from_toml(text).map_err(|p| {
        let at = p.line.map(|l| format!("line {l}: ")).unwrap_or_default();
        fail(
            if p.key.is_empty() {
                String::new()
            } else {
                format!("key `{}`", p.key)
            },
            format!("{at}{}", p.reason),
        )
    })?;
    let gravity = raw.gravity.unwrap_or([0.0, 0.0, -9.81]);
    if gravity.iter().any(|g| !g.is_finite()) {
        return Err(fail("key `gravity`".into(), "must be finite".into()));
    }
    let mut bodies = Vec::with_capacity(raw.joint.len());
    // The fixed part of the previous standard row (placement of the next joint).
    let mut carried = Transform::IDENTITY;
    let mut seen = std::collections::HashSet::new();
    for (i, row) in raw.joint.into_iter().enumerate() {
        let name = row
            .name
            .clone()
            .unwrap_or_else(|| format!("joint{}", i + 1));
        let item = format!("joint `{name}` (row {})", i + 1);
        if !seen.insert(name.clone()) {
            return Err(fail(
                item,
                "the name is used by an earlier joint (names must be unique: run.csv columns, \
                 parameter names and messages refer to joints by them)"
                    .into(),
            ));
        }
        let kind = match row.kind.as_deref().unwrap_or("revolute") {
            "revolute" => JointKind::Revolute,
            "prismatic" => JointKind::Prismatic,
            other => {
                return Err(fail(
                    item,
                    format!("unknown joint type `{other}` (expected revolute or prismatic)"),
                ))
            }
        };
        let theta = row.theta.unwrap_or(0.0);
        for (k, v) in [
            ("a", row.a),
            ("alpha", row.alpha),
            ("d", row.d),
            ("theta", theta),
        ] {
            if !v.is_finite() {
                return Err(fail(item, format!("`{k}` must be finite (got {v})")));
            }
        }
        let (Some(mass), Some(com), Some(inertia)) = (row.mass, row.com, row.inertia) else {
            return Err(fail(
                item,
                "missing mass properties: every link needs `mass`, `com` and `inertia`".into(),
            ));
        };
        let [ixx, iyy, izz, ixy, ixz, iyz] = inertia;
        let i_dh = inertia_tensor(ixx, ixy, ixz, iyy, iyz, izz);
        let com_dh = DVec3::from(com);
        checks.inertial(&format!("link of {item}"), mass, i_dh, com_dh)?;
        // Joint placement and the D-H frame of this link, both relative to the body frame.
        let (placement, link_frame) = match raw.convention {
            Convention::Standard => (
                carried,
                rot_z(theta)
                    .then(&trans(0.0, 0.0, row.d))
                    .then(&trans(row.a, 0.0, 0.0))
                    .then(&rot_x(row.alpha)),
            ),
            Convention::Modified => (
                rot_x(row.alpha)
                    .then(&trans(row.a, 0.0, 0.0))
                    .then(&rot_z(theta))
                    .then(&trans(0.0, 0.0, row.d)),
                Transform::IDENTITY,
            ),
        };
        // Prismatic rows: d is the offset at q = 0; the joint adds q along z.
        let inertia_body = Inertia::from_com(mass, com_dh, i_dh).to_parent(&link_frame);
        let limits = Limits {
            q_min: row.q_min.unwrap_or(f64::NEG_INFINITY),
            q_max: row.q_max.unwrap_or(f64::INFINITY),
            velocity: row.velocity_max.unwrap_or(f64::INFINITY),
            effort: row.torque_max.unwrap_or(f64::INFINITY),
        };
        let friction = Friction {
            viscous: row.viscous.unwrap_or(0.0),
            coulomb: row.coulomb.unwrap_or(0.0),
            v_smooth: row.v_smooth.unwrap_or(Friction::default().v_smooth),
        };
        bodies.push(Body {
            joint: name.clone(),
            link: format!("link_{name}"),
            parent: i.checked_sub(1),
            placement,
            kind,
            axis: DVec3::Z,
            inertia: inertia_body,
            friction,
            limits,
            armature: row.armature.unwrap_or(0.0),
        });
        carried = if raw.convention == Convention::Standard {
            link_frame
        } else {
            Transform::IDENTITY
        };
    }
    let model = Model {
        name: raw.name.unwrap_or_else(|| {
            file.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        }),
        bodies,
        gravity: DVec3::from(gravity),
    };
    checks.finish(model)
}
