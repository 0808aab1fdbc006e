//! A kinematic tree of rigid bodies, each attached to its parent by one revolute or prismatic
//! joint, and the dynamics algorithms on it. `Model` is the robot (immutable, shareable);
//! `Data` holds every buffer the algorithms write, allocated once (Pinocchio's Model/Data split),
//! so no call allocates and a controller and a plant can each own their own `Data`.
//!
//! Equation of motion (RKGNN paper, eq. 1): tau = M(q) qdd + V(q, qd) + G(q) + F(qd).

use super::spatial::{Articulated, Force, Inertia, Motion, Transform};
use evoloop_linalg::{cholesky_solve_in_place, NotPositiveDefinite};
use glam::{DMat3, DVec3};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// How a joint moves its body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    /// Turns about its axis: positions in rad, efforts in N m.
    Revolute,
    /// Slides along its axis: positions in m, efforts in N.
    Prismatic,
}

/// Joint friction: viscous plus Coulomb, the Coulomb part smoothed by tanh(qd / v_smooth) so the
/// equations stay Lipschitz through zero velocity (an integrator-friendly stand-in for stiction).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Friction {
    /// Viscous coefficient (N m s/rad; N s/m on a prismatic joint).
    pub viscous: f64,
    /// Coulomb level (N m; N on a prismatic joint).
    pub coulomb: f64,
    /// Velocity scale of the Coulomb part's tanh (rad/s or m/s; default 0.01): at this velocity it
    /// gives 76 % of `coulomb`.
    pub v_smooth: f64,
}

impl Default for Friction {
    fn default() -> Self {
        Self {
            viscous: 0.0,
            coulomb: 0.0,
            v_smooth: 0.01,
        }
    }
}

impl Friction {
    /// The friction torque (force, on a prismatic joint) at joint velocity `qd`:
    /// viscous qd + coulomb tanh(qd / v_smooth).
    pub fn torque(&self, qd: f64) -> f64 {
        self.viscous * qd + self.coulomb * (qd / self.v_smooth).tanh()
    }
}

/// Joint limits; infinite where the description gives none.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Limits {
    /// Lower position limit (rad; m on a prismatic joint).
    pub q_min: f64,
    /// Upper position limit (rad; m on a prismatic joint).
    pub q_max: f64,
    /// Velocity limit (rad/s; m/s on a prismatic joint).
    pub velocity: f64,
    /// Effort limit: the actuator's largest torque (N m), or force on a prismatic joint (N).
    pub effort: f64,
}

impl Limits {
    /// The position range, or -pi..pi for a joint without (finite, non-empty) limits: where
    /// random and probe states are drawn.
    pub fn position_span(&self) -> (f64, f64) {
        if self.q_min.is_finite() && self.q_max.is_finite() && self.q_min < self.q_max {
            (self.q_min, self.q_max)
        } else {
            (-std::f64::consts::PI, std::f64::consts::PI)
        }
    }
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            q_min: f64::NEG_INFINITY,
            q_max: f64::INFINITY,
            velocity: f64::INFINITY,
            effort: f64::INFINITY,
        }
    }
}

/// One moving body and the joint that moves it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Body {
    /// The joint's name (URDF joint name, or `joint<i>` for D-H rows).
    pub joint: String,
    /// The body's (link's) name.
    pub link: String,
    /// Index of the parent body; `None` for bodies attached to the fixed root.
    pub parent: Option<usize>,
    /// Parent body frame → joint frame (before the joint moves).
    #[serde(skip)]
    pub placement: Transform,
    /// Whether the joint turns about `axis` or slides along it.
    pub kind: JointKind,
    /// Unit joint axis in the joint frame.
    #[serde(skip)]
    pub axis: DVec3,
    /// The body's inertia in its own frame (the joint frame after the joint's motion).
    #[serde(skip)]
    pub inertia: Inertia,
    /// The joint's friction, F(qd).
    pub friction: Friction,
    /// The joint's position, velocity and effort limits.
    pub limits: Limits,
    /// Reflected rotor inertia added to M's diagonal (Pinocchio's and MuJoCo's `armature`).
    pub armature: f64,
}

