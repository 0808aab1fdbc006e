//! Robots from URDF files, parsed by the `urdf-rs` crate.
//!
//! Revolute, continuous and prismatic joints become bodies; fixed joints merge their child link's
//! inertia into the moving body they hang from (links fixed to the root are dropped). Joints are
//! numbered in depth-first order from the root link, children in document order, so for a
//! serial chain the order is the chain's. Gravity defaults to 9.81 m/s^2 along -z of the root link.
//! `<dynamics damping>` becomes viscous friction and `<dynamics friction>` Coulomb friction.

use super::model::{Body, Friction, JointKind, Limits, Model};
use super::spatial::{Inertia, Transform};
use super::{inertia_tensor, Checks, LoadOptions, Loaded, RobotError};
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

/// What the loader needs to know of the raw XML before urdf-rs reads it: the kinematic joints are
/// the `<joint>` elements directly under `<robot>`. `<joint name=..>` also appears inside
/// `<transmission>` (ros_control), `<ros2_control>` and `<gazebo>` blocks, and in comments; those
/// are not joints of the tree and are skipped.
fn check_xml(text: &str) -> Result<(), (String, String)> {
    use quick_xml::events::{BytesStart, Event};
    let attr = |e: &BytesStart, key: &str| -> Option<String> {
        e.try_get_attribute(key)
            .ok()
            .flatten()
            .and_then(|a| a.unescape_value().ok().map(|v| v.into_owned()))
    };
    let mut reader = quick_xml::Reader::from_str(text);
    // Names of the open elements, outermost first.
    let mut open: Vec<Vec<u8>> = Vec::new();
    loop {
        let event = reader
            .read_event()
            .map_err(|e| (String::new(), format!("not well-formed XML: {e}")))?;
        let (e, empty) = match &event {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(_) => {
                open.pop();
                continue;
            }
            Event::Eof => return Ok(()),
            _ => continue,
        };
        let name = e.name().as_ref().to_vec();
        if name.starts_with(b"xacro:") {
            return Err((
                String::new(),
                format!(
                    "`<{}>` is a xacro macro: this is an unprocessed .xacro file; expand it first (`xacro robot.urdf.xacro > robot.urdf`)",
                    String::from_utf8_lossy(&name)
                ),
            ));
        }
        // Substitutions left in the numbers of links and joints cannot be read.
        let top = |n: &[u8]| matches!(n, b"link" | b"joint");
        let in_tree = match open.len() {
            1 => top(&name),
            n => n >= 2 && top(&open[1]),
        };
        if in_tree {
            for a in e.attributes().flatten() {
                let v = String::from_utf8_lossy(&a.value);
                if v.contains("${") || v.contains("$(") {
                    return Err((
                        String::new(),
                        format!(
                            "`{}=\"{v}\"` of `<{}>` is a xacro expression: this is an unprocessed .xacro file; expand it first (`xacro robot.urdf.xacro > robot.urdf`)",
                            String::from_utf8_lossy(a.key.as_ref()),
                            String::from_utf8_lossy(&name)
                        ),
                    ));
                }
            }
        }
        if open.len() == 1 && name == b"joint" {
            let joint = attr(e, "name").unwrap_or_else(|| "?".into());
            match attr(e, "type").as_deref() {
                Some("revolute" | "continuous" | "prismatic" | "fixed") => {}
                Some(t @ ("floating" | "planar" | "spherical")) => {
                    return Err((
                        joint,
                        format!("joint type `{t}` is not supported (revolute, continuous, prismatic and fixed are)"),
                    ))
                }
                Some(t) => {
                    return Err((
                        joint,
                        format!("unknown joint type `{t}` (expected revolute, continuous, prismatic or fixed)"),
                    ))
                }
                None => return Err((joint, "has no `type` attribute".into())),
            }
        }
        if !empty {
            open.push(name);
            // The URDF reader below recurses per level: 30 000 levels overflowed the stack
            // (an abort, not an error). A URDF is a few levels deep.
            if open.len() > MAX_DEPTH {
                return Err((
                    String::new(),
                    format!("elements nested more than {MAX_DEPTH} deep; a URDF is a few levels deep (robot, link, inertial, origin)"),
                ));
            }
        }
    }
}

/// How deep `check_xml` lets elements nest.
const MAX_DEPTH: usize = 64;

/// A URDF file, read leniently with its friction (see `parse_with`).
pub fn parse(text: &str, file: &Path) -> Result<Model, RobotError> {
    parse_with(text, file, &LoadOptions::default()).map(|l| l.model)
}

