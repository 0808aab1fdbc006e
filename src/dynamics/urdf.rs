//! Robots from URDF files, parsed by the `urdf-rs` crate.
//!
//! Revolute, continuous and prismatic joints become bodies; fixed joints merge their child link's
//! inertia into the moving body they hang from (links fixed to the root are dropped). Joints are
//! numbered in depth-first order from the root link, children in document order, so for a
//! serial chain the order is the chain's. Gravity defaults to 9.81 m/s^2 along -z of the root link.
//! `<dynamics damping>` becomes viscous friction and `<dynamics friction>` Coulomb friction.

use super::model::{Body, Friction, JointKind, Limits, Model};
use super::spatial::{Inertia, Transform};
use super::{check_inertial, finish, inertia_tensor, RobotError};
use glam::{DMat3, DVec3};
use std::collections::HashMap;
use std::path::Path;

/// Rotation of a URDF `rpy` triple: fixed-axis roll about x, then pitch about y, then yaw about z.
fn rpy(r: [f64; 3]) -> DMat3 {
    DMat3::from_rotation_z(r[2]) * DMat3::from_rotation_y(r[1]) * DMat3::from_rotation_x(r[0])
}

fn pose(p: &urdf_rs::Pose) -> Transform {
    Transform::from_placement(rpy(p.rpy.0), DVec3::from(p.xyz.0))
}

/// `name="..."` or `type='...'` of one XML start tag.
fn attribute<'t>(tag: &'t str, key: &str) -> Option<&'t str> {
    let mut rest = tag;
    while let Some(at) = rest.find(key) {
        let before_ok = at == 0 || rest[..at].ends_with(|c: char| c.is_whitespace());
        let after = rest[at + key.len()..].trim_start();
        if before_ok && after.starts_with('=') {
            let v = after[1..].trim_start();
            let quote = v.chars().next()?;
            if quote == '"' || quote == '\'' {
                let end = v[1..].find(quote)?;
                return Some(&v[1..1 + end]);
            }
        }
        rest = &rest[at + key.len()..];
    }
    None
}

/// Joint types checked on the raw text before parsing, so an unknown or unsupported type is
/// reported with the joint's name rather than as a deserialiser error.
fn check_joint_types(text: &str) -> Result<(), (String, String)> {
    let mut rest = text;
    while let Some(at) = rest.find("<joint") {
        rest = &rest[at + 6..];
        if !rest.starts_with(|c: char| c.is_whitespace()) {
            continue;
        }
        let tag = &rest[..rest.find('>').unwrap_or(rest.len())];
        let name = attribute(tag, "name").unwrap_or("?").to_string();
        match attribute(tag, "type") {
            Some("revolute" | "continuous" | "prismatic" | "fixed") => {}
            Some(t @ ("floating" | "planar" | "spherical")) => {
                return Err((
                    name,
                    format!("joint type `{t}` is not supported (revolute, continuous, prismatic and fixed are)"),
                ))
            }
            Some(t) => {
                return Err((
                    name,
                    format!("unknown joint type `{t}` (expected revolute, continuous, prismatic or fixed)"),
                ))
            }
            None => return Err((name, "has no `type` attribute".into())),
        }
    }
    Ok(())
}