/// A robot: its moving bodies, each with the joint that moves it, and gravity. Immutable; the
/// algorithms write into a `Data` of it (`Model::data`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Model {
    /// The robot's name (URDF `<robot name>`; D-H `name`, or the file's stem).
    pub name: String,
    /// Bodies in an order where every parent precedes its children.
    pub bodies: Vec<Body>,
    /// Gravitational acceleration in root coordinates (m/s^2).
    #[serde(skip)]
    pub gravity: DVec3,
}

/// Buffers for the algorithms on one model.
#[derive(Debug, Clone)]
pub struct Data {
    /// Parent → body transforms at the last `update` configuration.
    pub x: Vec<Transform>,
    /// Joint motion subspaces (axis) per body, in body coordinates.
    pub(super) s: Vec<Motion>,
    /// Body velocities and accelerations (gravity included as the root's) of the last pass.
    pub(super) v: Vec<Motion>,
    pub(super) a: Vec<Motion>,
    f: Vec<Force>,
    ic: Vec<Inertia>,
    /// The joint-space inertia matrix from the last `mass_matrix` call.
    pub m: DMatrix<f64>,
    /// Workspace for the Cholesky factor (M is kept intact).
    chol: DMatrix<f64>,
    rhs: DVector<f64>,
    tmp: Vec<f64>,
    tmp2: Vec<f64>,
    /// Zero joint velocities for G(q); never written (the scratch buffers above are).
    zero: Vec<f64>,
    /// The regressor's n x n workspace: entry i n + j is joint j's motion subspace in body i's
    /// coordinates, for j an ancestor of i (or i itself).
    pub(super) sub: Vec<Motion>,
    /// ABA's buffers (its bias forces go in `f`): articulated inertias, velocity-product
    /// accelerations c, U = I^A S, 1/D and u.
    ia: Vec<Articulated>,
    c: Vec<Motion>,
    ua: Vec<Force>,
    d_inv: Vec<f64>,
    u: Vec<f64>,
}

impl Body {
    /// A revolute joint about its frame's z axis: motion subspace S = [z; 0].
    #[inline]
    pub fn is_z_revolute(&self) -> bool {
        self.kind == JointKind::Revolute && self.axis == DVec3::Z
    }

    /// The parent → body transform at joint position q: the placement, then the joint's motion.
    pub fn transform(&self, q: f64) -> Transform {
        let joint = match self.kind {
            JointKind::Revolute => {
                // Rotation about the unit axis by q: child axes in joint coordinates are
                // R(axis, q); the transform rotates joint coordinates into child ones by Rᵀ.
                let r = if self.axis == DVec3::Z {
                    DMat3::from_rotation_z(q)
                } else {
                    DMat3::from_axis_angle(self.axis, q)
                };
                Transform::from_placement(r, DVec3::ZERO)
            }
            JointKind::Prismatic => Transform {
                e: DMat3::IDENTITY,
                r: self.axis * q,
            },
        };
        self.placement.then(&joint)
    }

    /// `transform` for a revolute joint about z, the common case (every D-H joint, most URDF
    /// joints), written out: the child's axes are R_z(q)ᵀ times the placement's. Of the general
    /// product only the terms that are not exact zeros are left (12 products instead of 36), so
    /// the values are the same (a dropped term only ever added a zero; tested): RNEA, CRBA and
    /// ABA all start from these transforms.
    #[inline]
    pub fn transform_z(&self, q: f64) -> Transform {
        let (s, c) = q.sin_cos();
        let p = &self.placement;
        let rot = |v: DVec3| DVec3::new(c * v.x + s * v.y, -s * v.x + c * v.y, v.z);
        Transform {
            e: DMat3::from_cols(rot(p.e.x_axis), rot(p.e.y_axis), rot(p.e.z_axis)),
            r: p.r,
        }
    }
}