/// A URDF file read with `options`: the model and the loader's warnings. Elements that do not
/// matter to dynamics (visual, collision, gazebo, transmission, ros2_control, safety_controller,
/// calibration, materials) are ignored.
pub fn parse_with(text: &str, file: &Path, options: &LoadOptions) -> Result<Loaded, RobotError> {
    let mut checks = Checks::new(file, options);
    let fail = |item: String, reason: String| RobotError {
        file: file.to_path_buf(),
        item,
        reason,
    };
    check_xml(text).map_err(|(j, r)| {
        let item = if j.is_empty() {
            j
        } else {
            format!("joint `{j}`")
        };
        fail(item, r)
    })?;
    let robot = urdf_rs::read_from_string(text)
        .map_err(|e| fail(String::new(), format!("not a readable URDF: {e}")))?;
    let Tree {
        link_index,
        children,
        root,
    } = tree(&robot, &fail)?;

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
            let joint = &robot.joints[j];
            if let Some(m) = &joint.mimic {
                checks.dubious(
                    format!("joint `{}`", joint.name),
                    format!(
                        "mimics joint `{}` (multiplier {}, offset {}): simulated as an independent joint, evoloop does not couple joints",
                        m.joint,
                        m.multiplier.unwrap_or(1.0),
                        m.offset.unwrap_or(0.0)
                    ),
                )?;
            }
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
        // Links of the fixed base (the root and what is fixed to it) never move: their mass
        // properties do not enter the dynamics, so they are not checked.
        if let Some(b) = body {
            checks.inertial(&format!("link `{}`", link.name), inl.mass.value, i_com, com)?;
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
    checks.finish(model)
}

/// The joints and links as a tree: each link's index by name, each link's child joints, and the
/// one root link. Refused, naming the item: a name defined twice, a joint whose origin is not
/// finite or whose links are undefined, a link with two parents, no root or several.
struct Tree<'a> {
    link_index: HashMap<&'a str, usize>,
    children: Vec<Vec<usize>>,
    root: usize,
}

fn tree<'a>(
    robot: &'a urdf_rs::Robot,
    fail: &dyn Fn(String, String) -> RobotError,
) -> Result<Tree<'a>, RobotError> {
    // Names are how joints and links are found (limits, mimic, parent and child): two of one
    // name would silently make one of them unreachable.
    let joints = robot.joints.iter().map(|j| j.name.as_str());
    let links = robot.links.iter().map(|l| l.name.as_str());
    for (what, names) in [
        ("joint", joints.collect::<Vec<_>>()),
        ("link", links.collect()),
    ] {
        let mut seen = std::collections::HashSet::new();
        if let Some(n) = names.into_iter().find(|n| !seen.insert(*n)) {
            return Err(fail(format!("{what} `{n}`"), "is defined twice".into()));
        }
    }
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
        // Checked here, where the joint is known: a non-finite origin would otherwise surface
        // in the placement of whichever moving joint comes after it.
        let o = &joint.origin;
        if o.xyz.0.iter().chain(o.rpy.0.iter()).any(|v| !v.is_finite()) {
            return Err(fail(
                item,
                "origin xyz and rpy must be finite numbers".into(),
            ));
        }
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
    Ok(Tree {
        link_index,
        children,
        root,
    })
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
    if joint.joint_type != urdf_rs::JointType::Continuous && lim.lower > lim.upper {
        // lower = upper (both 0 when <limit> gives none) reads as unlimited; an inverted range
        // is a mistake in the file, refused as the D-H loader refuses it.
        return Err(format!(
            "limit lower {} is above upper {}",
            lim.lower, lim.upper
        ));
    }
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

/// A URDF `rpy` triple of a rotation (the inverse of `rpy`; at pitch +-90 deg roll is 0).
fn rpy_of(r: DMat3) -> [f64; 3] {
    let at = |i: usize, j: usize| r.col(j)[i];
    // cos(pitch) from the first column: well conditioned near +-90 deg, where asin is not.
    let c = at(0, 0).hypot(at(1, 0));
    let pitch = (-at(2, 0)).atan2(c);
    if c < 1e-15 {
        return [0.0, pitch, (-at(0, 1)).atan2(at(1, 1))];
    }
    [at(2, 1).atan2(at(2, 2)), pitch, at(1, 0).atan2(at(0, 0))]
}

