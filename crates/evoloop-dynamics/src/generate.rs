//! Plausible serial arms from a seed (`evoloop robot generate`), so that a claim about the arm
//! controllers can be measured on arms nobody tuned anything on.
//!
//! An arm is a base yaw joint, a shoulder and an elbow, then a wrist of 0-4 joints (a 7-joint
//! arm has the redundant upper-arm roll of a Panda or an iiwa instead). Every joint turns about
//! its frame's z axis; the frames follow the modified Denavit-Hartenberg convention with twists
//! of 0 or ±90°, so the kinematics are those of real arms (anthropomorphic, PUMA-like spherical
//! wrist, Panda-like offsets) while the lengths, offsets and twist signs come from the seed.
//!
//! The ranges are the spread of the arms evoloop ships and tests against (arm3, the
//! Panda-style arm7, the UR5- and iiwa-style test files): links 0.2-0.6 m, 4-12 kg per metre
//! tapering towards the tool, wrist housings of 0.06-0.12 m, friction and damping a fraction of
//! the joint's effort, limits ±1.7-2.9 rad. Each link's inertia is a solid cylinder along the
//! link (so its principal moments satisfy the triangle inequality by construction), turned by a
//! small random rotation so the tensor has products of inertia as CAD tensors do.
//!
//! Only IEEE-exact operations (+, -, *, /, sqrt) shape the numbers (no sin or cos: twists are
//! 0 or ±90°, rotations come from quaternions), so one seed gives the same file on any machine.

use glam::{DMat3, DQuat, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;

/// The fewest and the most joints a generated arm has.
pub const JOINTS: std::ops::RangeInclusive<usize> = 3..=7;

const G: f64 = 9.81;

/// One joint and the link it moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// The joint frame from its parent link's.
    pub frame: DhRow,
    /// Mass of the link (kg).
    pub mass: f64,
    /// Centre of mass in the link frame (m).
    pub com: DVec3,
    /// Inertia about the centre of mass, in the link frame (kg m^2).
    pub inertia: DMat3,
    /// Position limits (rad), symmetric.
    pub limit: f64,
    /// Torque limit (N m): four times the static load the joint carries at full reach, at least 5.
    pub effort: f64,
    /// Velocity limit (rad/s).
    pub velocity: f64,
    /// Viscous (N m s/rad) and Coulomb (N m) friction, URDF's damping and friction.
    pub damping: f64,
    /// Coulomb friction (N m), URDF's `friction`.
    pub friction: f64,
}

/// A twist of the modified D-H convention: the only ones real arms use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Twist {
    /// No twist: the joint's z axis is parallel to the parent's.
    Zero,
    /// +90° about the parent's x axis.
    PlusHalfPi,
    /// -90° about the parent's x axis.
    MinusHalfPi,
}

impl Twist {
    fn radians(self) -> f64 {
        match self {
            Twist::Zero => 0.0,
            Twist::PlusHalfPi => std::f64::consts::FRAC_PI_2,
            Twist::MinusHalfPi => -std::f64::consts::FRAC_PI_2,
        }
    }
}

/// A generated arm: its joints base to tip and the tool frame's offset from the last joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Arm {
    /// The arm's name, `gen<joints>_s<seed>` (its URDF robot name).
    pub name: String,
    /// The seed it was generated from.
    pub seed: u64,
    /// Its joints, base to tip.
    pub joints: Vec<Joint>,
    /// The tool frame's origin in the last link's frame (m).
    pub tool: DVec3,
}

/// An arm of a joint count outside `JOINTS` was asked for (the count asked).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JointCountError(pub usize);

impl std::fmt::Display for JointCountError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "an arm has {} to {} joints (got {})",
            JOINTS.start(),
            JOINTS.end(),
            self.0
        )
    }
}

impl std::error::Error for JointCountError {}