impl Model {
    /// Number of joints (degrees of freedom).
    pub fn dof(&self) -> usize {
        self.bodies.len()
    }

    /// Fresh buffers for the algorithms on this model, allocated here once: no call on them
    /// allocates afterwards.
    pub fn data(&self) -> Data {
        let n = self.dof();
        Data {
            x: vec![Transform::IDENTITY; n],
            s: self
                .bodies
                .iter()
                .map(|b| match b.kind {
                    JointKind::Revolute => Motion {
                        w: b.axis,
                        v: DVec3::ZERO,
                    },
                    JointKind::Prismatic => Motion {
                        w: DVec3::ZERO,
                        v: b.axis,
                    },
                })
                .collect(),
            v: vec![Motion::ZERO; n],
            a: vec![Motion::ZERO; n],
            f: vec![Force::ZERO; n],
            ic: vec![Inertia::ZERO; n],
            m: DMatrix::zeros(n, n),
            chol: DMatrix::zeros(n, n),
            rhs: DVector::zeros(n),
            tmp: vec![0.0; n],
            tmp2: vec![0.0; n],
            zero: vec![0.0; n],
            sub: vec![Motion::ZERO; n * n],
            ia: vec![Articulated::ZERO; n],
            c: vec![Motion::ZERO; n],
            ua: vec![Force::ZERO; n],
            d_inv: vec![0.0; n],
            u: vec![0.0; n],
        }
    }

    /// The parent → body transforms for configuration q.
    pub fn update(&self, d: &mut Data, q: &[f64]) {
        for (i, b) in self.bodies.iter().enumerate() {
            d.x[i] = if b.is_z_revolute() {
                b.transform_z(q[i])
            } else {
                b.transform(q[i])
            };
        }
    }

    /// The forward pass of Newton-Euler on the transforms of the last `update`: body velocities
    /// and accelerations into `d.v`, `d.a` (qdd = None means zero acceleration; `gravity` false
    /// drops it). The regressor's first pass; RNEA takes the same `body_motion` step in its own
    /// loop, fused with the forces.
    pub(super) fn motion_pass(&self, d: &mut Data, qd: &[f64], qdd: Option<&[f64]>, gravity: bool) {
        let a_root = self.root_acceleration(gravity);
        for (i, b) in self.bodies.iter().enumerate() {
            (d.v[i], d.a[i]) = body_motion(d, i, b.parent, qd, qdd, a_root);
        }
    }

    /// Gravity enters as a fictitious upward acceleration of the root (Featherstone 5.3).
    fn root_acceleration(&self, gravity: bool) -> Motion {
        Motion {
            w: DVec3::ZERO,
            v: if gravity { -self.gravity } else { DVec3::ZERO },
        }
    }

    /// Recursive Newton-Euler on the transforms of the last `update`: tau = M qdd + V + G
    /// (qdd = None means zero acceleration; `gravity` false drops G). Friction not included.
    fn rnea_pass(
        &self,
        d: &mut Data,
        qd: &[f64],
        qdd: Option<&[f64]>,
        gravity: bool,
        tau: &mut [f64],
    ) {
        let a_root = self.root_acceleration(gravity);
        for (i, b) in self.bodies.iter().enumerate() {
            let (v, a) = body_motion(d, i, b.parent, qd, qdd, a_root);
            (d.v[i], d.a[i]) = (v, a);
            d.f[i] = b.inertia.apply(a) + v.cross_force(b.inertia.apply(v));
        }
        for i in (0..self.dof()).rev() {
            let fi = d.f[i];
            tau[i] = d.s[i].dot(fi);
            if let Some(qdd) = qdd {
                tau[i] += self.bodies[i].armature * qdd[i];
            }
            if let Some(p) = self.bodies[i].parent {
                let fp = d.x[i].apply_transpose_force(fi);
                d.f[p] = d.f[p] + fp;
            }
        }
    }

