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
    pub(super) s: Vec<Subspace>,
    /// Body velocities and accelerations (gravity included as the root's) of the last pass.
    pub(super) v: Vec<Motion>,
    pub(super) a: Vec<Motion>,
    f: Vec<Force>,
    ic: Vec<Inertia>,
    /// CRBA's column forces: entry k is Ic_k S_k carried toward the root (`crba_pass`).
    col: Vec<Force>,
    /// Body i's subtree: i, then its descendants in increasing order.
    subtree: Vec<Vec<usize>>,
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

/// A joint's motion subspace S, in its body's coordinates. A revolute joint about its frame's z
/// axis (every D-H joint, most URDF ones) has S = [z; 0], and its products with S pick or place
/// one component: the general products' values (their other terms are products with exact
/// zeros; an exact zero may differ in sign), for fewer operations in RNEA, CRBA and ABA.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Subspace {
    /// Revolute about the body frame's z axis: S = [z; 0].
    RevoluteZ,
    /// Any other joint: S as a motion vector.
    General(Motion),
}

impl Subspace {
    /// The joint's subspace: [axis; 0] for a revolute joint, [0; axis] for a prismatic one.
    fn of(b: &Body) -> Subspace {
        match b.kind {
            _ if b.is_z_revolute() => Subspace::RevoluteZ,
            JointKind::Revolute => Subspace::General(Motion {
                w: b.axis,
                v: DVec3::ZERO,
            }),
            JointKind::Prismatic => Subspace::General(Motion {
                w: DVec3::ZERO,
                v: b.axis,
            }),
        }
    }

    /// S as a motion vector.
    #[inline(always)]
    pub(super) fn motion(self) -> Motion {
        match self {
            Subspace::RevoluteZ => Motion {
                w: DVec3::Z,
                v: DVec3::ZERO,
            },
            Subspace::General(s) => s,
        }
    }

    /// Sᵀ f, the joint's share of the force f.
    #[inline(always)]
    fn dot(self, f: Force) -> f64 {
        match self {
            Subspace::RevoluteZ => f.n.z,
            Subspace::General(s) => s.dot(f),
        }
    }

    /// S x, the joint's motion at rate x.
    #[inline(always)]
    fn scaled(self, x: f64) -> Motion {
        match self {
            Subspace::RevoluteZ => Motion {
                w: DVec3::new(0.0, 0.0, x),
                v: DVec3::ZERO,
            },
            Subspace::General(s) => s.scaled(x),
        }
    }

    /// I S, the momentum of a rigid body of inertia `i` moving as S.
    #[inline(always)]
    fn momentum(self, i: &Inertia) -> Force {
        match self {
            Subspace::RevoluteZ => i.apply_z(),
            Subspace::General(s) => i.apply(s),
        }
    }
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
            s: self.bodies.iter().map(Subspace::of).collect(),
            v: vec![Motion::ZERO; n],
            a: vec![Motion::ZERO; n],
            f: vec![Force::ZERO; n],
            ic: vec![Inertia::ZERO; n],
            col: vec![Force::ZERO; n],
            subtree: self.subtrees(),
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

    /// Each body's subtree: the body, then its descendants in increasing order (a body's
    /// descendants come after it).
    fn subtrees(&self) -> Vec<Vec<usize>> {
        let mut subtree = vec![Vec::new(); self.dof()];
        for k in 0..self.dof() {
            let mut j = Some(k);
            while let Some(a) = j {
                subtree[a].push(k);
                j = self.bodies[a].parent;
            }
        }
        // A body heads its own list only if parents precede their children, as `crba_pass`
        // needs (it reads the descendants from index 1 on).
        debug_assert!(subtree.iter().enumerate().all(|(i, s)| s[0] == i));
        subtree
    }