/// `s` as an XML attribute value.
fn escaped(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Whether `to_urdf` can write `model` whole: URDF's gravity, no armature and the default
/// friction smoothing; why not otherwise.
pub fn writable(model: &Model) -> Result<(), NotWritable> {
    if model.gravity != DVec3::new(0.0, 0.0, -9.81) {
        return Err(NotWritable::Gravity(model.gravity));
    }
    let smoothing = Friction::default().v_smooth;
    match (model.bodies.iter()).find(|b| b.armature != 0.0 || b.friction.v_smooth != smoothing) {
        Some(b) => Err(NotWritable::Joint(b.joint.clone())),
        None => Ok(()),
    }
}

/// Why `to_urdf` refuses a model rather than write it wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum NotWritable {
    /// A gravity other than URDF's fixed (0, 0, -9.81) m/s^2 (the model's).
    Gravity(DVec3),
    /// A joint with an armature or a friction smoothing URDF cannot carry (its name).
    Joint(String),
}

impl std::fmt::Display for NotWritable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotWritable::Gravity(g) => write!(f, "gravity {g} is not URDF's (0, 0, -9.81)"),
            NotWritable::Joint(j) => write!(
                f,
                "joint `{j}`: an armature or a friction smoothing URDF cannot carry"
            ),
        }
    }
}

impl std::error::Error for NotWritable {}

/// `model` as URDF: a base link, each body's joint (placement, axis, limits, friction) and its
/// link (mass, centre of mass, inertia about it). Numbers are written in Rust's shortest form
/// that reads back to the same value; rotations as `rpy`, which reads back to within rounding.
/// URDF has no armature, no friction smoothing and a fixed gravity: a model with an armature, a
/// `v_smooth` other than the default or another gravity is refused, not written wrong.
pub fn to_urdf(model: &Model) -> Result<String, NotWritable> {
    writable(model)?;
    // The fixed base link, named apart from every body's link.
    let mut base = "base".to_string();
    while model.bodies.iter().any(|b| b.link == base) {
        base.push('_');
    }
    let base = escaped(&base);
    let mut s = format!(
        "<?xml version=\"1.0\"?>\n<robot name=\"{}\">\n  <link name=\"{base}\"/>\n",
        escaped(&model.name)
    );
    for b in &model.bodies {
        let c = b.inertia.com();
        let i = b.inertia.i_com();
        let at = |r: usize, k: usize| i.col(k)[r];
        let o = &b.placement;
        let [rr, rp, ry] = rpy_of(o.rotation());
        let parent = b
            .parent
            .map_or(base.clone(), |p| escaped(&model.bodies[p].link));
        let (kind, lower, upper) = match (b.kind, b.limits.q_min.is_finite()) {
            (JointKind::Revolute, false) => ("continuous", 0.0, 0.0),
            (JointKind::Revolute, true) => ("revolute", b.limits.q_min, b.limits.q_max),
            (JointKind::Prismatic, false) => ("prismatic", 0.0, 0.0),
            (JointKind::Prismatic, true) => ("prismatic", b.limits.q_min, b.limits.q_max),
        };
        // The loader reads 0 as "no limit".
        let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
        s += &format!(
            "  <link name=\"{link}\">\n    <inertial>\n      <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n      \
             <mass value=\"{}\"/>\n      <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" \
             izz=\"{}\"/>\n    </inertial>\n  </link>\n  <joint name=\"{}\" type=\"{kind}\">\n    \
             <parent link=\"{parent}\"/>\n    <child link=\"{link}\"/>\n    <origin xyz=\"{} {} {}\" \
             rpy=\"{rr} {rp} {ry}\"/>\n    <axis xyz=\"{} {} {}\"/>\n    <limit lower=\"{lower}\" \
             upper=\"{upper}\" effort=\"{}\" velocity=\"{}\"/>\n    <dynamics damping=\"{}\" \
             friction=\"{}\"/>\n  </joint>\n",
            c.x,
            c.y,
            c.z,
            b.inertia.m,
            at(0, 0),
            at(0, 1),
            at(0, 2),
            at(1, 1),
            at(1, 2),
            at(2, 2),
            escaped(&b.joint),
            o.r.x,
            o.r.y,
            o.r.z,
            b.axis.x,
            b.axis.y,
            b.axis.z,
            finite(b.limits.effort),
            finite(b.limits.velocity),
            b.friction.viscous,
            b.friction.coulomb,
            link = escaped(&b.link),
        );
    }
    s.push_str("</robot>\n");
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_of_inverts_rpy_also_at_and_near_ninety_degrees_of_pitch() {
        let half = std::f64::consts::FRAC_PI_2;
        for r in [
            [0.3, -0.7, 2.1],
            [1.0, half, -0.4],
            [0.2, half - 3e-7, 0.9],
            [-0.5, -half, 0.1],
            [0.7, -half + 2e-8, -2.0],
            [0.0, 0.0, 0.0],
        ] {
            let m = rpy(r);
            assert!(
                m.abs_diff_eq(rpy(rpy_of(m)), 1e-12),
                "{r:?}: {:?}",
                rpy_of(m)
            );
        }
    }
}