    /// Composite rigid body algorithm on the transforms of the last `update`, into `d.m`.
    fn crba_pass(&self, d: &mut Data) {
        let n = self.dof();
        for i in 0..n {
            d.ic[i] = self.bodies[i].inertia;
        }
        for i in (0..n).rev() {
            if let Some(p) = self.bodies[i].parent {
                let add = d.ic[i].to_parent(&d.x[i]);
                d.ic[p] = d.ic[p] + add;
            }
        }
        for i in 0..n {
            let mut f = d.ic[i].apply(d.s[i]);
            d.m[(i, i)] = d.s[i].dot(f) + self.bodies[i].armature;
            let mut j = i;
            while let Some(p) = self.bodies[j].parent {
                f = d.x[j].apply_transpose_force(f);
                j = p;
                let mij = d.s[j].dot(f);
                d.m[(i, j)] = mij;
                d.m[(j, i)] = mij;
            }
        }
        // Entries between bodies on different branches stay zero.
    }

    /// Whether any joint has friction or damping (F(qd) is not identically zero).
    pub fn has_friction(&self) -> bool {
        self.bodies
            .iter()
            .any(|b| b.friction.viscous != 0.0 || b.friction.coulomb != 0.0)
    }

    /// Drop every joint's friction and damping: the rigid-body model (armature stays, it is
    /// inertia).
    pub fn clear_friction(&mut self) {
        for b in &mut self.bodies {
            b.friction.viscous = 0.0;
            b.friction.coulomb = 0.0;
        }
    }

    /// Joint friction F(qd).
    pub fn friction(&self, qd: &[f64], out: &mut [f64]) {
        for (i, b) in self.bodies.iter().enumerate() {
            out[i] = b.friction.torque(qd[i]);
        }
    }

    /// Inverse dynamics tau = M qdd + V + G + F.
    pub fn inverse_dynamics(
        &self,
        d: &mut Data,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) {
        self.update(d, q);
        self.rnea_pass(d, qd, Some(qdd), true, tau);
        for (i, b) in self.bodies.iter().enumerate() {
            tau[i] += b.friction.torque(qd[i]);
        }
    }

    /// Rigid-body inverse dynamics M qdd + V + G (no friction): what Pinocchio's `rnea` returns.
    pub fn rnea(&self, d: &mut Data, q: &[f64], qd: &[f64], qdd: &[f64], tau: &mut [f64]) {
        self.update(d, q);
        self.rnea_pass(d, qd, Some(qdd), true, tau);
    }

