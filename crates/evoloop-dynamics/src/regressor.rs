//! The joint-torque regressor: tau = Y(q, qd, qdd) pi, linear in the inertial parameters.
//!
//! pi holds 10 parameters per moving body, bodies base to tip, each in the order
//! m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz with the inertia about the body
//! (joint) frame's origin: the order of Pinocchio's `Inertia::toDynamicParameters` and
//! `computeJointTorqueRegressor`, so the two compare column by column. Optional friction columns
//! follow all the bodies, two per joint: viscous (qd_j) and Coulomb (the model's smoothed sign,
//! tanh(qd_j / v_smooth)). A joint's armature is not a parameter (as in Pinocchio):
//! Y pi + armature * qdd is the model's inverse dynamics.
//!
//! The algorithm: a body's spatial force f_i = I_i a_i + v_i x* I_i v_i is linear in its
//! parameters, and joint j transmits S_j . f_i of every body i it carries. Written in body i's
//! coordinates, with s = S_j carried into them, S_j . f_i = s . I(a_i) - (v_i x s) . I(v_i), and
//! for each parameter the two scalar products are a few multiplications (`columns`). The
//! subspaces of a body's ancestors are carried down the tree once (`Data::sub`), so the cost is
//! one motion transform and ten short bilinear forms per (ancestor, body) pair, and nothing is
//! allocated.

use super::model::{Data, Model};
use super::spatial::Motion;
use nalgebra::DMatrix;

/// Inertial parameters per body.
pub const PER_BODY: usize = 10;

/// The parameters' names in a body, the body's number (1-based) appended: `m1`, `mx1`, `Ixx1`.
pub const NAMES: [&str; PER_BODY] = [
    "m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz",
];

/// y . I(x) for each unit parameter of an inertia, in `NAMES` order (y, x spatial motions).
#[inline]
fn columns(y: Motion, x: Motion) -> [f64; PER_BODY] {
    // h = e_k: I(x) = (e_k x x.v, -e_k x x.w), so y . I(x) is component k of this vector.
    let h = x.v.cross(y.w) - x.w.cross(y.v);
    let (yw, xw) = (y.w, x.w);
    [
        y.v.dot(x.v),
        h.x,
        h.y,
        h.z,
        yw.x * xw.x,
        yw.x * xw.y + yw.y * xw.x,
        yw.y * xw.y,
        yw.x * xw.z + yw.z * xw.x,
        yw.y * xw.z + yw.z * xw.y,
        yw.z * xw.z,
    ]
}

impl Model {
    /// Columns of the regressor: 10 per body, and 2 per joint with friction.
    pub fn regressor_columns(&self, friction: bool) -> usize {
        self.dof() * (PER_BODY + if friction { 2 } else { 0 })
    }

    /// Column names in order (`m1` .. `Izz<n>`, then `fv1`, `fc1`, .. with friction).
    pub fn parameter_names(&self, friction: bool) -> Vec<String> {
        let mut out: Vec<String> = (1..=self.dof())
            .flat_map(|b| NAMES.iter().map(move |p| format!("{p}{b}")))
            .collect();
        if friction {
            for j in 1..=self.dof() {
                out.push(format!("fv{j}"));
                out.push(format!("fc{j}"));
            }
        }
        out
    }

    /// The model's own parameter vector pi in column order.
    pub fn parameters(&self, friction: bool) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.regressor_columns(friction));
        for b in &self.bodies {
            let (h, i) = (b.inertia.h, b.inertia.i);
            out.extend_from_slice(&[
                b.inertia.m,
                h.x,
                h.y,
                h.z,
                i.x_axis.x,
                i.y_axis.x,
                i.y_axis.y,
                i.z_axis.x,
                i.z_axis.y,
                i.z_axis.z,
            ]);
        }
        if friction {
            for b in &self.bodies {
                out.extend_from_slice(&[b.friction.viscous, b.friction.coulomb]);
            }
        }
        out
    }

    /// Put `pi` (in `parameters` order: ten per body, then with `friction` fv, fc per joint,
    /// then with `armature` one per joint) into the model's bodies: the inverse of
    /// `parameters`. Any real vector is accepted, physically consistent or not (a base-parameter
    /// estimate puts whole regrouped sums on one column): every algorithm here is linear in the
    /// parameters and never divides by a mass. Allocation-free.
    pub fn set_parameters(&mut self, pi: &[f64], friction: bool, armature: bool) {
        let n = self.dof();
        let expected = self.regressor_columns(friction) + if armature { n } else { 0 };
        assert_eq!(pi.len(), expected, "one value per regressor column");
        for (b, p) in self.bodies.iter_mut().zip(pi.chunks_exact(PER_BODY)) {
            b.inertia.m = p[0];
            b.inertia.h = glam::DVec3::new(p[1], p[2], p[3]);
            b.inertia.i = glam::DMat3::from_cols_array(&[
                p[4], p[5], p[7], //
                p[5], p[6], p[8], //
                p[7], p[8], p[9],
            ]);
        }
        let mut rest = &pi[n * PER_BODY..];
        if friction {
            for (b, f) in self.bodies.iter_mut().zip(rest.chunks_exact(2)) {
                b.friction.viscous = f[0];
                b.friction.coulomb = f[1];
            }
            rest = &rest[2 * n..];
        }
        if armature {
            for (b, a) in self.bodies.iter_mut().zip(rest) {
                b.armature = *a;
            }
        }
    }

    /// Y(q, qd, qdd) into `y` (dof rows, `regressor_columns(friction)` columns; the friction
    /// columns are written when `y` has them). Allocation-free.
    pub fn regressor(
        &self,
        d: &mut Data,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        y: &mut DMatrix<f64>,
    ) {
        let n = self.dof();
        let friction = y.ncols() == self.regressor_columns(true);
        assert!(
            y.nrows() == n && (friction || y.ncols() == self.regressor_columns(false)),
            "the regressor is {n} x {} (or {} with friction), not {} x {}",
            self.regressor_columns(false),
            self.regressor_columns(true),
            y.nrows(),
            y.ncols()
        );
        self.update(d, q);
        self.motion_pass(d, qd, Some(qdd), true);
        y.as_mut_slice().fill(0.0); // a memset (DMatrix::fill walks entry by entry)
        for (i, b) in self.bodies.iter().enumerate() {
            // Carry the ancestors' subspaces into body i's coordinates.
            d.sub[i * n + i] = d.s[i].motion();
            let mut j = b.parent;
            while let Some(k) = j {
                let p = b.parent.unwrap_or(k);
                d.sub[i * n + k] = d.x[i].apply_motion(d.sub[p * n + k]);
                j = self.bodies[k].parent;
            }
            let (v, a) = (d.v[i], d.a[i]);
            // Body i's ten columns, column-major: entry (k, c) at c n + k.
            let block = &mut y.as_mut_slice()[PER_BODY * i * n..PER_BODY * (i + 1) * n];
            let mut j = Some(i);
            while let Some(k) = j {
                let s = d.sub[i * n + k];
                let plus = columns(s, a);
                let minus = columns(v.cross_motion(s), v);
                for (c, (p, m)) in plus.iter().zip(&minus).enumerate() {
                    block[c * n + k] = p - m;
                }
                j = self.bodies[k].parent;
            }
        }
        if friction {
            for (j, b) in self.bodies.iter().enumerate() {
                y[(j, PER_BODY * n + 2 * j)] = qd[j];
                y[(j, PER_BODY * n + 2 * j + 1)] = (qd[j] / b.friction.v_smooth).tanh();
            }
        }
    }
}