pub fn parse(text: &str, file: &Path) -> Result<Model, RobotError> {
    let fail = |item: String, reason: String| RobotError {
        file: file.to_path_buf(),
        item,
        reason,
    };
    check_joint_types(text).map_err(|(j, r)| fail(format!("joint `{j}`"), r))?;
    let robot = urdf_rs::read_from_string(text)
        .map_err(|e| fail(String::new(), format!("not a readable URDF: {e}")))?;
    let link_index: HashMap<&str, usize> = robot
        .links
        .iter()
        .enumerate()
        .map(|(i, l)| (l.name.as_str(), i))
        .collect();
    let mut parent_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
    for (j, joint) in robot.joints.iter().enumerate() {
        let item = format!("joint `{}`", joint.name);
        let Some(&p) = link_index.get(joint.parent.link.as_str()) else {
            return Err(fail(
                item,
                format!("parent link `{}` is not defined", joint.parent.link),
            ));
        };
        let Some(&c) = link_index.get(joint.child.link.as_str()) else {
            return Err(fail(
                item,
                format!("child link `{}` is not defined", joint.child.link),
            ));
        };
        if let Some(other) = parent_joint[c] {
            return Err(fail(
                format!("link `{}`", joint.child.link),
                format!(
                    "is the child of two joints, `{}` and `{}`: the joint graph has a loop or a second parent, not a tree",
                    robot.joints[other].name, joint.name
                ),
            ));
        }
        parent_joint[c] = Some(j);
        children[p].push(j);
    }
    let roots: Vec<usize> = (0..robot.links.len())
        .filter(|&l| parent_joint[l].is_none())
        .collect();
    let root = match roots.as_slice() {
        [r] => *r,
        [] => {
            return Err(fail(
                String::new(),
                "no root link: every link is some joint's child, so the joints form a loop".into(),
            ))
        }
        many => {
            let names: Vec<String> = many
                .iter()
                .map(|&l| format!("`{}`", robot.links[l].name))
                .collect();
            return Err(fail(
                String::new(),
                format!(
                    "several root links ({}): the description is not one connected tree",
                    names.join(", ")
                ),
            ));
        }
    };

    let mut bodies: Vec<Body> = Vec::new();
    let mut reached = vec![false; robot.links.len()];
    // Depth-first walk. An entry is a link to visit, the moving body it hangs from, the transform
    // from that body's frame to the link's frame, and the moving joint that leads to it (the body
    // is created when the entry is popped, so bodies come in depth-first order).
    let mut stack: Vec<(usize, Option<usize>, Transform, Option<usize>)> =
        vec![(root, None, Transform::IDENTITY, None)];
    while let Some((l, mut body, mut offset, via)) = stack.pop() {
        reached[l] = true;
        if let Some(j) = via {
            bodies.push(
                moving_body(&robot.joints[j], body, offset)
                    .map_err(|r| fail(format!("joint `{}`", robot.joints[j].name), r))?,
            );
            body = Some(bodies.len() - 1);
            offset = Transform::IDENTITY;
        }
        let link = &robot.links[l];
        let inl = &link.inertial;
        let i = &inl.inertia;
        let i_frame = inertia_tensor(i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz);
        let r = rpy(inl.origin.rpy.0);
        let i_com = r * i_frame * r.transpose();
        let com = DVec3::from(inl.origin.xyz.0);
        check_inertial(inl.mass.value, i_com, com)
            .map_err(|e| fail(format!("link `{}`", link.name), e))?;
        if let Some(b) = body {
            let inertia = Inertia::from_com(inl.mass.value, com, i_com).to_parent(&offset);
            bodies[b].inertia = bodies[b].inertia + inertia;
        }
        // Pushed in reverse so children are visited in document order.
        for &j in children[l].iter().rev() {
            let joint = &robot.joints[j];
            let c = link_index[joint.child.link.as_str()];
            let to_joint = offset.then(&pose(&joint.origin));
            if joint.joint_type == urdf_rs::JointType::Fixed {
                stack.push((c, body, to_joint, None));
            } else {
                stack.push((c, body, to_joint, Some(j)));
            }
        }
    }
    if let Some(l) = (0..robot.links.len()).find(|&l| !reached[l]) {
        return Err(fail(
            format!("link `{}`", robot.links[l].name),
            format!(
                "is not reachable from the root link `{}`: the joints form a loop",
                robot.links[root].name
            ),
        ));
    }
    let model = Model {
        name: robot.name.clone(),
        bodies,
        gravity: DVec3::new(0.0, 0.0, -9.81),
    };
    finish(model, file)
}

/// The body moved by a revolute, continuous or prismatic joint placed at `placement` in the
/// frame of body `parent`; its inertia is filled in as the walk meets its links.
fn moving_body(
    joint: &urdf_rs::Joint,
    parent: Option<usize>,
    placement: Transform,
) -> Result<Body, String> {
    let kind = match joint.joint_type {
        urdf_rs::JointType::Prismatic => JointKind::Prismatic,
        _ => JointKind::Revolute,
    };
    let axis = DVec3::from(joint.axis.xyz.0);
    if !axis.is_finite() || axis.length() < 1e-9 {
        return Err("axis must be a non-zero vector".into());
    }
    let lim = &joint.limit;
    let positional = joint.joint_type != urdf_rs::JointType::Continuous && lim.lower < lim.upper;
    let dynamics = joint.dynamics.clone().unwrap_or_default();
    Ok(Body {
        joint: joint.name.clone(),
        link: joint.child.link.clone(),
        parent,
        placement,
        kind,
        axis: axis.normalize(),
        inertia: Inertia::ZERO,
        friction: Friction {
            viscous: dynamics.damping,
            coulomb: dynamics.friction,
            ..Friction::default()
        },
        limits: Limits {
            q_min: if positional {
                lim.lower
            } else {
                f64::NEG_INFINITY
            },
            q_max: if positional { lim.upper } else { f64::INFINITY },
            velocity: if lim.velocity > 0.0 {
                lim.velocity
            } else {
                f64::INFINITY
            },
            effort: if lim.effort > 0.0 {
                lim.effort
            } else {
                f64::INFINITY
            },
        },
        armature: 0.0,
    })
}
