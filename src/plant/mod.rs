//! Plant models and their numerical integration. A plant is a continuous-time model
//! x' = f(t, x, u), y = h(x); the simulator integrates it at a fixed step with RK4 and samples it
//! each control period, applying the latest command as a zero-order hold.
//!
//! The same `PlantSim` runs in the plant process, in the in-process simulation used by tests and
//! (in later issues) in the optimiser's model evaluations.

pub mod arm;
pub mod integrator;
pub mod maglev;
pub mod two_mass;

pub use arm::Arm;
pub use integrator::Rk4;
pub use two_mass::TwoMass;

use crate::msg::PlantState;
use crate::{MAX_JOINTS, MAX_STATES};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A continuous-time plant model.
pub trait Plant: Send {
    /// Dimension of the state vector x.
    fn n_states(&self) -> usize;
    /// Dimension of the input u.
    fn n_inputs(&self) -> usize;
    /// Dimension of the measured output y.
    fn n_outputs(&self) -> usize;
    /// Number of bodies/joints with a position and velocity.
    fn n_joints(&self) -> usize;
    /// x' = f(t, x, u), written into `dx`. Must not allocate.
    fn derivative(&self, t: f64, x: &[f64], u: &[f64], dx: &mut [f64]);
    /// Noise-free measured outputs y = h(x).
    fn output(&self, x: &[f64], y: &mut [f64]);
    /// Joint positions and velocities from the state.
    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]);
    /// Initial state.
    fn initial_state(&self, x: &mut [f64]);
    /// Hard constraints applied after every integration step (e.g. joint stops). Default: none.
    fn constrain(&self, _x: &mut [f64]) {}
    /// The measuring chain after the sensor noise (e.g. an ADC's quantisation). Default: none.
    fn measure(&self, _y: &mut [f64]) {}
}

/// A plant being simulated: the model plus all the buffers its integration needs, allocated once
/// (Model/Data split), so `advance` never allocates.
pub struct PlantSim {
    pub plant: Box<dyn Plant>,
    pub x: Vec<f64>,
    pub t: f64,
    step: f64,
    rk: Rk4,
    noise: Option<(Normal<f64>, ChaCha8Rng)>,
    y_clean: Vec<f64>,
}

impl PlantSim {
    /// `step` is the integration step (s); `noise_std` the standard deviation of additive output
    /// noise drawn from a ChaCha RNG seeded with `seed` (0 std = no noise, no RNG draws).
    pub fn new(plant: Box<dyn Plant>, step: f64, noise_std: f64, seed: u64) -> Self {
        let n = plant.n_states();
        let mut x = vec![0.0; n];
        plant.initial_state(&mut x);
        let noise = (noise_std > 0.0).then(|| {
            (
                Normal::new(0.0, noise_std).expect("noise std validated positive and finite"),
                ChaCha8Rng::seed_from_u64(seed),
            )
        });
        Self {
            y_clean: vec![0.0; plant.n_outputs()],
            plant,
            x,
            t: 0.0,
            step,
            rk: Rk4::new(n),
            noise,
        }
    }

    /// Integrate over `dt` with the command `u` held constant (zero-order hold), in fixed
    /// sub-steps of at most `step`. The number of sub-steps depends only on dt and step, so the
    /// result is bit-for-bit reproducible.
    pub fn advance(&mut self, u: &[f64], dt: f64) {
        if dt <= 0.0 {
            return;
        }
        let n = (dt / self.step - 1e-9).ceil().max(1.0) as usize;
        let h = dt / n as f64;
        for _ in 0..n {
            self.rk.step(self.plant.as_ref(), self.t, &mut self.x, u, h);
            self.plant.constrain(&mut self.x);
            self.t += h;
        }
    }

    /// Sample the plant into a state message: positions, velocities, the full state and the
    /// (noisy) measured outputs. Consumes noise draws only when noise is configured.
    pub fn sample(&mut self, seq: u64, stamp_ns: u64, u_applied: &[f64], msg: &mut PlantState) {
        let p = self.plant.as_ref();
        let (nx, nq, ny) = (p.n_states(), p.n_joints(), p.n_outputs());
        msg.seq = seq;
        msg.stamp_ns = stamp_ns;
        msg.t = self.t;
        msg.n_x = nx as u32;
        msg.n_q = nq as u32;
        msg.n_y = ny as u32;
        msg.x[..nx.min(MAX_STATES)].copy_from_slice(&self.x[..nx.min(MAX_STATES)]);
        p.joints(&self.x, &mut msg.q[..nq], &mut msg.qd[..nq]);
        p.output(&self.x, &mut self.y_clean);
        for i in 0..ny.min(MAX_JOINTS) {
            let e = match &mut self.noise {
                Some((dist, rng)) => dist.sample(rng),
                None => 0.0,
            };
            msg.y[i] = self.y_clean[i] + e;
        }
        p.measure(&mut msg.y[..ny.min(MAX_JOINTS)]);
        let nu = u_applied.len().min(MAX_JOINTS);
        msg.u_applied[..nu].copy_from_slice(&u_applied[..nu]);
    }
}