    /// The joint-space inertia matrix M(q), left in `d.m` (and returned).
    pub fn mass_matrix<'d>(&self, d: &'d mut Data, q: &[f64]) -> &'d DMatrix<f64> {
        self.update(d, q);
        self.crba_pass(d);
        &d.m
    }

    /// The gravity vector G(q).
    pub fn gravity_torque(&self, d: &mut Data, q: &[f64], out: &mut [f64]) {
        self.update(d, q);
        let zero = std::mem::take(&mut d.zero);
        self.rnea_pass(d, &zero, None, true, out);
        d.zero = zero;
    }

    /// The centrifugal and Coriolis vector V(q, qd).
    pub fn coriolis(&self, d: &mut Data, q: &[f64], qd: &[f64], out: &mut [f64]) {
        self.update(d, q);
        self.rnea_pass(d, qd, None, false, out);
    }

    /// The Coriolis matrix C(q, qd) of the Christoffel symbols, with V = C qd and Mdot - 2C skew
    /// symmetric. V is a quadratic form in qd whose symmetric coefficients are exactly the
    /// Christoffel symbols of the first kind, so column j of C is the polarisation
    /// (V(qd + e_j) - V(qd - e_j)) / 4: exact for a quadratic, 2n passes of RNEA.
    pub fn coriolis_matrix(&self, d: &mut Data, q: &[f64], qd: &[f64], c: &mut DMatrix<f64>) {
        let n = self.dof();
        self.update(d, q);
        let mut plus = std::mem::take(&mut d.tmp);
        let mut minus = std::mem::take(&mut d.tmp2);
        for j in 0..n {
            plus.copy_from_slice(qd);
            plus[j] += 1.0;
            minus.copy_from_slice(qd);
            minus[j] -= 1.0;
            let mut vp = [0.0; evoloop_msg::MAX_JOINTS];
            let mut vm = [0.0; evoloop_msg::MAX_JOINTS];
            self.rnea_pass(d, &plus, None, false, &mut vp[..n]);
            self.rnea_pass(d, &minus, None, false, &mut vm[..n]);
            for i in 0..n {
                c[(i, j)] = 0.25 * (vp[i] - vm[i]);
            }
        }
        d.tmp = plus;
        d.tmp2 = minus;
    }

    /// Forward dynamics qdd = M^-1 (tau - V - G - F), by a Cholesky factorisation of M.
    pub fn forward_dynamics(
        &self,
        d: &mut Data,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), NotPositiveDefinite> {
        let n = self.dof();
        self.update(d, q);
        let mut bias = std::mem::take(&mut d.tmp);
        self.rnea_pass(d, qd, None, true, &mut bias);
        self.crba_pass(d);
        for i in 0..n {
            d.rhs[i] = tau[i] - bias[i] - self.bodies[i].friction.torque(qd[i]);
        }
        d.tmp = bias;
        d.chol.copy_from(&d.m);
        cholesky_solve_in_place(&mut d.chol, &mut d.rhs)?;
        qdd.copy_from_slice(&d.rhs.as_slice()[..n]);
        Ok(())
    }

    /// Forward dynamics qdd = M^-1 (tau - V - G - F) by Featherstone's articulated-body
    /// algorithm (RBDA, Table 7.1): O(n), three passes, no joint-space matrix. Armature enters
    /// D_i = S_iᵀ U_i + armature_i, as it enters M's diagonal. Err when a D_i is not positive
    /// (a subtree that carries no inertia about its joint), as the Cholesky route fails then.
    pub fn forward_dynamics_aba(
        &self,
        d: &mut Data,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<(), NotPositiveDefinite> {
        let n = self.dof();
        self.update(d, q);
        for (i, b) in self.bodies.iter().enumerate() {
            let v_p = b.parent.map_or(Motion::ZERO, |p| d.v[p]);
            let vj = d.s[i].scaled(qd[i]);
            let v = d.x[i].apply_motion(v_p) + vj;
            d.v[i] = v;
            d.c[i] = v.cross_motion(vj);
            d.ia[i] = Articulated::rigid(&b.inertia);
            d.f[i] = v.cross_force(b.inertia.apply(v));
        }
        for i in (0..n).rev() {
            let b = &self.bodies[i];
            let s = d.s[i];
            let ua = d.ia[i].apply(s);
            let di = s.dot(ua) + b.armature;
            if di.is_nan() || di <= 0.0 {
                return Err(NotPositiveDefinite { joint: i });
            }
            let u = tau[i] - s.dot(d.f[i]) - b.friction.torque(qd[i]);
            (d.ua[i], d.d_inv[i], d.u[i]) = (ua, 1.0 / di, u);
            if let Some(p) = b.parent {
                let ia = d.ia[i].minus_outer(ua, d.d_inv[i]);
                let pa = d.f[i] + ia.apply(d.c[i]) + ua.scaled(u * d.d_inv[i]);
                d.ia[p] = d.ia[p] + ia.to_parent(&d.x[i]);
                d.f[p] = d.f[p] + d.x[i].apply_transpose_force(pa);
            }
        }
        let a_root = self.root_acceleration(true);
        for (i, b) in self.bodies.iter().enumerate() {
            let a_p = b.parent.map_or(a_root, |p| d.a[p]);
            let a = d.x[i].apply_motion(a_p) + d.c[i];
            qdd[i] = (d.u[i] - a.dot(d.ua[i])) * d.d_inv[i];
            d.a[i] = a + d.s[i].scaled(qdd[i]);
        }
        Ok(())
    }

    /// Kinetic energy 1/2 qdᵀ M(q) qd.
    pub fn kinetic_energy(&self, d: &mut Data, q: &[f64], qd: &[f64]) -> f64 {
        let m = self.mass_matrix(d, q);
        let n = qd.len();
        let mut e = 0.0;
        for i in 0..n {
            for j in 0..n {
                e += qd[i] * m[(i, j)] * qd[j];
            }
        }
        0.5 * e
    }

    /// Root -> body transforms at q (forward kinematics); allocates, for tests and reports.
    pub fn world_transforms(&self, d: &mut Data, q: &[f64]) -> Vec<Transform> {
        self.update(d, q);
        let mut world: Vec<Transform> = Vec::with_capacity(self.dof());
        for (i, b) in self.bodies.iter().enumerate() {
            let x0 = match b.parent {
                Some(p) => world[p].then(&d.x[i]),
                None => d.x[i],
            };
            world.push(x0);
        }
        world
    }

    /// Potential energy of gravity, -sum m_i g . c_i (zero at the root's origin).
    pub fn potential_energy(&self, d: &mut Data, q: &[f64]) -> f64 {
        self.world_transforms(d, q)
            .iter()
            .zip(&self.bodies)
            .map(|(x, b)| -b.inertia.m * self.gravity.dot(x.point_to_parent(b.inertia.com())))
            .sum()
    }

    /// Root-frame origins of the bodies.
    pub fn body_origins(&self, d: &mut Data, q: &[f64]) -> Vec<DVec3> {
        self.world_transforms(d, q).iter().map(|x| x.r).collect()
    }
}

