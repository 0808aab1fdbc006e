//! A serial (or branched) arm as a plant: x = [q; qd], u = joint torques (forces for prismatic
//! joints), y = q. The forward dynamics come from `dynamics::Model`; torques are clipped to each
//! joint's effort limit, and joint position limits act as inelastic stops (after each integration
//! step a joint past its limit is put back on it and its velocity into the limit removed).

use super::Plant;
use crate::dynamics::{Data, Model};
use std::cell::RefCell;

pub struct Arm {
    pub model: Model,
    /// `derivative` takes &self (the integrator's contract), the algorithms need buffers: the
    /// plant is owned by one simulator thread, so a RefCell is enough and never contended.
    data: RefCell<Data>,
    tau: RefCell<Vec<f64>>,
    pub x0: Vec<f64>,
}

impl Arm {
    /// The arm at rest at joint positions `q0`.
    pub fn new(model: Model, q0: &[f64]) -> Self {
        let n = model.dof();
        assert_eq!(q0.len(), n, "one initial position per joint");
        let mut x0 = vec![0.0; 2 * n];
        x0[..n].copy_from_slice(q0);
        Self {
            data: RefCell::new(model.data()),
            tau: RefCell::new(vec![0.0; n]),
            model,
            x0,
        }
    }
}

impl Plant for Arm {
    fn n_states(&self) -> usize {
        2 * self.model.dof()
    }
    fn n_inputs(&self) -> usize {
        self.model.dof()
    }
    fn n_outputs(&self) -> usize {
        self.model.dof()
    }
    fn n_joints(&self) -> usize {
        self.model.dof()
    }

    fn derivative(&self, _t: f64, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let n = self.model.dof();
        let (q, qd) = x.split_at(n);
        let mut tau = self.tau.borrow_mut();
        for (i, b) in self.model.bodies.iter().enumerate() {
            tau[i] = u[i].clamp(-b.limits.effort, b.limits.effort);
        }
        dx[..n].copy_from_slice(qd);
        let mut d = self.data.borrow_mut();
        // M(q) was checked positive definite when the robot loaded; should a configuration make
        // it singular the joints are frozen for this stage rather than poisoned with NaN.
        if self
            .model
            .forward_dynamics(&mut d, q, qd, &tau, &mut dx[n..])
            .is_err()
        {
            dx[n..].fill(0.0);
        }
    }

    fn output(&self, x: &[f64], y: &mut [f64]) {
        let n = self.model.dof();
        y[..n].copy_from_slice(&x[..n]);
    }

    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        let n = self.model.dof();
        q[..n].copy_from_slice(&x[..n]);
        qd[..n].copy_from_slice(&x[n..2 * n]);
    }

    fn initial_state(&self, x: &mut [f64]) {
        x.copy_from_slice(&self.x0);
    }

    fn constrain(&self, x: &mut [f64]) {
        let n = self.model.dof();
        for (i, b) in self.model.bodies.iter().enumerate() {
            if x[i] < b.limits.q_min {
                x[i] = b.limits.q_min;
                x[n + i] = x[n + i].max(0.0);
            } else if x[i] > b.limits.q_max {
                x[i] = b.limits.q_max;
                x[n + i] = x[n + i].min(0.0);
            }
        }
    }
}