/// The arm of `joints` joints (3-7) that `seed` gives.
pub fn generate(joints: usize, seed: u64) -> Result<Arm, JointCountError> {
    if !JOINTS.contains(&joints) {
        return Err(JointCountError(joints));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let frames = kinematics(joints, &mut rng);
    let tool = frames.tool;
    // Each link runs from its joint to the next joint's origin (the last one to the tool).
    let ends: Vec<DVec3> = (0..joints)
        .map(|i| frames.rows.get(i + 1).map_or(tool, |r| r.origin()))
        .collect();
    let density = mm(&mut rng, 4.0, 12.0);
    let taper = rng.gen_range(0.75..0.95);
    let mut arm_joints: Vec<Joint> = frames
        .rows
        .iter()
        .zip(&ends)
        .enumerate()
        .map(|(i, (frame, end))| {
            let (mass, com, inertia) = link(&mut rng, *end, density * taper_pow(taper, i));
            Joint {
                frame: *frame,
                mass,
                com,
                inertia,
                limit: round(rng.gen_range(1.7..2.9), 100.0),
                effort: 0.0,
                velocity: round(rng.gen_range(2.0..3.5), 100.0),
                damping: 0.0,
                friction: 0.0,
            }
        })
        .collect();
    set_efforts_and_friction(&mut arm_joints, &ends, &mut rng);
    Ok(Arm {
        name: format!("gen{joints}_s{seed}"),
        seed,
        joints: arm_joints,
        tool,
    })
}

/// One row of the modified D-H table: the twist about the parent's x, the length along it, the
/// offset along the joint's z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// The twist about the parent's x axis.
    pub twist: Twist,
    /// Length along the parent's x axis (m).
    pub a: f64,
    /// Offset along the joint's z axis (m).
    pub d: f64,
}

impl DhRow {
    /// The joint frame's origin in the parent link's frame: Rx(twist) Tx(a) Tz(d) moves the
    /// origin to (a, -d sin(twist), d cos(twist)).
    pub fn origin(&self) -> DVec3 {
        match self.twist {
            Twist::Zero => DVec3::new(self.a, 0.0, self.d),
            Twist::PlusHalfPi => DVec3::new(self.a, 0.0 - self.d, 0.0), // +0, not -0, where d is 0
            Twist::MinusHalfPi => DVec3::new(self.a, self.d, 0.0),
        }
    }
}

struct Frames {
    rows: Vec<DhRow>,
    tool: DVec3,
}

/// The D-H rows and tool offset of a `joints`-joint arm.
fn kinematics(joints: usize, rng: &mut ChaCha8Rng) -> Frames {
    let base = mm(rng, 0.15, 0.45);
    let upper = mm(rng, 0.25, 0.6);
    let fore = mm(rng, 0.2, 0.55);
    // A shoulder offset on half the arms (UR-like), none on the rest (arm3-like).
    let shoulder = if rng.gen_bool(0.5) {
        mm(rng, 0.03, 0.12)
    } else {
        0.0
    };
    let row = |twist, a, d| DhRow { twist, a, d };
    let mut rows = vec![
        row(Twist::Zero, 0.0, base),
        row(quarter(rng), shoulder, 0.0),
    ];
    if joints == 7 {
        // Panda/iiwa-like: upper-arm roll, elbow with its offset, forearm roll, wrist.
        let offset = mm(rng, 0.0, 0.09);
        rows.push(row(quarter(rng), 0.0, upper));
        rows.push(row(quarter(rng), offset, 0.0));
        rows.push(row(quarter(rng), -offset, fore));
        rows.push(row(quarter(rng), 0.0, 0.0));
        rows.push(row(quarter(rng), mm(rng, 0.0, 0.09), 0.0));
        let tool = DVec3::new(0.0, 0.0, mm(rng, 0.05, 0.12));
        return Frames { rows, tool };
    }
    rows.push(row(Twist::Zero, upper, 0.0));
    let tool = match joints {
        3 => DVec3::new(fore, 0.0, 0.0),
        4 => {
            // A wrist pitch at the forearm's end.
            rows.push(row(Twist::Zero, fore, 0.0));
            DVec3::new(mm(rng, 0.06, 0.15), 0.0, 0.0)
        }
        _ => {
            // A forearm roll (an elbow offset on some arms), then a spherical wrist.
            let elbow = if rng.gen_bool(0.5) {
                mm(rng, 0.02, 0.08)
            } else {
                0.0
            };
            rows.push(row(quarter(rng), elbow, fore));
            for _ in 5..=joints {
                rows.push(row(quarter(rng), 0.0, 0.0));
            }
            DVec3::new(0.0, 0.0, mm(rng, 0.05, 0.12))
        }
    };
    Frames { rows, tool }
}