/// Body i's velocity and acceleration from its parent's (already in `d.v`, `d.a`): the step of
/// the forward pass that RNEA and the regressor share.
#[inline(always)]
fn body_motion(
    d: &Data,
    i: usize,
    parent: Option<usize>,
    qd: &[f64],
    qdd: Option<&[f64]>,
    a_root: Motion,
) -> (Motion, Motion) {
    let (v_p, a_p) = match parent {
        Some(p) => (d.v[p], d.a[p]),
        None => (Motion::ZERO, a_root),
    };
    let (x, s) = (d.x[i], d.s[i]);
    let vj = s.scaled(qd[i]);
    let v = x.apply_motion(v_p) + vj;
    let mut a = x.apply_motion(a_p) + v.cross_motion(vj);
    if let Some(qdd) = qdd {
        a = a + s.scaled(qdd[i]);
    }
    (v, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The written-out z rotation gives exactly the general product's values, on every z joint
    /// of the shipped arms (D-H and URDF placements) over a sweep of angles.
    #[test]
    fn z_joint_transform_equals_the_general_product_exactly() {
        let mut checked = 0;
        for file in [
            "config/robots/arm7.urdf",
            "config/robots/industrial6.toml",
            "config/robots/arm3.toml",
        ] {
            // The workspace's robot files (config/robots at its root).
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../..")
                .join(file);
            let model = crate::load(&path).unwrap();
            for b in model.bodies.iter().filter(|b| b.axis == DVec3::Z) {
                for k in -400..=400 {
                    let q = k as f64 * 0.0123 + 1e-3;
                    let (fast, general) = (b.transform_z(q), b.transform(q));
                    // == also holds for 0.0 against -0.0, the only difference a dropped zero
                    // term can make.
                    assert_eq!(fast, general, "{file} {} at q = {q}", b.joint);
                    checked += 1;
                }
            }
        }
        assert!(checked > 10 * 801, "{checked}");
    }
}
