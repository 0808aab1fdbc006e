//! A plant and a control law of your own, on evoloop's simulator and control-law traits.
//!
//! The plant is a DC motor's speed, J w' = -b w + k u (`Plant`), integrated by evoloop's RK4
//! (`PlantSim`); its open-loop step response is checked against the closed form
//! w(t) = (k u / b)(1 - exp(-b t / J)). The law is a PI speed controller (`Controller`) with a
//! bumpless gain swap, closed around the motor at 1 kHz as the controller process would close it.
//!
//!     cargo run --release --example custom_plant

use evoloop::law::Controller;
use evoloop::msg::PlantState;
use evoloop::plant::{Plant, PlantSim};
use evoloop::reference::Setpoint;

/// J w' = -b w + k u: one state (speed, rad/s), one input (voltage), speed measured.
pub struct Motor {
    /// J, the rotor's inertia, kg m^2.
    pub inertia: f64,
    /// b, the viscous friction, N m s/rad.
    pub damping: f64,
    /// k, the torque per volt, N m/V.
    pub gain: f64,
}

impl Plant for Motor {
    fn n_states(&self) -> usize {
        1
    }
    fn n_inputs(&self) -> usize {
        1
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn n_joints(&self) -> usize {
        1
    }
    fn derivative(&self, _t: f64, x: &[f64], u: &[f64], dx: &mut [f64]) {
        dx[0] = (-self.damping * x[0] + self.gain * u[0]) / self.inertia;
    }
    fn output(&self, x: &[f64], y: &mut [f64]) {
        y[0] = x[0];
    }
    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        q[0] = x[0];
        qd[0] = 0.0;
    }
    fn initial_state(&self, x: &mut [f64]) {
        x[0] = 0.0;
    }
}

/// u = kp e + ki integral(e), e = set-point speed - measured speed. Parameters [kp, ki].
#[derive(Clone)]
pub struct SpeedPi {
    /// [kp, ki], V s/rad and V/rad: the parameter set an optimiser would swap.
    pub gains: [f64; 2],
    integral: f64,
    period: f64,
}

impl SpeedPi {
    /// A PI with gains `kp`, `ki`, integrating over `period` s, its integral at 0.
    pub fn new(kp: f64, ki: f64, period: f64) -> Self {
        Self {
            gains: [kp, ki],
            integral: 0.0,
            period,
        }
    }
}

impl Controller for SpeedPi {
    fn kind(&self) -> evoloop::msg::ParamKind {
        evoloop::msg::ParamKind::Pid
    }
    fn n_params(&self) -> usize {
        2
    }
    fn params(&self) -> &[f64] {
        &self.gains
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        let e = sp.q[0] - state.y[0];
        u[0] = self.gains[0] * e + self.gains[1] * self.integral;
        self.integral += e * self.period;
    }
    /// Bumpless: the integral is rescaled so that the new gains give the same command now.
    fn swap_params(&mut self, new: &[f64], state: &PlantState, sp: &Setpoint) {
        let e = sp.q[0] - state.y[0];
        let u_old = self.gains[0] * e + self.gains[1] * self.integral;
        self.gains = [new[0], new[1]];
        if new[1] != 0.0 {
            self.integral = (u_old - new[0] * e) / new[1];
        }
    }
}

/// What the example measured.
#[derive(Debug)]
pub struct Outcome {
    /// Largest |simulated - closed form| of the open-loop step response, rad/s.
    pub open_loop_error: f64,
    /// Closed loop: the speed at the end, rad/s. (The swap is bumpless: `swap_bump` is 0 up to
    /// rounding.)
    pub final_speed: f64,
    /// |new gains' command - old gains' command| on the sample of the swap, V.
    pub swap_bump: f64,
}

/// The step response against its closed form, then the PI closed around the motor at 1 kHz
/// for 5 s, its gains doubled at 1.5 s.
pub fn run() -> Outcome {
    let motor = || Motor {
        inertia: 0.01,
        damping: 0.02,
        gain: 0.5,
    };
    let period = 0.001;
    // Open loop: u = 1 V for 2 s against the closed form.
    let mut sim = PlantSim::new(Box::new(motor()), period / 4.0, 0.0, 1);
    let m = motor();
    let mut open_loop_error: f64 = 0.0;
    for k in 1..=2000 {
        sim.advance(&[1.0], period);
        let t = k as f64 * period;
        let exact = m.gain / m.damping * (1.0 - (-m.damping * t / m.inertia).exp());
        open_loop_error = open_loop_error.max((sim.x[0] - exact).abs());
    }
    // Closed loop: a 10 rad/s set-point, the gains doubled at 1.5 s (bumpless).
    let mut sim = PlantSim::new(Box::new(motor()), period / 4.0, 0.0, 1);
    let mut law = SpeedPi::new(0.05, 0.5, period);
    let mut sp = Setpoint::default();
    sp.q[0] = 10.0;
    let mut state = PlantState::default();
    let (mut u, mut swap_bump) = ([0.0], 0.0);
    for k in 0..5000u64 {
        sim.sample(k, 0, &u, &mut state);
        if k == 1500 {
            // The command the old gains would give on this sample, then the new gains' own.
            let mut old = [0.0];
            law.clone().step(&state, &sp, &mut old);
            law.swap_params(&[0.1, 1.0], &state, &sp);
            law.step(&state, &sp, &mut u);
            swap_bump = (u[0] - old[0]).abs();
        } else {
            law.step(&state, &sp, &mut u);
        }
        sim.advance(&u, period);
    }
    Outcome {
        open_loop_error,
        final_speed: sim.x[0],
        swap_bump,
    }
}

#[allow(dead_code)]
fn main() {
    let o = run();
    println!(
        "open loop: largest error against the closed form {:.2e} rad/s",
        o.open_loop_error
    );
    println!(
        "closed loop (PI, 10 rad/s): {:.4} rad/s after 5 s; command change at the gain swap {:.2e} V",
        o.final_speed, o.swap_bump
    );
}