    /// The parent → body transforms for configuration q.
    pub fn update(&self, d: &mut Data, q: &[f64]) {
        for (i, b) in self.bodies.iter().enumerate() {
            d.x[i] = if matches!(d.s[i], Subspace::RevoluteZ) {
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
    ///
    /// One backward pass: body i's composite inertia is complete once its children (later in
    /// the order) have added theirs, so its column's force Ic_i S_i is formed there; then every
    /// column force that has reached body i (its own and its descendants', `Data::subtree`)
    /// gives row i's entries and moves on to the parent (Pinocchio's order). Each column goes
    /// through the same operations as when carried to the root on its own, in the same order,
    /// so M(q) is the column-by-column pass's (tested against it). With the z joints' products
    /// written out, this order is the faster one; either change alone gained nothing
    /// (measurement record 2026-12-07-crba).
    fn crba_pass(&self, d: &mut Data) {
        for (ic, b) in d.ic.iter_mut().zip(&self.bodies) {
            *ic = b.inertia;
        }
        for i in (0..self.dof()).rev() {
            let b = &self.bodies[i];
            let s = d.s[i];
            d.col[i] = s.momentum(&d.ic[i]);
            d.m[(i, i)] = s.dot(d.col[i]) + b.armature;
            for &k in &d.subtree[i][1..] {
                let mik = s.dot(d.col[k]);
                d.m[(i, k)] = mik;
                d.m[(k, i)] = mik;
            }
            if let Some(p) = b.parent {
                let x = d.x[i];
                for &k in &d.subtree[i] {
                    d.col[k] = x.apply_transpose_force(d.col[k]);
                }
                let add = d.ic[i].to_parent(&x);
                d.ic[p] = d.ic[p] + add;
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
            let ua = d.ia[i].apply(s.motion());
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
    let x = d.x[i];
    let vj = d.s[i].scaled(qd[i]);
    let v = x.apply_motion(v_p) + vj;
    let mut a = x.apply_motion(a_p) + v.cross_motion(vj);
    if let Some(qdd) = qdd {
        a = a + d.s[i].scaled(qdd[i]);
    }
    (v, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped arms (D-H and URDF placements) and the UR5-style test arm (joints about y
    /// beside joints about z), loaded from the workspace's files, with their names.
    fn arms() -> Vec<(&'static str, Model)> {
        [
            "config/robots/arm7.urdf",
            "config/robots/industrial6.toml",
            "config/robots/arm3.toml",
            "tests/robots/ur5_style.urdf",
        ]
        .into_iter()
        .map(|file| {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../..")
                .join(file);
            (file, crate::load(&path).unwrap())
        })
        .collect()
    }

    /// The written-out z rotation gives exactly the general product's values, on every z joint
    /// of the arms over a sweep of angles.
    #[test]
    fn z_joint_transform_equals_the_general_product_exactly() {
        let mut checked = 0;
        for (file, model) in arms() {
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

    /// M(q) by the column-by-column CRBA (each column's force carried to the root on its own,
    /// the general products throughout): the pass `crba_pass` replaced, kept as its reference.
    fn column_by_column_crba(model: &Model, d: &mut Data, q: &[f64]) -> DMatrix<f64> {
        let n = model.dof();
        model.update(d, q);
        let mut ic: Vec<Inertia> = model.bodies.iter().map(|b| b.inertia).collect();
        for i in (0..n).rev() {
            if let Some(p) = model.bodies[i].parent {
                let add = ic[i].to_parent(&d.x[i]);
                ic[p] = ic[p] + add;
            }
        }
        let mut m = DMatrix::zeros(n, n);
        for i in 0..n {
            let mut f = ic[i].apply(d.s[i].motion());
            m[(i, i)] = d.s[i].motion().dot(f) + model.bodies[i].armature;
            let mut j = i;
            while let Some(p) = model.bodies[j].parent {
                f = d.x[j].apply_transpose_force(f);
                j = p;
                m[(i, j)] = d.s[j].motion().dot(f);
                m[(j, i)] = m[(i, j)];
            }
        }
        m
    }

    /// `d` with every joint's subspace in its general form: the products with S in full.
    fn in_general_form(d: &mut Data) {
        for s in &mut d.s {
            *s = Subspace::General(s.motion());
        }
    }

    /// A sweep of states of an n-joint arm: entry j of state k, scaled by c.
    fn state(n: usize, k: usize, c: f64) -> Vec<f64> {
        (0..n)
            .map(|j| ((k * 7 + j * 3) as f64 * c).sin() * 2.5)
            .collect()
    }

    /// Pinocchio's order gives the column-by-column pass's M(q), on chains and on a branched
    /// tree with a prismatic joint and tilted axes: the same operations in the same order.
    #[test]
    fn crba_in_one_backward_pass_equals_the_column_by_column_pass() {
        let branched = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/robots/branched.urdf");
        let mut all = arms();
        all.push((
            "tests/robots/branched.urdf",
            crate::load(&branched).unwrap(),
        ));
        for (file, model) in all {
            let (mut d, mut reference) = (model.data(), model.data());
            in_general_form(&mut reference);
            for k in 0..200 {
                let q = state(model.dof(), k, 0.377);
                let want = column_by_column_crba(&model, &mut reference, &q);
                assert_eq!(model.mass_matrix(&mut d, &q), &want, "{file} at {q:?}");
            }
        }
    }

    /// RNEA, CRBA, ABA and the regressor with a z joint's S written out give the general
    /// products' values (== to the last bit; only an exact zero may differ in sign), on every
    /// arm over a sweep of states.
    #[test]
    fn z_joints_written_out_give_the_general_products_values_exactly() {
        for (file, model) in arms() {
            let (mut fast, mut general) = (model.data(), model.data());
            assert!(fast.s.contains(&Subspace::RevoluteZ), "{file}: no z joint");
            in_general_form(&mut general);
            let n = model.dof();
            let columns = model.regressor_columns(true);
            let (mut y_fast, mut y_general) =
                (DMatrix::zeros(n, columns), DMatrix::zeros(n, columns));
            for k in 0..200 {
                let (q, qd, qdd) = (state(n, k, 0.377), state(n, k, 0.291), state(n, k, 0.613));
                let m = model.mass_matrix(&mut fast, &q).clone();
                assert_eq!(&m, model.mass_matrix(&mut general, &q), "{file} at {q:?}");
                let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
                model.rnea(&mut fast, &q, &qd, &qdd, &mut a);
                model.rnea(&mut general, &q, &qd, &qdd, &mut b);
                assert_eq!(a, b, "{file} at {q:?}");
                model.regressor(&mut fast, &q, &qd, &qdd, &mut y_fast);
                model.regressor(&mut general, &q, &qd, &qdd, &mut y_general);
                assert_eq!(y_fast, y_general, "{file} at {q:?}");
                model
                    .forward_dynamics_aba(&mut fast, &q, &qd, &qdd, &mut a)
                    .unwrap();
                model
                    .forward_dynamics_aba(&mut general, &q, &qd, &qdd, &mut b)
                    .unwrap();
                assert_eq!(a, b, "{file} at {q:?}");
            }
        }
    }
}