/// Mass, centre of mass and inertia of a link from its joint to `end`, `density` kg per metre:
/// a solid cylinder along the link, or a housing around the joint where the next joint sits
/// on this one (a spherical wrist).
fn link(rng: &mut ChaCha8Rng, end: DVec3, density: f64) -> (f64, DVec3, DMat3) {
    let housing = mm(rng, 0.06, 0.12);
    let is_housing = end.length() < housing;
    let length = end.length().max(housing);
    let axis = if is_housing {
        DVec3::Z
    } else {
        end / end.length()
    };
    let mass = round((density * length).clamp(0.3, 15.0), 100.0);
    let radius = mm(rng, 0.03, 0.07);
    let along = if is_housing {
        0.0
    } else {
        rng.gen_range(0.35..0.6)
    };
    let jitter = DVec3::new(
        mm(rng, -0.01, 0.01),
        mm(rng, -0.01, 0.01),
        mm(rng, -0.01, 0.01),
    );
    let com = end * along + jitter;
    let i_axis = mass * radius * radius / 2.0;
    let i_perp = mass * (3.0 * radius * radius + length * length) / 12.0;
    let principal = DMat3::from_diagonal(DVec3::new(i_axis, i_perp, i_perp));
    // x onto the link's direction, then a small tilt of up to about 11 degrees.
    let onto = DQuat::from_rotation_arc(DVec3::X, axis);
    let tilt = DQuat::from_xyzw(
        rng.gen_range(-0.1..0.1),
        rng.gen_range(-0.1..0.1),
        rng.gen_range(-0.1..0.1),
        1.0,
    )
    .normalize();
    let r = DMat3::from_quat(tilt * onto);
    let inertia = r * principal * r.transpose();
    // Exactly symmetric, as a file gives it.
    let sym = |i: usize, j: usize| (inertia.col(j)[i] + inertia.col(i)[j]) / 2.0;
    let inertia = crate::inertia_tensor(
        sym(0, 0),
        sym(1, 0),
        sym(2, 0),
        sym(1, 1),
        sym(2, 1),
        sym(2, 2),
    );
    (mass, com, inertia)
}

/// Efforts from the static load each joint carries (the links beyond it held out at full
/// reach), four times over for acceleration (arm3 and the Panda have 4-7 times their static
/// torque), and friction a fraction of the effort.
fn set_efforts_and_friction(joints: &mut [Joint], ends: &[DVec3], rng: &mut ChaCha8Rng) {
    let n = joints.len();
    for i in 0..n {
        let reach: f64 = ends[i..].iter().map(|e| e.length()).sum();
        let carried: f64 = joints[i..].iter().map(|j| j.mass).sum();
        let effort = (4.0 * G * carried * reach).max(5.0).ceil();
        let j = &mut joints[i];
        j.effort = effort;
        j.damping = round(effort * rng.gen_range(0.0005..0.006), 1000.0);
        j.friction = round(effort * rng.gen_range(0.001..0.005), 1000.0);
    }
}

/// taper^i by repeated multiplication: `powi`'s rounding is not specified, this one's is.
fn taper_pow(taper: f64, i: usize) -> f64 {
    (0..i).fold(1.0, |p, _| p * taper)
}

/// A uniform draw in [lo, hi) rounded to the millimetre (or gram, per metre): files read as
/// a designer writes them.
fn mm(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    round(rng.gen_range(lo..hi), 1000.0)
}

/// `v` to the nearest 1 / `per` (a division by an exact integer: 0.3, not 0.30000000000000004).
fn round(v: f64, per: f64) -> f64 {
    (v * per).round() / per
}

fn quarter(rng: &mut ChaCha8Rng) -> Twist {
    if rng.gen_bool(0.5) {
        Twist::PlusHalfPi
    } else {
        Twist::MinusHalfPi
    }
}

impl Arm {
    /// The arm as URDF: a fixed base link, one revolute joint per row (its D-H frame as the
    /// joint origin, turning about z) and a fixed tool frame.
    pub fn to_urdf(&self) -> String {
        let mut s = String::new();
        self.write_urdf(&mut s)
            .expect("writing to a String cannot fail");
        s
    }

    fn write_urdf(&self, s: &mut String) -> std::fmt::Result {
        // (XML comments may not hold "--": the command is spelled without its dashes.)
        writeln!(
            s,
            "<?xml version=\"1.0\"?>\n<!-- Generated by evoloop robot generate, joints {}, seed {}: \
             a plausible serial arm, not a product. -->\n<robot name=\"{}\">\n  <link \
             name=\"base_link\"/>",
            self.joints.len(),
            self.seed,
            self.name
        )?;
        let mut parent = "base_link".to_string();
        for (i, j) in self.joints.iter().enumerate() {
            let link = format!("link{}", i + 1);
            let (c, m, o) = (j.com, j.inertia, j.frame.origin());
            let at = |r: usize, k: usize| m.col(k)[r];
            writeln!(
                s,
                concat!(
                    "  <link name=\"{link}\">\n",
                    "    <inertial>\n",
                    "      <origin xyz=\"{cx} {cy} {cz}\" rpy=\"0 0 0\"/>\n",
                    "      <mass value=\"{mass}\"/>\n",
                    "      <inertia ixx=\"{ixx}\" ixy=\"{ixy}\" ixz=\"{ixz}\" iyy=\"{iyy}\" ",
                    "iyz=\"{iyz}\" izz=\"{izz}\"/>\n",
                    "    </inertial>\n",
                    "  </link>\n",
                    "  <joint name=\"joint{number}\" type=\"revolute\">\n",
                    "    <parent link=\"{parent}\"/>\n",
                    "    <child link=\"{link}\"/>\n",
                    "    <origin xyz=\"{ox} {oy} {oz}\" rpy=\"{twist} 0 0\"/>\n",
                    "    <axis xyz=\"0 0 1\"/>\n",
                    "    <limit lower=\"{lower}\" upper=\"{upper}\" effort=\"{effort}\" ",
                    "velocity=\"{velocity}\"/>\n",
                    "    <dynamics damping=\"{damping}\" friction=\"{friction}\"/>\n",
                    "  </joint>"
                ),
                link = link,
                cx = c.x,
                cy = c.y,
                cz = c.z,
                mass = j.mass,
                ixx = at(0, 0),
                ixy = at(0, 1),
                ixz = at(0, 2),
                iyy = at(1, 1),
                iyz = at(1, 2),
                izz = at(2, 2),
                number = i + 1,
                parent = parent,
                ox = o.x,
                oy = o.y,
                oz = o.z,
                twist = j.frame.twist.radians(),
                lower = -j.limit,
                upper = j.limit,
                effort = j.effort,
                velocity = j.velocity,
                damping = j.damping,
                friction = j.friction,
            )?;
            parent = link;
        }
        let t = self.tool;
        writeln!(
            s,
            "  <link name=\"tool\"/>\n  <joint name=\"tool_joint\" type=\"fixed\">\n    <parent \
             link=\"{parent}\"/>\n    <child link=\"tool\"/>\n    <origin xyz=\"{} {} {}\" \
             rpy=\"0 0 0\"/>\n  </joint>\n</robot>",
            t.x, t.y, t.z
        )
    }

    /// Total moving mass (kg) and the reach from the shoulder's axis to the tool (m, the sum of
    /// the link lengths beyond the base joint), for a one-line description.
    pub fn mass_and_reach(&self) -> (f64, f64) {
        let mass = self.joints.iter().map(|j| j.mass).sum();
        let reach = self
            .joints
            .iter()
            .skip(2)
            .map(|j| j.frame.origin().length())
            .sum::<f64>()
            + self.tool.length();
        (mass, reach)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_seed_gives_one_arm_and_another_seed_another() {
        for n in JOINTS {
            let a = generate(n, 7).unwrap();
            assert_eq!(a, generate(n, 7).unwrap());
            assert_ne!(a.to_urdf(), generate(n, 8).unwrap().to_urdf());
            assert_eq!(a.joints.len(), n);
        }
    }

    #[test]
    fn every_inertia_is_a_rigid_bodys() {
        for n in JOINTS {
            for seed in 0..50 {
                for j in generate(n, seed).unwrap().joints {
                    let m = j.inertia;
                    assert!(j.mass > 0.0);
                    // Symmetric, positive definite, principal moments satisfying the triangle
                    // inequality (Sylvester on the tensor, the trace bound on its diagonal).
                    for (i, k) in [(0, 1), (0, 2), (1, 2)] {
                        assert_eq!(m.col(k)[i], m.col(i)[k]);
                    }
                    let minor = m.col(0)[0] * m.col(1)[1] - m.col(1)[0] * m.col(0)[1];
                    assert!(m.col(0)[0] > 0.0 && minor > 0.0 && m.determinant() > 0.0);
                    let d = [m.col(0)[0], m.col(1)[1], m.col(2)[2]];
                    let tr: f64 = d.iter().sum();
                    assert!(d.iter().all(|v| 2.0 * v <= tr * (1.0 + 1e-12)), "{d:?}");
                }
            }
        }
    }

    #[test]
    fn two_and_eight_joints_are_refused() {
        let e = generate(2, 1).unwrap_err();
        assert_eq!(e, JointCountError(2));
        assert!(e.to_string().contains("3 to 7 joints"), "{e}");
        assert_eq!(generate(8, 1).unwrap_err(), JointCountError(8));
    }
}
